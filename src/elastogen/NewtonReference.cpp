#include "elastogen/NewtonReference.hpp"

#include <utility>

#include "parallel/PetscCheck.hpp"

namespace gen4d::elastogen {

using parallel::check;

NewtonReference::NewtonReference(VoxelSystem& sys, Stress stress, double dt, PhaseTimers& timers)
    : sys_(sys), timers_(timers), stress_(std::move(stress)), inv_dt2_(1.0 / (dt * dt)) {
  DM dm = sys.grid().dm(3);
  const Box& G = sys.ghosted();
  check(DMSetMatType(dm, MATAIJ), "DMSetMatType");
  check(DMCreateMatrix(dm, &J_), "DMCreateMatrix");
  check(MatSetOption(J_, MAT_NEW_NONZERO_ALLOCATION_ERR, PETSC_FALSE), "MatSetOption");
  check(SNESCreate(sys.grid().comm(), &snes_), "SNESCreate");
  check(DMCreateGlobalVector(dm, &X_), "DMCreateGlobalVector");
  Vec F;
  check(VecDuplicate(X_, &F), "VecDuplicate");
  check(SNESSetFunction(snes_, F, &NewtonReference::form_function, this), "SNESSetFunction");
  check(VecDestroy(&F), "VecDestroy");
  check(SNESSetJacobian(snes_, J_, J_, &NewtonReference::form_jacobian, this), "SNESSetJacobian");
  KSP ksp;
  PC pc;
  check(SNESGetKSP(snes_, &ksp), "SNESGetKSP");
  check(KSPSetType(ksp, KSPCG), "KSPSetType");
  check(KSPGetPC(ksp, &pc), "KSPGetPC");
  check(PCSetType(pc, PCGAMG), "PCSetType");
  check(KSPSetTolerances(ksp, 1e-8, PETSC_DEFAULT, PETSC_DEFAULT, 2000), "KSPSetTolerances");
  check(SNESSetTolerances(snes_, 1e-50, 1e-10, 1e-14, 100, 100000), "SNESSetTolerances");
  check(SNESSetOptionsPrefix(snes_, "newton_"), "SNESSetOptionsPrefix");
  check(SNESSetFromOptions(snes_), "SNESSetFromOptions");
  const std::size_t n = 3 * G.size();
  work_x_.assign(n, 0.0);
  work_r_.assign(n, 0.0);
}

NewtonReference::~NewtonReference() {
  SNESDestroy(&snes_);
  MatDestroy(&J_);
  VecDestroy(&X_);
}

void NewtonReference::unpack(Vec X, std::vector<double>& x) const {
  const PetscScalar* a = nullptr;
  VecGetArrayRead(X, &a);
  std::size_t p = 0;
  for_owned(sys_.owned(), sys_.ghosted(), [&](std::size_t n, long, long, long) {
    for (int d = 0; d < 3; ++d) x[3 * n + d] = a[p++];
  });
  VecRestoreArrayRead(X, &a);
}

PetscErrorCode NewtonReference::form_function(SNES, Vec X, Vec F, void* ctx) {
  auto* self = static_cast<NewtonReference*>(ctx);
  self->unpack(X, self->work_x_);
  {
    PhaseTimers::Scope t(self->timers_, "halo");
    self->halo_->gather(self->work_x_.data());
  }
  (*self->residual_)(self->work_x_, self->work_r_);
  PetscScalar* f = nullptr;
  PetscCall(VecGetArray(F, &f));
  std::size_t p = 0;
  const auto& free = self->sys_.free_mask();
  const auto& hold = *self->hold_;
  for_owned(self->sys_.owned(), self->sys_.ghosted(), [&](std::size_t n, long, long, long) {
    for (int d = 0; d < 3; ++d, ++p) {
      const std::size_t q = 3 * n + d;
      // The objective's gradient is -r; held nodes are pinned by x - x_hold = 0.
      f[p] = free[n] ? -self->work_r_[q] : self->work_x_[q] - hold[q];
    }
  });
  PetscCall(VecRestoreArray(F, &f));
  return 0;
}

PetscErrorCode NewtonReference::form_jacobian(SNES, Vec X, Mat J, Mat, void* ctx) {
  auto* self = static_cast<NewtonReference*>(ctx);
  self->unpack(X, self->work_x_);
  self->halo_->gather(self->work_x_.data());
  try {
    self->assemble_jacobian(J);
  } catch (const std::exception&) {
    return PETSC_ERR_LIB;
  }
  return 0;
}

void NewtonReference::assemble_jacobian(Mat J) {
  PhaseTimers::Scope timer(timers_, "newton-jacobian");
  check(MatZeroEntries(J), "MatZeroEntries");
  const HexStencil& s = HexStencil::get();
  const Box& oc = sys_.grid().owned_cells();
  const Box& G = sys_.ghosted();
  const Vec3d& h = sys_.spacing();
  const double w = h[0] * h[1] * h[2] / 8.0;
  const double inv_h[3] = {1.0 / h[0], 1.0 / h[1], 1.0 / h[2]};
  const bool cubic = sys_.cubic();
  std::array<long, 8> off{};
  for (int m = 0; m < 8; ++m)
    off[m] = static_cast<long>(
        G.index(G.start[0] + (m & 1), G.start[1] + ((m >> 1) & 1), G.start[2] + ((m >> 2) & 1)));
  for (long ck = oc.start[2]; ck < oc.start[2] + oc.count[2]; ++ck)
    for (long cj = oc.start[1]; cj < oc.start[1] + oc.count[1]; ++cj)
      for (long ci = oc.start[0]; ci < oc.start[0] + oc.count[0]; ++ci) {
        if (!sys_.solid(ci, cj, ck)) continue;
        const std::size_t base = G.index(ci, cj, ck);
        double xe[8][3];
        for (int m = 0; m < 8; ++m)
          for (int a = 0; a < 3; ++a) xe[m][a] = work_x_[3 * (base + off[m]) + a];
        PetscScalar Ke[24 * 24] = {};
        for (int q = 0; q < 8; ++q) {
          double F[9], C[9][9];
          deformation_gradient(s, q, xe, inv_h, F);
          // dP/dF by central differences: C[ij][kl] = dP_ij / dF_kl.
          for (int kl = 0; kl < 9; ++kl) {
            const double d = 1e-6 * (1.0 + std::fabs(F[kl]));
            double Fp[9], Fm[9], Pp[9], Pm[9];
            for (int t = 0; t < 9; ++t) Fp[t] = Fm[t] = F[t];
            Fp[kl] += d;
            Fm[kl] -= d;
            stress_(Fp, Pp);
            stress_(Fm, Pm);
            for (int ij = 0; ij < 9; ++ij) C[ij][kl] = (Pp[ij] - Pm[ij]) / (2 * d);
          }
          // K[(l,a),(m,b)] += w sum_{j,k} dN_l,j C[aj][bk] dN_m,k / (h_j h_k)
          for (int l = 0; l < 8; ++l)
            for (int a = 0; a < 3; ++a)
              for (int m = 0; m < 8; ++m)
                for (int b = 0; b < 3; ++b) {
                  double v = 0;
                  if (cubic) {
                    for (int j = 0; j < 3; ++j)
                      for (int k = 0; k < 3; ++k)
                        v += s.dN[q][l][j] * C[3 * a + j][3 * b + k] * s.dN[q][m][k];
                    Ke[(3 * l + a) * 24 + 3 * m + b] += w * inv_h[0] * inv_h[0] * v;
                  } else {
                    for (int j = 0; j < 3; ++j)
                      for (int k = 0; k < 3; ++k)
                        v += s.dN[q][l][j] * inv_h[j] * C[3 * a + j][3 * b + k] * s.dN[q][m][k] *
                             inv_h[k];
                    Ke[(3 * l + a) * 24 + 3 * m + b] += w * v;
                  }
                }
        }
        MatStencil idx[24];
        for (int l = 0; l < 8; ++l)
          for (int a = 0; a < 3; ++a) {
            idx[3 * l + a].i = static_cast<PetscInt>(ci + (l & 1));
            idx[3 * l + a].j = static_cast<PetscInt>(cj + ((l >> 1) & 1));
            idx[3 * l + a].k = static_cast<PetscInt>(ck + ((l >> 2) & 1));
            idx[3 * l + a].c = a;
          }
        check(MatSetValuesStencil(J, 24, idx, 24, idx, Ke, ADD_VALUES), "MatSetValuesStencil");
      }
  std::vector<MatStencil> held;
  for_owned(sys_.owned(), G, [&](std::size_t n, long i, long j, long kk) {
    for (int c = 0; c < 3; ++c) {
      MatStencil r{static_cast<PetscInt>(kk), static_cast<PetscInt>(j), static_cast<PetscInt>(i),
                   c};
      if (sys_.free_mask()[n]) {
        const PetscScalar m = sys_.mass()[n] * inv_dt2_;
        check(MatSetValuesStencil(J, 1, &r, 1, &r, &m, ADD_VALUES), "MatSetValuesStencil");
      } else {
        held.push_back(r);
      }
    }
  });
  check(MatAssemblyBegin(J, MAT_FINAL_ASSEMBLY), "MatAssemblyBegin");
  check(MatAssemblyEnd(J, MAT_FINAL_ASSEMBLY), "MatAssemblyEnd");
  // Held nodes (fixed or touching no voxel) get identity rows and columns.
  check(MatZeroRowsColumnsStencil(J, static_cast<PetscInt>(held.size()), held.data(), 1.0, nullptr,
                                  nullptr),
        "MatZeroRowsColumnsStencil");
}

NewtonStats NewtonReference::solve(std::vector<double>& x, const Residual& residual,
                                   parallel::Halo& halo) {
  residual_ = &residual;
  halo_ = &halo;
  std::vector<double> hold = x;
  hold_ = &hold;
  PetscScalar* a = nullptr;
  check(VecGetArray(X_, &a), "VecGetArray");
  std::size_t p = 0;
  for_owned(sys_.owned(), sys_.ghosted(), [&](std::size_t n, long, long, long) {
    for (int d = 0; d < 3; ++d) a[p++] = x[3 * n + d];
  });
  check(VecRestoreArray(X_, &a), "VecRestoreArray");
  check(SNESSolve(snes_, nullptr, X_), "SNESSolve");
  NewtonStats st;
  PetscInt its = 0, lits = 0;
  SNESConvergedReason reason;
  check(SNESGetIterationNumber(snes_, &its), "SNESGetIterationNumber");
  check(SNESGetLinearSolveIterations(snes_, &lits), "SNESGetLinearSolveIterations");
  check(SNESGetConvergedReason(snes_, &reason), "SNESGetConvergedReason");
  st.newton_iterations = static_cast<int>(its);
  st.krylov_iterations = static_cast<long>(lits);
  st.converged = reason > 0;
  unpack(X_, x);
  {
    PhaseTimers::Scope t(timers_, "halo");
    halo.gather(x.data());
  }
  residual_ = nullptr;
  halo_ = nullptr;
  hold_ = nullptr;
  return st;
}

}  // namespace gen4d::elastogen

#include "forward/Model.hpp"
#include "forward/MpmModel.hpp"

#include "forward/BlockLDLT.hpp"
#include "forward/ElementKernel.hpp"
#include "forward/Filter.hpp"
#include "forward/HenckyJ2.hpp"
#include "forward/NodeBlockProduct.hpp"

#include <Eigen/Dense>
#include <Eigen/IterativeLinearSolvers>
#include <Eigen/Sparse>
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <type_traits>
#include <utility>

#include "core/Error.hpp"
#include "elastogen/HexStencil.hpp"
#include "geometry/Shape.hpp"
#include "materials/FixedCorotated.hpp"
#include "materials/LinearElastic.hpp"
#include "materials/NeoHookean.hpp"
#include "materials/Registry.hpp"
#include "materials/StVK.hpp"

namespace gen4d::forward {

namespace {

// Shape functions of the element (kShapes, ElementKernel.hpp): the 8 trilinear corners, then
// the 3 incompatible (bubble) modes 4 xi_i (1 - xi_i) of Wilson and Taylor, one per axis,
// whose amplitudes are condensed per element. With them the voxel bends like the beam it is
// (the trilinear hexahedron with full integration locks in shear: it is stiffer in bending,
// the more so in higher modes).

//! F = sum_l x_l (x) grad N_l at one Gauss point (g: the gradients there, 1/m; the bubbles'
//! "positions" x_8..10 are their amplitudes).
inline void grad_at(const double (&g)[kShapes][3], const double x[kShapes][3], double F[9]) {
  for (int a = 0; a < 3; ++a) {
    double f0 = 0, f1 = 0, f2 = 0;
    for (int l = 0; l < kShapes; ++l) {
      f0 += x[l][a] * g[l][0];
      f1 += x[l][a] * g[l][1];
      f2 += x[l][a] * g[l][2];
    }
    F[3 * a] = f0, F[3 * a + 1] = f1, F[3 * a + 2] = f2;
  }
}

//! fe_l += w P grad N_l at one Gauss point (w: its volume, m^3).
inline void scatter_at(const double (&g)[kShapes][3], const double P[9], double w,
                       double fe[kShapes][3]) {
  for (int l = 0; l < kShapes; ++l)
    for (int a = 0; a < 3; ++a)
      fe[l][a] += w * (P[3 * a] * g[l][0] + P[3 * a + 1] * g[l][1] + P[3 * a + 2] * g[l][2]);
}

using elastogen::HexStencil;
using SpMat = Eigen::SparseMatrix<double>;
const double kPi = std::acos(-1.0);

//! The one instance of a constant table, built at its first use.
template <class T>
const T& built_once() {
  static const T table;
  return table;
}

//! Gradients (unit cube) of the element's shape functions at its 8 Gauss points: the trilinear
//! corners of HexStencil, then the bubbles 4 xi_i (1 - xi_i), whose gradient is along axis i.
//! The bubbles' gradients sum to zero over the Gauss points, so a constant stress does no work
//! on them and the element passes the patch test.
struct ElementStencil {
  double dN[8][kShapes][3];
  ElementStencil() {
    const HexStencil& S = HexStencil::get();
    const double g[2] = {0.5 - 0.5 / std::sqrt(3.0), 0.5 + 0.5 / std::sqrt(3.0)};
    for (int q = 0; q < 8; ++q) {
      for (int l = 0; l < 8; ++l)
        for (int c = 0; c < 3; ++c) dN[q][l][c] = S.dN[q][l][c];
      const double xi[3] = {g[q & 1], g[(q >> 1) & 1], g[(q >> 2) & 1]};
      for (int i = 0; i < 3; ++i)
        for (int c = 0; c < 3; ++c) dN[q][8 + i][c] = c == i ? 4.0 * (1.0 - 2.0 * xi[i]) : 0.0;
    }
  }
};

constexpr int kDof = 3 * kShapes;  // 24 nodal + 9 bubble amplitudes
using ElemMat = Eigen::Matrix<double, kDof, kDof>;

//! Unit-cube element stiffness of linear elasticity, split by Lame parameter:
//! K = h (lambda KL + mu KM), dof (shape l, axis a) -> 3 l + a.
struct UnitStiffness {
  ElemMat KL, KM;
  UnitStiffness() {
    const ElementStencil& S = built_once<ElementStencil>();
    for (int l = 0; l < kShapes; ++l)
      for (int a = 0; a < 3; ++a)
        for (int m = 0; m < kShapes; ++m)
          for (int b = 0; b < 3; ++b) {
            double kl = 0, km = 0;
            for (int q = 0; q < 8; ++q) {
              const auto& gl = S.dN[q][l];
              const auto& gm = S.dN[q][m];
              kl += 0.125 * gl[a] * gm[b];
              km += 0.125 * ((a == b ? gl[0] * gm[0] + gl[1] * gm[1] + gl[2] * gm[2] : 0.0) +
                             gl[b] * gm[a]);
            }
            KL(3 * l + a, 3 * m + b) = kl;
            KM(3 * l + a, 3 * m + b) = km;
          }
  }
};

//! Static condensation of the bubble amplitudes (massless, element-local) from an element
//! matrix [Kuu Kua; Kau Kaa]: Kc = Kuu - Kua Kaa^-1 Kau, and what the amplitudes' update needs,
//! L = Kaa^-1 Kau and Kaa^-1. False when Kaa is singular (it may be indefinite: the tangent
//! of a compressed plastic state is).
struct Condensed {
  Eigen::Matrix<double, 24, 24> Kc;
  Eigen::Matrix<double, 9, 24> L;
  Eigen::Matrix<double, 9, 9> Kinv;
};
bool condense(const ElemMat& K, Condensed& c) {
  const Eigen::Matrix<double, 9, 9> Kaa = K.block<9, 9>(24, 24);
  const Eigen::FullPivLU<Eigen::Matrix<double, 9, 9>> lu(Kaa);
  if (!lu.isInvertible()) return false;
  c.Kinv = lu.inverse();
  c.L = c.Kinv * K.block<9, 24>(24, 0);
  c.Kc = K.block<24, 24>(0, 0) - K.block<24, 9>(0, 24) * c.L;
  return true;
}

//! The element of linear elasticity at (lambda, mu) on a cell of edges h, with the bubbles
//! condensed (incompatible element) or left out (trilinear). Cubes scale the unit-cube matrices
//! by h; box cells integrate with each gradient component divided by its edge. False when the
//! bubble stiffness is singular.
bool rest_element(bool bubbles, const Vec3d& h, double lambda, double mu, Condensed& c) {
  ElemMat K0e;
  if (h[0] == h[1] && h[1] == h[2]) {
    const UnitStiffness& U = built_once<UnitStiffness>();
    K0e = h[0] * (lambda * U.KL + mu * U.KM);
  } else {
    const ElementStencil& S = built_once<ElementStencil>();
    const double w = h[0] * h[1] * h[2] / 8.0;
    for (int l = 0; l < kShapes; ++l)
      for (int a = 0; a < 3; ++a)
        for (int m = 0; m < kShapes; ++m)
          for (int b = 0; b < 3; ++b) {
            double k = 0;
            for (int q = 0; q < 8; ++q) {
              double gl[3], gm[3];
              for (int d = 0; d < 3; ++d)
                gl[d] = S.dN[q][l][d] / h[d], gm[d] = S.dN[q][m][d] / h[d];
              k += lambda * gl[a] * gm[b] +
                   mu * ((a == b ? gl[0] * gm[0] + gl[1] * gm[1] + gl[2] * gm[2] : 0.0) +
                         gl[b] * gm[a]);
            }
            K0e(3 * l + a, 3 * m + b) = w * k;
          }
  }
  if (bubbles) return condense(K0e, c);
  c.Kc = K0e.block<24, 24>(0, 0);
  return true;
}

//! The free dofs: 3 per node, every node but the rigidly fixed ones (all of them when the
//! clamp is a spring); their count in ndof.
std::vector<int> free_dofs(const std::vector<char>& fixed, bool clamp_springs, int& ndof) {
  std::vector<int> dof(fixed.size(), -1);
  ndof = 0;
  for (std::size_t n = 0; n < fixed.size(); ++n)
    if (!fixed[n] || clamp_springs) dof[n] = ndof, ndof += 3;
  return dof;
}

//! Stiffness at rest on the free dofs: the condensed unit element Kc of every voxel times its
//! factor. trip receives the entries in assembly order (voxel, node pair, axes).
SpMat assemble_stiffness(const std::vector<std::array<int, 8>>& vox_node,
                         const std::vector<int>& dof, int ndof, const std::vector<double>& vfac,
                         const Eigen::Matrix<double, 24, 24>& Kc,
                         std::vector<Eigen::Triplet<double>>& trip) {
  const std::size_t nv = vox_node.size();
  trip.clear();
  trip.reserve(nv * 576);
  for (std::size_t v = 0; v < nv; ++v) {
    for (int l = 0; l < 8; ++l) {
      const int dl = dof[static_cast<std::size_t>(vox_node[v][l])];
      if (dl < 0) continue;
      for (int m = 0; m < 8; ++m) {
        const int dm = dof[static_cast<std::size_t>(vox_node[v][m])];
        if (dm < 0) continue;
        for (int a = 0; a < 3; ++a)
          for (int b = 0; b < 3; ++b)
            trip.emplace_back(dl + a, dm + b, vfac[v] * Kc(3 * l + a, 3 * m + b));
      }
    }
  }
  SpMat K(ndof, ndof);
  K.setFromTriplets(trip.begin(), trip.end());
  return K;
}

//! Mass matrix on the free dofs: theta consistent (the trilinear shape functions' integral; the
//! bubbles carry no mass) plus (1 - theta) lumped (node masses per unit density `mass`), plus
//! the attached parts' `point_mass` (kg per node) lumped.
SpMat assemble_mass(const std::vector<std::array<int, 8>>& vox_node, const std::vector<int>& dof,
                    int ndof, const std::vector<double>& mass, double density, double theta,
                    const Vec3d& h, const std::vector<double>& point_mass) {
  double me[8][8];
  for (int l = 0; l < 8; ++l)
    for (int m = 0; m < 8; ++m) {
      double w = theta * density * h[0] * h[1] * h[2];
      for (int d = 0; d < 3; ++d) w *= ((l >> d) & 1) == ((m >> d) & 1) ? 1.0 / 3.0 : 1.0 / 6.0;
      me[l][m] = w;
    }
  std::vector<Eigen::Triplet<double>> tm;
  tm.reserve(vox_node.size() * 192 + mass.size() * 3);
  for (std::size_t n = 0; n < mass.size(); ++n)
    if (dof[n] >= 0)
      for (int a = 0; a < 3; ++a) {
        tm.emplace_back(dof[n] + a, dof[n] + a, (1 - theta) * mass[n] * density);
        if (point_mass[n] > 0) tm.emplace_back(dof[n] + a, dof[n] + a, point_mass[n]);
      }
  for (std::size_t v = 0; v < vox_node.size(); ++v)
    for (int l = 0; l < 8; ++l) {
      const int dl = dof[static_cast<std::size_t>(vox_node[v][l])];
      if (dl < 0) continue;
      for (int m = 0; m < 8; ++m) {
        const int dm = dof[static_cast<std::size_t>(vox_node[v][m])];
        if (dm >= 0)
          for (int a = 0; a < 3; ++a) tm.emplace_back(dl + a, dm + a, me[l][m]);
      }
    }
  SpMat Mc(ndof, ndof);
  Mc.setFromTriplets(tm.begin(), tm.end());
  return Mc;
}

void mat_mul(const double A[9], const double B[9], double C[9]) {
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      C[3 * i + j] = A[3 * i] * B[j] + A[3 * i + 1] * B[3 + j] + A[3 * i + 2] * B[6 + j];
}

bool invert(const double A[9], double R[9]) {
  const double c00 = A[4] * A[8] - A[5] * A[7], c01 = A[5] * A[6] - A[3] * A[8],
               c02 = A[3] * A[7] - A[4] * A[6];
  const double det = A[0] * c00 + A[1] * c01 + A[2] * c02;
  if (!(std::abs(det) > 1e-300)) return false;
  const double id = 1.0 / det;
  R[0] = c00 * id;
  R[1] = (A[2] * A[7] - A[1] * A[8]) * id;
  R[2] = (A[1] * A[5] - A[2] * A[4]) * id;
  R[3] = c01 * id;
  R[4] = (A[0] * A[8] - A[2] * A[6]) * id;
  R[5] = (A[2] * A[3] - A[0] * A[5]) * id;
  R[6] = c02 * id;
  R[7] = (A[1] * A[6] - A[0] * A[7]) * id;
  R[8] = (A[0] * A[4] - A[1] * A[3]) * id;
  return true;
}

//! Adds the lifetime of the scope to a seconds counter.
class PhaseTimer {
 public:
  explicit PhaseTimer(double& total) : total_(total), t0_(std::chrono::steady_clock::now()) {}
  ~PhaseTimer() {
    total_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0_).count();
  }
  PhaseTimer(const PhaseTimer&) = delete;
  PhaseTimer& operator=(const PhaseTimer&) = delete;

 private:
  double& total_;
  std::chrono::steady_clock::time_point t0_;
};

struct Plane {
  Vec3d p, n;  // n unit
  double mu;
};

//! Whether a law provides its analytic stress Jacobian, pk1_jacobian(F, D[9][9]).
template <class Law, class = void>
struct HasPk1Jacobian : std::false_type {};
template <class Law>
struct HasPk1Jacobian<
    Law, std::void_t<decltype(std::declval<const Law&>().pk1_jacobian(
             std::declval<const materials::Mat3&>(), std::declval<double (&)[9][9]>()))>>
    : std::true_type{};

}  // namespace

ModelTerms model_terms(const Physics& ph) {
  ModelTerms t;
  for (const auto& a : ph.effects) a.effect->add_terms(a.terms, t);
  return t;
}

std::unique_ptr<ForwardModel> make_forward_model(const Config& cfg) {
  if (cfg.solver.method == "mpm") return std::make_unique<MpmModel>(cfg);
  return std::make_unique<VoxelModel>(cfg);
}

VoxelModel::VoxelModel(const Config& cfg) : cfg_(cfg) {
  const std::string& src = cfg.source;
  if (!cfg.kinematic.empty())
    throw InputError(src +
                     ": [[kinematic]] regions are not supported by gen4d diagnose; "
                     "hold the support with [[fixed]]");
  if (!cfg.tractions.empty())
    throw InputError(src +
                     ": [[traction]] loads are not supported by gen4d diagnose; "
                     "give the load as a [[force]] region");
  for (const auto& c : cfg.colliders)
    if (c.type != "plane")
      throw InputError(src + ": [[collider]] of type '" + c.type +
                       "' is not supported by gen4d diagnose (planes are)");
  if (cfg.solver.method == "mpm")
    throw InputError(src + ": key 'solver.method': \"mpm\" decks take MpmModel");
  if (!(cfg.dt > 0) || !(cfg.end_time > 0))
    throw InputError(src + ": keys 'simulation.dt' and 'simulation.end_time' must be > 0");
  const auto at = cfg.material.param_where.find("model");  // InputError for an unknown law
  materials::deck_law(cfg.material.model, materials::Solver::Voxel,
                      at == cfg.material.param_where.end() ? "" : at->second);
  if (!cfg.material_regions.empty())
    throw InputError(cfg.material_regions[0].where +
                     ": several [[material]] entries are not supported by gen4d diagnose (it "
                     "fits one material; model a region's difference as an effect)");

  h_ = cfg.cell_edges();
  auto shape = geometry::make_shape(cfg.geometry);
  const geometry::Aabb b = shape->bounds();
  for (int a = 0; a < 3; ++a) {
    cells_[a] = std::max(1L, static_cast<long>(std::ceil((b.hi[a] - b.lo[a]) / h_[a] - 1e-9))) +
                2L * cfg.padding;
    origin_[a] = b.lo[a] - cfg.padding * h_[a];
  }
  const long ncell = cells_[0] * cells_[1] * cells_[2];
  if (ncell > 4000000)
    throw InputError(src + ": key 'domain.voxel_size': " + std::to_string(ncell) +
                     " cells; gen4d diagnose runs many forward solves and needs a coarser grid");
  std::vector<std::uint8_t> occ;
  geometry::voxelize(*shape, Eigen::Vector3d(origin_[0], origin_[1], origin_[2]),
                     Eigen::Vector3d(h_[0], h_[1], h_[2]), {0, 0, 0}, cells_, occ);
  const long nnx = cells_[0] + 1, nny = cells_[1] + 1, nnz = cells_[2] + 1;
  std::vector<int> node_id(static_cast<std::size_t>(nnx * nny * nnz), -1);
  cell_voxel_.assign(static_cast<std::size_t>(ncell), -1);
  bounds_.lo = {1e300, 1e300, 1e300};
  bounds_.hi = {-1e300, -1e300, -1e300};
  for (long k = 0; k < cells_[2]; ++k)
    for (long j = 0; j < cells_[1]; ++j)
      for (long i = 0; i < cells_[0]; ++i) {
        const long c = (k * cells_[1] + j) * cells_[0] + i;
        if (!occ[static_cast<std::size_t>(c)]) continue;
        cell_voxel_[static_cast<std::size_t>(c)] = static_cast<long>(vox_node_.size());
        std::array<int, 8> nodes{};
        for (int l = 0; l < 8; ++l) {
          const long ni = i + (l & 1), nj = j + ((l >> 1) & 1), nk = k + ((l >> 2) & 1);
          int& id = node_id[static_cast<std::size_t>((nk * nny + nj) * nnx + ni)];
          if (id < 0) {
            id = static_cast<int>(X_.size());
            X_.push_back(
                {origin_[0] + h_[0] * ni, origin_[1] + h_[1] * nj, origin_[2] + h_[2] * nk});
          }
          nodes[l] = id;
        }
        vox_node_.push_back(nodes);
        vox_ijk_.push_back({i, j, k});
        for (int a = 0; a < 3; ++a) {
          const long idx = a == 0 ? i : a == 1 ? j : k;
          bounds_.lo[a] = std::min(bounds_.lo[a], origin_[a] + h_[a] * idx);
          bounds_.hi[a] = std::max(bounds_.hi[a], origin_[a] + h_[a] * (idx + 1));
        }
      }
  if (vox_node_.empty())
    throw InputError(src + ": [[geometry]] produces no solid voxel at voxel_size " +
                     fmt::format("{}", h_) + " m");
  const std::size_t nn = X_.size();
  mass_.assign(nn, 0.0);
  fixed_.assign(nn, 0);
  area_.assign(nn, 0.0);
  vox_area_.assign(vox_node_.size(), 0.0);
  clamp_area_.assign(nn, 0.0);
  for (const auto& v : vox_node_)
    for (int l = 0; l < 8; ++l)
      mass_[static_cast<std::size_t>(v[l])] += h_[0] * h_[1] * h_[2] / 8.0;
  for (std::size_t n = 0; n < nn; ++n)
    for (const auto& f : cfg.fixed)
      if (f.region.contains(X_[n])) fixed_[n] = 1;
  // Exposed faces: a face whose corners are all fixed is clamp area, else drag area.
  auto solid = [&](long i, long j, long k) {
    if (i < 0 || j < 0 || k < 0 || i >= cells_[0] || j >= cells_[1] || k >= cells_[2]) return false;
    return cell_voxel_[static_cast<std::size_t>((k * cells_[1] + j) * cells_[0] + i)] >= 0;
  };
  for (std::size_t v = 0; v < vox_node_.size(); ++v) {
    const auto [i, j, k] = vox_ijk_[v];
    for (int a = 0; a < 3; ++a)
      for (int side = 0; side < 2; ++side) {
        long nb[3] = {i, j, k};
        nb[a] += side ? 1 : -1;
        if (solid(nb[0], nb[1], nb[2])) continue;
        // Corner q: the voxel corner whose bits on the two face axes are q's two bits.
        std::array<int, 4> corners{};
        int c = 0;
        for (int l = 0; l < 8; ++l)
          if (((l >> a) & 1) == side) corners[c++] = vox_node_[v][l];
        bool all_fixed = true;
        for (int q = 0; q < 4; ++q) all_fixed = all_fixed && fixed_[corners[q]];
        const double face = h_[(a + 1) % 3] * h_[(a + 2) % 3];
        if (all_fixed) {
          clamp_faces_.push_back(corners);
          clamp_face_area_.push_back(face);
          clamp_face_axis_.push_back(a);
        } else {
          for (int q = 0; q < 4; ++q) area_[static_cast<std::size_t>(corners[q])] += face / 4;
          vox_area_[v] += face;
        }
      }
  }
  std::vector<char> on_face(nn, 0);
  for (const auto& f : clamp_faces_)
    for (int q : f) on_face[static_cast<std::size_t>(q)] = 1;
  long nfixed = 0;
  for (std::size_t n = 0; n < nn; ++n)
    if (fixed_[n]) {
      ++nfixed;
      if (!on_face[n]) clamp_area_[n] = h_[1] * h_[2];  // an interior anchor: a face's area
    }
  if (nfixed == static_cast<long>(nn))
    throw InputError(src + ": [[fixed]] regions hold every node; nothing can move");
  add_point_masses();
  // How far each node lies from the nearest held node (the support's friction acts there).
  support_distance_.assign(nn, std::numeric_limits<double>::infinity());
  std::vector<std::size_t> held;
  for (std::size_t n = 0; n < nn; ++n)
    if (fixed_[n]) held.push_back(n);
  for (std::size_t n = 0; n < nn; ++n)
    for (std::size_t f : held) {
      double d2 = 0;
      for (int a = 0; a < 3; ++a) d2 += (X_[n][a] - X_[f][a]) * (X_[n][a] - X_[f][a]);
      support_distance_[n] = std::min(support_distance_[n], std::sqrt(d2));
    }
}

void VoxelModel::spread_mass(const ModelTerms::AddedMass& am, std::vector<double>& pm) const {
  std::vector<double> w(X_.size(), 0.0);
  double sum = 0;
  for (std::size_t n = 0; n < X_.size(); ++n) {
    double t = mass_[n];
    for (int a = 0; a < 3; ++a)
      t *= std::max(0.0, 1.0 - std::abs(X_[n][a] - am.at[a]) / am.spread[a]);
    w[n] = t, sum += t;
  }
  if (sum > 0)
    for (std::size_t n = 0; n < X_.size(); ++n) pm[n] += am.mass * w[n] / sum;
}

//! The deck's [[point_mass]] parts on the nodes in their regions, by the nodes' own mass.
void VoxelModel::add_point_masses() {
  point_mass_.assign(X_.size(), 0.0);
  for (const PointMassConfig& pm : cfg_.point_masses) {
    double sum = 0;
    for (std::size_t n = 0; n < X_.size(); ++n)
      if (pm.region.contains(X_[n])) sum += mass_[n];
    if (!(sum > 0))
      throw InputError(fmt::format("{}: [[point_mass]] region [{}, {}] holds no node of the body",
                                   pm.where, pm.region.lo, pm.region.hi));
    for (std::size_t n = 0; n < X_.size(); ++n)
      if (pm.region.contains(X_[n])) point_mass_[n] += pm.mass * mass_[n] / sum;
  }
}

VoxelModel::~VoxelModel() = default;

Physics VoxelModel::nominal() const {
  Physics p;
  p.law = cfg_.material.model;
  p.youngs_modulus = cfg_.material.youngs_modulus;
  p.poisson_ratio = cfg_.material.poisson_ratio;
  p.density = cfg_.material.density;
  p.gravity = cfg_.gravity;
  p.dt = cfg_.dt;
  return p;
}

double VoxelModel::exposed_area() const {
  double a = 0;
  for (double x : area_) a += x;
  return a;
}

Vec3d VoxelModel::voxel_center(std::size_t v) const {
  const auto& c = vox_ijk_[v];
  return {origin_[0] + h_[0] * (c[0] + 0.5), origin_[1] + h_[1] * (c[1] + 0.5),
          origin_[2] + h_[2] * (c[2] + 0.5)};
}

BoxRegion VoxelModel::voxel_box(const std::vector<std::size_t>& voxels) const {
  BoxRegion r;
  r.lo = {1e300, 1e300, 1e300};
  r.hi = {-1e300, -1e300, -1e300};
  for (std::size_t v : voxels)
    for (int a = 0; a < 3; ++a) {
      r.lo[a] = std::min(r.lo[a], origin_[a] + h_[a] * vox_ijk_[v][a]);
      r.hi[a] = std::max(r.hi[a], origin_[a] + h_[a] * (vox_ijk_[v][a] + 1));
    }
  return r;
}

bool VoxelModel::inside(const Vec3d& X) const {
  const double tol = 0.25;
  for (int dk = -1; dk <= 1; ++dk)
    for (int dj = -1; dj <= 1; ++dj)
      for (int di = -1; di <= 1; ++di) {
        const double off[3] = {di * tol, dj * tol, dk * tol};
        long c[3];
        bool in = true;
        for (int a = 0; a < 3; ++a) {
          c[a] = static_cast<long>(std::floor((X[a] - origin_[a]) / h_[a] + off[a]));
          in = in && c[a] >= 0 && c[a] < cells_[a];
        }
        if (in &&
            cell_voxel_[static_cast<std::size_t>((c[2] * cells_[1] + c[1]) * cells_[0] + c[0])] >=
                0)
          return true;
      }
  return false;
}

long VoxelModel::voxel_containing(const Vec3d& X) const {
  long c[3];
  for (int a = 0; a < 3; ++a) {
    c[a] = static_cast<long>(std::floor((X[a] - origin_[a]) / h_[a]));
    if (c[a] < 0 || c[a] >= cells_[a]) return -1;
  }
  return cell_voxel_[static_cast<std::size_t>((c[2] * cells_[1] + c[1]) * cells_[0] + c[0])];
}

Attachment VoxelModel::attach(const Vec3d& X) const {
  // The solid voxel nearest to X (X itself may lie on a face shared with empty space).
  long best = -1;
  double best_d = 1e300;
  long c0[3];
  for (int a = 0; a < 3; ++a) c0[a] = static_cast<long>(std::floor((X[a] - origin_[a]) / h_[a]));
  for (long dk = -1; dk <= 1; ++dk)
    for (long dj = -1; dj <= 1; ++dj)
      for (long di = -1; di <= 1; ++di) {
        const long c[3] = {c0[0] + di, c0[1] + dj, c0[2] + dk};
        if (c[0] < 0 || c[1] < 0 || c[2] < 0 || c[0] >= cells_[0] || c[1] >= cells_[1] ||
            c[2] >= cells_[2])
          continue;
        const long v =
            cell_voxel_[static_cast<std::size_t>((c[2] * cells_[1] + c[1]) * cells_[0] + c[0])];
        if (v < 0) continue;
        double d = 0;
        for (int a = 0; a < 3; ++a) {
          const double lo = origin_[a] + h_[a] * c[a], hi = lo + h_[a];
          const double e = X[a] < lo ? lo - X[a] : X[a] > hi ? X[a] - hi : 0.0;
          d += e * e;
        }
        if (d < best_d) best_d = d, best = v;
      }
  if (best < 0) throw std::logic_error("attach: point is not on the body");
  Attachment at;
  at.X = X;
  double xi[3];
  for (int a = 0; a < 3; ++a) {
    const double lo = origin_[a] + h_[a] * vox_ijk_[static_cast<std::size_t>(best)][a];
    xi[a] = std::clamp((X[a] - lo) / h_[a], 0.0, 1.0);
  }
  for (int l = 0; l < 8; ++l) {
    at.node[l] = vox_node_[static_cast<std::size_t>(best)][l];
    double w = 1;
    for (int a = 0; a < 3; ++a) w *= ((l >> a) & 1) ? xi[a] : 1.0 - xi[a];
    at.w[l] = w;
  }
  return at;
}

std::vector<double> VoxelModel::load_events() const {
  std::vector<double> e;
  for (const auto& f : cfg_.forces) {
    if (f.start > 0) e.push_back(f.start);
    if (f.end < 1e299) e.push_back(f.end);
  }
  std::sort(e.begin(), e.end());
  e.erase(std::unique(e.begin(), e.end()), e.end());
  return e;
}

//! One run of VoxelModel with the hyperelastic law as a compile-time type (pk1(Mat3) -> Mat3):
//! the model's step matrix and constitutive state set up once, then trapezoidal steps, each a
//! Newton iteration with a lagged tangent, then the samples.
template <class Law>
class VoxelRun {
 public:
  VoxelRun(const VoxelModel& md, const Physics& ph, const ModelTerms& tm, const Law& law)
      : md_(md), ph(ph), tm(tm), law(law), nn(md.X_.size()), nv(md.vox_node_.size()) {}

  Trace run(const std::vector<ChannelRequest>& req) {
    if (!setup_stiffness()) return tr;
    setup_mass_and_supports();
    const bool preloaded = std::any_of(md_.cfg_.forces.begin(), md_.cfg_.forces.end(),
                                       [](const ForceConfig& f) { return f.start < 0; });
    if (!preloaded && !setup_step_matrix()) return tr;
    setup_constitutive();
    setup_sampling(req);
    setup_loads();
    fext.assign(3 * nn, 0.0);
    tol_du = ph.newton_tolerance * h_min;
    if (preloaded && !preload()) return tr;
    initial_acceleration();
    record(0);
    a_prev = a;
    for (long s = 1; s <= nsteps; ++s)
      if (!step(s)) return tr;
    if (ph.lowpass_hz > 0)  // each sampled node's u, v, a over the steps
      for (std::size_t k = 0; k < 9 * ns; ++k)
        lowpass_zero_phase(&hist_u[k], static_cast<std::size_t>(nsteps) + 1, 9 * ns, dt,
                           ph.lowpass_hz);
    sample(req);
    return tr;
  }

 private:
  using Vec24 = Eigen::Matrix<double, 24, 1>;
  const VoxelModel& md_;
  const Physics& ph;
  const ModelTerms& tm;
  const Law& law;
  Trace tr;
  const std::size_t nn, nv;
  Vec3d h{};             // cell edges
  double h_min = 0;      // the smallest edge
  double w_tangent = 0;  // the element tangent's weight: cell volume / 8 over (Dn's scale)^2
  // Gradients the element tangent contracts with: the unit cube's (cubes), or scaled to the
  // first edge (box cells), with w_tangent.
  double Dn[8][kShapes][3];
  double dt = 0, lambda0 = 0, mu0 = 0;
  int ndof = 0;
  std::vector<int> dof;
  std::vector<double> vfac;
  bool clamp_springs = false, bubbles = false;
  // The clamp's springs per unit area along a clamp face's normal and in its plane.
  double k_normal = 0, k_tangent = 0;
  std::vector<double> pmass;  // per node: the deck's point masses and the effects' added masses
  Condensed c0;
  // Per voxel: L, its transpose (the products read both along their outputs) and Kinv.
  std::vector<Eigen::Matrix<double, 9, 24>> condL;
  std::vector<Eigen::Matrix<double, 24, 9>> condLt;
  std::vector<Eigen::Matrix<double, 9, 9>> condKinv;
  SpMat K0, Kt, Mc, diagA;
  std::vector<int> kslot;
  Eigen::VectorXd M, Cd, Ks;
  bool consistent = false, clamp_faces = false;
  NodeBlockProduct Mc_nodes;  // Mc's product, one index per node pair (the same bits)
  double ca = 0, cv = 0, k_pen = 0;
  std::vector<Plane> planes;
  BlockLDLT solver;
  std::vector<char> active;
  // Constitutive state per Gauss point.
  bool plastic = false, visco = false, kelvin_voigt = false;
  bool linear_steps = false;  // one solve a step (Physics::linear_single_solve)
  HenckyJ2 j2;                // von Mises with linear hardening (Hencky elasticity)
  std::vector<double> fp_inv, fp_inv_new, pstate, pstate_new, qv, qv_new;
  double rv = 0;
  std::vector<double> u, v, a, u1, v1, a1, a_prev, fext, fint;
  std::vector<double> f_static;  // the loads the pre-loaded initial state balances (or empty)
  // Bubble amplitudes per voxel (9: axis i, component d at 3 i + d), their rates (trapezoidal,
  // for the viscous stress), trial values, and their residual (element-local equations).
  std::vector<double> al, ald, al1, ald1, ral;
  Eigen::VectorXd R, du, wa, Mwa;
  const ElementStencil& S = built_once<ElementStencil>();
  double step_max_mises = 0;
  long step_continued = 0;  // StVK: Gauss points continued at the step's predictor
  double G[8][kShapes][3];
  static constexpr bool kStvk = std::is_same_v<Law, materials::StVK>;
  static constexpr bool kLinearLaw = std::is_same_v<Law, materials::LinearElastic>;
  static constexpr bool kLaneLaw = kStvk || kLinearLaw ||
                                   std::is_same_v<Law, materials::NeoHookean> ||
                                   std::is_same_v<Law, materials::FixedCorotated>;
  bool vector_pass = false, vector_tangent = false;
  ElasticForcePass pass;
  ElasticTangent vtangent;
  alignas(64) double Gl[kShapes][3][8];
  long nsteps = 0;
  std::vector<int> sample_slot;
  std::vector<std::size_t> sampled;
  std::size_t ns = 0;
  std::vector<double> hist_u;  // u, v, a of the sampled nodes per step
  std::vector<double> region_mass;
  double t_tol = 0, tol_du = 0;

  bool fail(const std::string& why) {
    tr.ok = false;
    tr.failure = why;
    return false;
  }

  //! Degrees of freedom (every node but the rigidly fixed ones) and the linear stiffness at
  //! rest, K0, on them, the bubbles condensed per element (the same for every voxel up to its
  //! stiffness factor). Per voxel: L = Kaa^-1 Kau and Kaa^-1 of the matrix last factored, for
  //! the bubbles' update after each global solve.
  bool setup_stiffness() {
    clamp_springs = std::isfinite(tm.clamp_stiffness) || std::isfinite(tm.clamp_normal_stiffness);
    dof = free_dofs(md_.fixed_, clamp_springs, ndof);
    h = md_.h_, dt = ph.dt;
    h_min = std::min({h[0], h[1], h[2]});
    lambda0 = ph.youngs_modulus * ph.poisson_ratio /
              ((1 + ph.poisson_ratio) * (1 - 2 * ph.poisson_ratio));
    mu0 = ph.youngs_modulus / (2 * (1 + ph.poisson_ratio));
    vfac = md_.stiffness_factors(tm);
    bubbles = ph.element == Element::incompatible;
    if (!rest_element(bubbles, h, lambda0, mu0, c0))
      return fail("the element's bubble stiffness is singular");
    if (bubbles) {
      condL.assign(nv, c0.L);
      condLt.assign(nv, c0.L.transpose());
      condKinv.resize(nv);
      for (std::size_t vx = 0; vx < nv; ++vx) condKinv[vx] = c0.Kinv / vfac[vx];
    }
    std::vector<Eigen::Triplet<double>> trip;
    K0 = assemble_stiffness(md_.vox_node_, dof, ndof, vfac, c0.Kc, trip);
    // Where each voxel's free 3x3 node blocks sit among K0's values (the tangent has K0's
    // pattern): the tangent is added there directly, in the order of the loops above, instead
    // of through triplets sorted anew on every rebuild.
    kslot.reserve(trip.size());
    for (const auto& tr3 : trip) {
      const int col = tr3.col();
      const int* begin = K0.innerIndexPtr() + K0.outerIndexPtr()[col];
      const int* end = K0.innerIndexPtr() + K0.outerIndexPtr()[col + 1];
      kslot.push_back(
          static_cast<int>(std::lower_bound(begin, end, tr3.row()) - K0.innerIndexPtr()));
    }
    return true;
  }

  //! Mass: lumped (a diagonal, M), or Mc = theta consistent + (1 - theta) lumped, the
  //! consistent part the trilinear shape functions' integral (the bubbles carry no mass).
  //! Mass-proportional damping uses the same matrix; Cd is the diagonal rest (the node forces'
  //! damping, clamp dashpots), Ks the clamp springs. Then the contact planes.
  void setup_mass_and_supports() {
    M.resize(ndof), Cd.resize(ndof), Ks.resize(ndof);
    const double theta = std::clamp(ph.consistent_mass_fraction, 0.0, 1.0);
    consistent = theta > 0;
    pmass = md_.point_mass_;
    for (const ModelTerms::AddedMass& am : tm.added_masses) md_.spread_mass(am, pmass);
    if (consistent) {
      Mc = assemble_mass(md_.vox_node_, dof, ndof, md_.mass_, ph.density, theta, h, pmass);
      Mc_nodes = NodeBlockProduct(Mc);
    }
    // Rigid in the clamp face's plane when only the normal springs give: 1e4 E / h, the clamp
    // compliance effect's own rigid value.
    k_tangent =
        std::isfinite(tm.clamp_stiffness) ? tm.clamp_stiffness : 1e4 * ph.youngs_modulus / md_.h();
    k_normal = std::isfinite(tm.clamp_normal_stiffness) ? tm.clamp_normal_stiffness : k_tangent;
    for (std::size_t n = 0; n < nn; ++n) {
      if (dof[n] < 0) continue;
      const double m = mass_of(n);
      double c = 0;
      for (const auto& nf : tm.node_forces) c += nf->damping(force_node(n, m));
      double k = 0;
      if (md_.fixed_[n] && clamp_springs) {
        k = k_tangent * md_.clamp_area_[n];
        c += tm.clamp_damping * md_.clamp_area_[n];
      }
      for (int d = 0; d < 3; ++d) M[dof[n] + d] = m, Cd[dof[n] + d] = c, Ks[dof[n] + d] = k;
    }
    clamp_faces = clamp_springs && !md_.clamp_faces_.empty();
    // Trapezoidal rule: a1 = 4 (u1 - u - dt v - dt^2/4 a) / dt^2, v1 = v + dt/2 (a + a1).
    ca = 4.0 / (dt * dt), cv = 2.0 / dt;
    for (const auto& c : md_.cfg_.colliders) {
      Vec3d n = c.normal;
      const double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
      for (double& x : n) x /= len;
      planes.push_back({c.point, n, c.friction});
    }
    for (const auto& c : tm.planes) planes.push_back({c.point, c.normal, c.friction});
    k_pen = 2.0 * ph.youngs_modulus * h_min;  // N/m per node: sub-micron sag, mild tangent
  }

  //! The clamp faces' springs and dashpots as an elastic foundation, integrated with the
  //! face's bilinear shape functions (the consistent matrix, h^2/36 times 4, 2, 1 for a corner
  //! with itself, along an edge, across): exact for the linear field of a face that tilts, so
  //! the clamp's rotational stiffness is k times the face's second moment of area on any
  //! mesh (lumped at the corners it is 1 + 2 (h/H)^2 times that, for a face H wide).
  //! Node n's mass (kg): its share of the body, the deck's point masses, the added masses.
  double mass_of(std::size_t n) const { return md_.mass_[n] * ph.density + pmass[n]; }
  ForceNode force_node(std::size_t n, double m) const {
    return {m, md_.area_[n], md_.X_[n], md_.support_distance_[n]};
  }
  //! The clamp springs' stiffness per unit area on clamp face fi along axis d.
  double clamp_k(std::size_t fi, int d) const {
    return d == md_.clamp_face_axis_[fi] ? k_normal : k_tangent;
  }

  double foundation(std::size_t face, int q, int r) const {
    const int same = ((q ^ r) & 1 ? 0 : 1) + ((q ^ r) & 2 ? 0 : 1);  // axes in common
    return md_.clamp_face_area_[face] / 36.0 * (same == 2 ? 4.0 : same == 1 ? 2.0 : 1.0);
  }

  //! Step matrix A = diag(ca M + cv C + springs) + (1 + cv beta) Kt (+ contact penalties); Kt
  //! starts as K0 and is replaced by the tangent at the current state when Newton slows down
  //! (the viscous stress of stiffness damping has about beta cv times its elastic tangent).
  bool setup_step_matrix() {
    diagA = SpMat(ndof, ndof);  // (ca + cv alpha) M + cv Cd + Ks
    const double cm = ca + cv * tm.rayleigh_alpha;
    std::vector<Eigen::Triplet<double>> d;
    for (int i = 0; i < ndof; ++i)
      d.emplace_back(i, i, (consistent ? 0.0 : cm * M[i]) + cv * Cd[i] + Ks[i]);
    if (clamp_faces)
      for (std::size_t fi = 0; fi < md_.clamp_faces_.size(); ++fi) {
        const auto& f = md_.clamp_faces_[fi];
        for (int q = 0; q < 4; ++q)
          for (int r = 0; r < 4; ++r)
            for (int k = 0; k < 3; ++k)
              d.emplace_back(dof[static_cast<std::size_t>(f[q])] + k,
                             dof[static_cast<std::size_t>(f[r])] + k,
                             (clamp_k(fi, k) + cv * tm.clamp_damping) * foundation(fi, q, r));
      }
    diagA.setFromTriplets(d.begin(), d.end());
    if (consistent) diagA += cm * Mc;
    Kt = K0;
    solver.analyze(K0 + diagA);
    active.assign(nn * std::max<std::size_t>(planes.size(), 1), 0);
    if (!factor()) return fail("the step matrix is singular");
    return true;
  }

  bool factor() {
    PhaseTimer timer(tr.time_factor);
    SpMat A = diagA + (1.0 + cv * tm.rayleigh_beta) * Kt;
    for (std::size_t n = 0; n < nn; ++n)
      for (std::size_t p = 0; p < planes.size(); ++p)
        if (dof[n] >= 0 && active[n * planes.size() + p])
          for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j)
              A.coeffRef(dof[n] + i, dof[n] + j) += k_pen * planes[p].n[i] * planes[p].n[j];
    ++tr.factorizations;
    return solver.factorize(A);
  }

  //! Plastic and viscous state per Gauss point, the motion's vectors, the shape-function
  //! gradients in physical units (1/m) at the 8 Gauss points (the bubbles' are zero for the
  //! plain trilinear element, whose amplitudes stay zero), and the vector kernels' setup.
  void setup_constitutive() {
    plastic = std::isfinite(tm.yield_stress);
    visco = tm.prony_g > 0;
    if (plastic) {
      j2.mu = mu0;
      j2.lambda = lambda0;
      j2.yield_stress = std::max(tm.yield_stress, 0.0);
      j2.hardening = std::max(tm.hardening, 0.0);
    }
    const std::size_t ngp = nv * 8;
    if (plastic) {
      fp_inv.assign(9 * ngp, 0.0);
      for (std::size_t g = 0; g < ngp; ++g)
        fp_inv[9 * g] = fp_inv[9 * g + 4] = fp_inv[9 * g + 8] = 1;
      pstate.assign(ngp, 0.0);  // equivalent plastic strain per Gauss point
      fp_inv_new = fp_inv;
      pstate_new = pstate;
    }
    if (visco) qv.assign(9 * ngp, 0.0), qv_new = qv;
    rv = visco ? dt / tm.prony_tau : 0.0;
    u.assign(3 * nn, 0.0), v.assign(3 * nn, 0.0), a.assign(3 * nn, 0.0);
    u1.resize(3 * nn), v1.resize(3 * nn), a1.resize(3 * nn);
    al.assign(bubbles ? 9 * nv : 0, 0.0), ald.assign(al.size(), 0.0), al1.resize(al.size()),
        ald1.resize(al.size()), ral.resize(al.size());
    R.resize(ndof), du.resize(ndof), wa.resize(ndof), Mwa.resize(ndof);
    for (int q = 0; q < 8; ++q)
      for (int l = 0; l < kShapes; ++l)
        for (int c = 0; c < 3; ++c) G[q][l][c] = (l < 8 || bubbles) ? S.dN[q][l][c] / h[c] : 0.0;
    // The tangent's weight: h^3 / 8 * (1/h)^2 on cubes; on box cells the gradients scaled to
    // the first edge (dN h0 / h_c) and the weight hx hy hz / (8 h0^2).
    const bool cube = h[0] == h[1] && h[1] == h[2];
    w_tangent = cube ? h[0] / 8.0 : h[0] * h[1] * h[2] / (8.0 * h[0] * h[0]);
    for (int q = 0; q < 8; ++q)
      for (int l = 0; l < kShapes; ++l)
        for (int c = 0; c < 3; ++c)
          Dn[q][l][c] = cube ? S.dN[q][l][c] : S.dN[q][l][c] * h[0] / h[c];
    fint.resize(3 * nn);
    kelvin_voigt = tm.rayleigh_beta != 0;
    linear_steps = ph.linear_single_solve && kLinearLaw && !plastic && !visco && planes.empty() &&
                   tm.node_forces.empty();
    if constexpr (kLaneLaw) setup_vector_kernels();
  }

  //! The elastic passes of the StVK, Neo-Hookean and corotated laws run in the vector kernel
  //! (ElementKernel.hpp: the same arithmetic, the Gauss points as lanes); so do the element
  //! tangents by central differences of the first two (the corotated law's analytic one stays
  //! in the scalar loop).
  void setup_vector_kernels() {
    vector_pass = md_.vector_kernels_ && !plastic;
    // The linear law's tangent (its rest stiffness, built a few times a run) stays scalar.
    vector_tangent = vector_pass && !HasPk1Jacobian<Law>::value && !kLinearLaw;
    for (int q = 0; q < 8; ++q)
      for (int l = 0; l < kShapes; ++l)
        for (int c = 0; c < 3; ++c) Gl[l][c][q] = G[q][l][c];
    pass.law = kStvk                                        ? ElasticLaw::StVK
               : kLinearLaw                                 ? ElasticLaw::Linear
               : std::is_same_v<Law, materials::NeoHookean> ? ElasticLaw::NeoHookean
                                                            : ElasticLaw::Corotated;
    pass.voxels = nv;
    pass.vox_node = md_.vox_node_.data();
    pass.X = md_.X_.data();
    pass.vfac = vfac.data();
    pass.G = Gl;
    pass.weight = h[0] * h[1] * h[2] / 8.0;
    pass.mu = law.mu;
    pass.lambda = law.lambda;
    pass.kv_beta = tm.rayleigh_beta;
    pass.kv_mu = mu0;
    pass.kv_lambda = lambda0;
    pass.prony_rate = rv;
    pass.prony_rate_g = rv * tm.prony_g;
    vtangent.law = pass.law;
    vtangent.G = Gl;
    vtangent.dN = Dn;
    vtangent.mu = law.mu;
    vtangent.lambda = law.lambda;
    vtangent.shapes = bubbles ? kShapes : 8;
  }

  //! Stress P of the elastic law at F; whether StVK's screen sent F to the continuation.
  bool elastic_stress(const double F[9], double P[9]) const {
    bool continued = false;
    materials::Mat3 Fm, Pm;
    std::copy(F, F + 9, Fm.a);
    if constexpr (std::is_same_v<Law, materials::FixedCorotated>) {
      // The rotation by Newton's polar iteration: ~10x cheaper than the SVD; the SVD stays for
      // inverted elements.
      materials::Mat3 Rm;
      if (!materials::polar_rotation_newton(Fm, Rm)) Rm = materials::polar_rotation(Fm);
      Pm = law.pk1(Fm, Rm);
    } else {
      Pm = law.pk1(Fm);
      if constexpr (std::is_same_v<Law, materials::StVK>) {
        constexpr double sc = kStvkContinuedStretch;
        continued = !materials::StVK::stretches_above(Fm.a, sc);
        if (continued) law.pk1_continued(Fm, sc, Pm);
      }
    }
    std::copy(Pm.a, Pm.a + 9, P);
    return continued;
  }

  //! Stress of the plastic return map from the state at the start of the step (Gauss point
  //! g): P, the Kirchhoff stress tau, the trial state and Fp^-1.
  bool plastic_stress(std::size_t g, const double F[9], double P[9], double tau[9], double* state,
                      double* fp_inv_out) const {
    double Fe[9], Finv[9];
    mat_mul(F, &fp_inv[9 * g], Fe);
    *state = pstate[g];
    if (!j2.update(Fe, *state, tau)) return false;
    if (!invert(F, Finv)) return false;
    if (fp_inv_out) mat_mul(Finv, Fe, fp_inv_out);
    for (int i = 0; i < 3; ++i)  // P = tau F^-T
      for (int j = 0; j < 3; ++j)
        P[3 * i + j] = tau[3 * i] * Finv[3 * j] + tau[3 * i + 1] * Finv[3 * j + 1] +
                       tau[3 * i + 2] * Finv[3 * j + 2];
    return true;
  }

  //! Internal force of the state u1 into fint (3 per node); trial constitutive states.
  //! with_mises: also the step's largest von Mises stress (a diagnostic that scales the yield
  //! probes: taken once per step, at the predictor, not on every Newton iterate).
  bool internal(bool with_mises) {
    PhaseTimer timer(tr.time_internal);
    std::fill(fint.begin(), fint.end(), 0.0);
    if (with_mises) step_max_mises = 0, step_continued = 0;
    if (vector_pass) {
      pass.u = u1.data();
      pass.v = v1.data();
      pass.alpha = bubbles ? al1.data() : nullptr;
      pass.alpha_rate = bubbles ? ald1.data() : nullptr;
      pass.q = visco ? qv.data() : nullptr;
      pass.q_new = visco ? qv_new.data() : nullptr;
      pass.max_mises = with_mises ? &step_max_mises : nullptr;
      pass.continued = with_mises ? &step_continued : nullptr;
      pass.fint = fint.data();
      pass.ral = ral.data();
      elastic_force_pass(pass);
      return true;
    }
    for (std::size_t vx = 0; vx < nv; ++vx) {
      double xe[kShapes][3] = {}, ve[kShapes][3] = {}, fe[kShapes][3] = {};
      for (int l = 0; l < 8; ++l) {
        const std::size_t n = static_cast<std::size_t>(md_.vox_node_[vx][l]);
        for (int d = 0; d < 3; ++d) xe[l][d] = md_.X_[n][d] + u1[3 * n + d];
        if (kelvin_voigt)  // nodal velocities only for the viscous stress
          for (int d = 0; d < 3; ++d) ve[l][d] = v1[3 * n + d];
      }
      if (bubbles)
        for (int i = 0; i < 9; ++i) {
          xe[8 + i / 3][i % 3] = al1[9 * vx + static_cast<std::size_t>(i)];
          ve[8 + i / 3][i % 3] = ald1[9 * vx + static_cast<std::size_t>(i)];
        }
      for (int q = 0; q < 8; ++q)
        if (!gauss_point_force(vx, q, xe, ve, with_mises, fe)) return false;
      for (int l = 0; l < 8; ++l) {  // one scatter per voxel
        const std::size_t n = static_cast<std::size_t>(md_.vox_node_[vx][l]);
        for (int i = 0; i < 3; ++i) fint[3 * n + i] += fe[l][i];
      }
      if (bubbles)
        for (int i = 0; i < 9; ++i)
          ral[9 * vx + static_cast<std::size_t>(i)] = fe[8 + i / 3][i % 3];
    }
    return true;
  }

  //! Gauss point q of voxel vx in the scalar element loop: its stress (elastic or plastic,
  //! relaxed, with the viscous stress, times the voxel's factor) scattered into fe.
  bool gauss_point_force(std::size_t vx, int q, const double (&xe)[kShapes][3],
                         const double (&ve)[kShapes][3], bool with_mises,
                         double (&fe)[kShapes][3]) {
    const std::size_t g = 8 * vx + static_cast<std::size_t>(q);
    double F[9], P[9], tau[9];
    grad_at(G[q], xe, F);
    if (plastic) {
      if (!plastic_stress(g, F, P, tau, &pstate_new[g], &fp_inv_new[9 * g])) return false;
    } else {
      if (elastic_stress(F, P) && with_mises) ++step_continued;
    }
    if (visco) {
      // Relaxing part q: dq/dt = (g P_el - q) / tau (backward Euler); stress P_el - q.
      for (int i = 0; i < 9; ++i) {
        qv_new[9 * g + i] = (qv[9 * g + i] + rv * tm.prony_g * P[i]) / (1.0 + rv);
        P[i] -= qv_new[9 * g + i];
      }
    }
    if (kelvin_voigt) add_viscous_stress(q, F, ve, P);
    for (int i = 0; i < 9; ++i) P[i] *= vfac[vx];
    if (with_mises) {
      if (!plastic)
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j)
            tau[3 * i + j] =
                P[3 * i] * F[3 * j] + P[3 * i + 1] * F[3 * j + 1] + P[3 * i + 2] * F[3 * j + 2];
      step_max_mises = std::max(step_max_mises, mises(tau));
    }
    scatter_at(G[q], P, h[0] * h[1] * h[2] / 8.0, fe);
    return true;
  }

  //! Stiffness-proportional (Kelvin-Voigt) damping as a viscous stress: beta times the linear
  //! elastic law applied to the Green strain rate sym(F^T dF/dt), P_v = F S_v. It is beta K v
  //! for small motions, and it does not resist rigid rotation (beta K0 v would: a cantilever
  //! swinging through large angles would be damped spuriously). Under the linear law, whose
  //! own stress resists rotation alike, it is beta times that law of sym(dF/dt): the step stays
  //! linear (one solve a step).
  void add_viscous_stress(int q, const double F[9], const double (&ve)[kShapes][3],
                          double P[9]) const {
    constexpr bool kLinear = kLinearLaw;
    double Fd[9], Ed[9];
    grad_at(G[q], ve, Fd);  // dF/dt
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) {
        double e = 0;
        if constexpr (kLinear)
          e = Fd[3 * i + j] + Fd[3 * j + i];
        else
          for (int k = 0; k < 3; ++k)
            e += F[3 * k + i] * Fd[3 * k + j] + Fd[3 * k + i] * F[3 * k + j];
        Ed[3 * i + j] = 0.5 * e;
      }
    const double trace = Ed[0] + Ed[4] + Ed[8];
    double Sv[9];
    for (int i = 0; i < 9; ++i) Sv[i] = tm.rayleigh_beta * 2.0 * mu0 * Ed[i];
    for (int i = 0; i < 3; ++i) Sv[4 * i] += tm.rayleigh_beta * lambda0 * trace;
    if constexpr (kLinear) {
      for (int i = 0; i < 9; ++i) P[i] += Sv[i];
      return;
    }
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        P[3 * i + j] += F[3 * i] * Sv[j] + F[3 * i + 1] * Sv[3 + j] + F[3 * i + 2] * Sv[6 + j];
  }

  //! dP/dF at Gauss point g (deformation gradient F) into D: of the plastic return map from
  //! the step's start by forward differences (10 return maps, not 18: the tangent only steers
  //! Newton, whose stopping test is on the residual's correction, so its O(eps) error costs
  //! nothing in accuracy), the law's analytic Jacobian, or central differences.
  void stress_jacobian(std::size_t g, const double F[9], double (&D)[9][9]) const {
    if (plastic) {
      const double eps = 1e-7;
      double P0[9] = {}, tau[9], st;
      plastic_stress(g, F, P0, tau, &st, nullptr);
      for (int j = 0; j < 9; ++j) {
        double Fp[9], Pp[9] = {};
        std::copy(F, F + 9, Fp);
        Fp[j] += eps;
        plastic_stress(g, Fp, Pp, tau, &st, nullptr);
        for (int i = 0; i < 9; ++i) D[i][j] = (Pp[i] - P0[i]) / eps;
      }
    } else if constexpr (HasPk1Jacobian<Law>::value) {
      materials::Mat3 Fm;
      std::copy(F, F + 9, Fm.a);
      law.pk1_jacobian(Fm, D);  // analytic: one SVD instead of 18 (corotated)
    } else {
      const double eps = 1e-6;
      for (int j = 0; j < 9; ++j) {
        double Fp[9], Fm[9], Pp[9] = {}, Pm[9] = {};
        std::copy(F, F + 9, Fp);
        std::copy(F, F + 9, Fm);
        Fp[j] += eps;
        Fm[j] -= eps;
        elastic_stress(Fp, Pp);
        elastic_stress(Fm, Pm);
        for (int i = 0; i < 9; ++i) D[i][j] = (Pp[i] - Pm[i]) / (2 * eps);
      }
    }
  }

  //! The element tangent of voxel vx at positions xe in the scalar element loop.
  //! w: h/8 times the voxel's factors, as for the kernel.
  void element_tangent(std::size_t vx, const double (&xe)[kShapes][3], double w,
                       ElemMat& Ke) const {
    const int nshape = bubbles ? kShapes : 8;
    Ke = ElemMat::Zero();
    for (int q = 0; q < 8; ++q) {
      double F[9], D[9][9];
      grad_at(G[q], xe, F);
      stress_jacobian(8 * vx + static_cast<std::size_t>(q), F, D);
      // T[l][a][b][e] = sum_c dN_l,c Dsym[ac][be]; Ke[la][mb] += w sum_e T dN_m,e
      double T[kShapes][3][3][3];
      for (int l = 0; l < nshape; ++l)
        for (int i = 0; i < 3; ++i)
          for (int b = 0; b < 3; ++b)
            for (int e = 0; e < 3; ++e) {
              double t = 0;
              for (int c = 0; c < 3; ++c)
                t += Dn[q][l][c] * 0.5 * (D[3 * i + c][3 * b + e] + D[3 * b + e][3 * i + c]);
              T[l][i][b][e] = w * t;
            }
      // Ke is symmetric (D symmetrised): its upper triangle only, mirrored below.
      for (int l = 0; l < nshape; ++l)
        for (int i = 0; i < 3; ++i)
          for (int m = l; m < nshape; ++m)
            for (int b = m == l ? i : 0; b < 3; ++b)
              Ke(3 * l + i, 3 * m + b) += T[l][i][b][0] * Dn[q][m][0] +
                                          T[l][i][b][1] * Dn[q][m][1] + T[l][i][b][2] * Dn[q][m][2];
    }
    for (int j = 0; j < 3 * nshape; ++j)
      for (int i = j + 1; i < 3 * nshape; ++i) Ke(i, j) = Ke(j, i);
  }

  //! A voxel's node positions for the displacements uu, and its bubble amplitudes from aa.
  void element_coords(std::size_t vx, const std::vector<double>& uu, const std::vector<double>& aa,
                      double xe[kShapes][3]) const {
    for (int l = 0; l < 8; ++l) {
      const std::size_t n = static_cast<std::size_t>(md_.vox_node_[vx][l]);
      for (int d = 0; d < 3; ++d) xe[l][d] = md_.X_[n][d] + uu[3 * n + d];
    }
    if (bubbles)
      for (int i = 0; i < 9; ++i) xe[8 + i / 3][i % 3] = aa[9 * vx + static_cast<std::size_t>(i)];
  }

  //! Tangent stiffness at u1: dP/dF of the law (with plasticity: of the return map from the
  //! step's start) per Gauss point (symmetrised), scaled like the stress (region factor,
  //! relaxed viscous part).
  bool tangent() {
    PhaseTimer timer(tr.time_tangent);
    double* kval = Kt.valuePtr();
    std::fill(kval, kval + Kt.nonZeros(), 0.0);
    std::size_t slot = 0;
    const double vscale = visco ? 1.0 - tm.prony_g * rv / (1.0 + rv) : 1.0;
    Condensed ce;
    for (std::size_t vx = 0; vx < nv; ++vx) {
      double xe[kShapes][3] = {};
      element_coords(vx, u1, al1, xe);
      ElemMat Ke;
      const double w = w_tangent * vfac[vx] * vscale;
      if (vector_tangent)
        elastic_element_tangent(vtangent, xe, w, Ke.data());
      else
        element_tangent(vx, xe, w, Ke);
      if (bubbles) {
        if (!condense(Ke, ce)) return false;
        condL[vx] = ce.L;
        condLt[vx] = ce.L.transpose();
        condKinv[vx] = ce.Kinv;
      } else {
        ce.Kc = Ke.block<24, 24>(0, 0);
      }
      for (int l = 0; l < 8; ++l) {
        const int dl = dof[static_cast<std::size_t>(md_.vox_node_[vx][l])];
        if (dl < 0) continue;
        for (int m = 0; m < 8; ++m) {
          const int dm = dof[static_cast<std::size_t>(md_.vox_node_[vx][m])];
          if (dm < 0) continue;
          for (int i = 0; i < 3; ++i)
            for (int b = 0; b < 3; ++b) kval[kslot[slot++]] += ce.Kc(3 * l + i, 3 * m + b);
        }
      }
    }
    return true;
  }

  //! Sampling: the nodes any channel reads, stored per step, for one step past the last
  //! sample's (a sample then never sits at the end of the history, and its value does not
  //! depend on which later samples were asked for: a run cut at a horizon gives the full run's
  //! values bit for bit).
  void setup_sampling(const std::vector<ChannelRequest>& req) {
    double t_last = 0;
    for (const auto& r : req)
      if (!r.t.empty()) t_last = std::max(t_last, r.t.back());
    t_last += std::max(0.0, ph.time_offset);
    nsteps = static_cast<long>(std::ceil(t_last / dt - 1e-9)) + 1;
    sample_slot.assign(nn, -1);
    for (const auto& r : req)
      for (int l = 0; l < 8; ++l) {
        const std::size_t n = static_cast<std::size_t>(r.at.node[l]);
        if (sample_slot[n] < 0)
          sample_slot[n] = static_cast<int>(sampled.size()), sampled.push_back(n);
      }
    ns = sampled.size();
    hist_u.resize(9 * ns * static_cast<std::size_t>(nsteps + 1));
  }

  void record(long s) {
    double* out = &hist_u[9 * ns * static_cast<std::size_t>(s)];
    for (std::size_t i = 0; i < ns; ++i)
      for (int d = 0; d < 3; ++d) {
        out[9 * i + d] = u[3 * sampled[i] + d];
        out[9 * i + 3 + d] = v[3 * sampled[i] + d];
        out[9 * i + 6 + d] = a[3 * sampled[i] + d];
      }
  }

  //! Applied loads: gravity plus the deck's force regions shared by mass over free nodes.
  void setup_loads() {
    region_mass.assign(md_.cfg_.forces.size(), 0.0);
    for (std::size_t n = 0; n < nn; ++n)
      if (!md_.fixed_[n])
        for (std::size_t r = 0; r < md_.cfg_.forces.size(); ++r)
          if (md_.cfg_.forces[r].region.contains(md_.X_[n])) region_mass[r] += md_.mass_[n];
    t_tol = 1e-6 * dt;
  }

  //! A force switched on or off exactly at a step time counts half there (the mean of its
  //! one-sided limits): the trapezoidal rule then delivers the pulse's exact impulse (counting
  //! it fully, or not at all, at its end adds or drops half a step of impulse). A force that
  //! starts at t = 0 acts fully from the initial state.
  //! A pre-load (start < 0) released at t = 0 is off from the first instant, or goes over
  //! Physics::release_duration.
  double on_fraction(const ForceConfig& fc, double t) const {
    if (fc.start < 0 && ph.release_duration > 0) {
      const double s = (t - fc.end) / ph.release_duration;
      return s <= 0 ? 1.0 : s >= 1 ? 0.0 : 0.5 * (1 + std::cos(kPi * s));
    }
    if (fc.start < 0 && fc.end <= t_tol && t <= t_tol) return 0.0;
    const bool at_start = std::abs(t - fc.start) <= t_tol && fc.start > 0;
    const bool at_end = std::abs(t - fc.end) <= t_tol;
    if (at_start && at_end) return 0.0;
    if (at_start || at_end) return 0.5;
    return (t >= fc.start && t < fc.end) ? 1.0 : 0.0;
  }

  //! Gravity and the forces on node n at time t; with statics, the loads before the run
  //! starts: gravity and the pre-loads.
  void external(double t, std::size_t n, double f[3], bool statics = false) const {
    const double m = mass_of(n);
    for (int d = 0; d < 3; ++d) f[d] = m * ph.gravity[d];
    if (md_.fixed_[n]) return;
    for (std::size_t r = 0; r < md_.cfg_.forces.size(); ++r) {
      const ForceConfig& fc = md_.cfg_.forces[r];
      if (region_mass[r] == 0.0 || !fc.region.contains(md_.X_[n])) continue;
      const double on = statics ? (fc.start < 0 ? 1.0 : 0.0) : on_fraction(fc, t);
      if (on == 0.0) continue;
      for (int d = 0; d < 3; ++d)
        f[d] += on * ph.load_scale * fc.force[d] * md_.mass_[n] / region_mass[r];
    }
  }

  //! The pre-loads ([[force]] with start < 0): the body starts at rest in static equilibrium
  //! under them and gravity. Newton on the step's equations without inertia (ca = cv = 0: the
  //! step matrix is the static tangent, clamp springs included), from the rest state; then the
  //! step matrix of the motion. f_static keeps the loads the state balances.
  bool preload() {
    const double ca0 = ca, cv0 = cv;
    ca = cv = 0;
    const bool built = setup_step_matrix();
    for (std::size_t n = 0; n < nn; ++n)
      if (dof[n] >= 0) external(0.0, n, &fext[3 * n], true);
    u1 = u, al1 = al;
    const bool ok = built && newton(1);
    ca = ca0, cv = cv0;
    if (!built) return false;
    if (!ok)
      return fail(
          "the static equilibrium under the pre-loads ([[force]] start < 0) did not "
          "converge");
    u.swap(u1);
    al.swap(al1);
    if (plastic) fp_inv.swap(fp_inv_new), pstate.swap(pstate_new);
    f_static = fext;
    return setup_step_matrix();
  }

  //! Initial acceleration from rest: M a0 = f_ext(0) - f_int(u0), where f_int(u0) balances the
  //! pre-loads (f_static) or is zero (the body at rest in its reference shape).
  void initial_acceleration() {
    Eigen::VectorXd f0(ndof), a0(ndof);
    for (std::size_t n = 0; n < nn; ++n) {
      if (dof[n] < 0) continue;
      double f[3];
      external(0.0, n, f);
      for (int d = 0; d < 3; ++d)
        f0[dof[n] + d] =
            f_static.empty() ? f[d] : f[d] - f_static[3 * n + static_cast<std::size_t>(d)];
    }
    if (consistent) {
      Eigen::ConjugateGradient<SpMat, Eigen::Lower | Eigen::Upper> cg(Mc);
      cg.setTolerance(1e-14);
      a0 = cg.solve(f0);
    } else {
      a0 = f0.cwiseQuotient(M);
    }
    for (std::size_t n = 0; n < nn; ++n)
      if (dof[n] >= 0)
        for (int d = 0; d < 3; ++d) a[3 * n + d] = a0[dof[n] + d];
  }

  //! The most compressed Gauss point of the last converged state (volume ratio J), and its
  //! voxel's centre: where a failing run's body was about to collapse.
  std::pair<double, Vec3d> most_compressed() const {
    double jmin = std::numeric_limits<double>::infinity();
    std::size_t vmin = 0;
    for (std::size_t vx = 0; vx < nv; ++vx) {
      double xe[kShapes][3] = {};
      element_coords(vx, u, al, xe);
      for (int q = 0; q < 8; ++q) {
        materials::Mat3 F;
        grad_at(G[q], xe, F.a);
        const double J = materials::det(F);
        if (J < jmin) jmin = J, vmin = vx;
      }
    }
    return std::make_pair(jmin, md_.voxel_center(vmin));
  }

  //! Predictor: the trapezoidal update with a1 guessed as the mean of the last two
  //! accelerations (smooth motion continues; a high mode that flips sign each step averages
  //! out instead of being doubled). The bubbles follow the predicted nodes through the
  //! condensed relation (their equations held at the end of the last step):
  //! alpha1 = alpha - L (u1 - u); or stay (bubbles_follow false).
  void predict(bool bubbles_follow) {
    for (std::size_t i = 0; i < 3 * nn; ++i)
      u1[i] = u[i] + dt * v[i] + 0.25 * dt * dt * (a[i] + 0.5 * (a[i] + a_prev[i]));
    for (std::size_t vx = 0; vx < al.size() / 9; ++vx) {
      Vec24 due;
      for (int l = 0; l < 8; ++l) {
        const std::size_t n = static_cast<std::size_t>(md_.vox_node_[vx][l]);
        for (int d = 0; d < 3; ++d) due[3 * l + d] = u1[3 * n + d] - u[3 * n + d];
      }
      Eigen::Map<Eigen::Matrix<double, 9, 1>> a1v(&al1[9 * vx]);
      a1v = Eigen::Map<const Eigen::Matrix<double, 9, 1>>(&al[9 * vx]);
      if (bubbles_follow) {
        double Ld[9];
        bubble_l_times(condL[vx].data(), due.data(), 1.0, Ld);
        for (int i = 0; i < 9; ++i) a1v[i] -= Ld[i];
      }
    }
  }

  //! a1, v1 and the bubbles' rates of the trial state u1, al1 (the trapezoidal rule).
  void trial_rates() {
    for (std::size_t i = 0; i < 3 * nn; ++i) {
      a1[i] = ca * (u1[i] - u[i] - dt * v[i]) - a[i];
      v1[i] = v[i] + 0.5 * dt * (a[i] + a1[i]);
    }
    for (std::size_t i = 0; i < al.size(); ++i) ald1[i] = cv * (al1[i] - al[i]) - ald[i];
  }

  //! The contact set at this iterate; whether it changed.
  bool update_contacts() {
    bool changed = false;
    for (std::size_t n = 0; n < nn; ++n) {
      if (dof[n] < 0) continue;
      for (std::size_t p = 0; p < planes.size(); ++p) {
        double gap = 0;
        for (int d = 0; d < 3; ++d)
          gap += (md_.X_[n][d] + u1[3 * n + d] - planes[p].p[d]) * planes[p].n[d];
        const char act = gap < 0;
        if (act != active[n * planes.size() + p])
          active[n * planes.size() + p] = act, changed = true;
      }
    }
    return changed;
  }

  //! Residual R of the free dofs at the trial state (stiffness damping is a stress, in fint);
  //! inertia and mass damping: M (a1 + alpha v1).
  void residual() {
    for (std::size_t n = 0; n < nn; ++n)
      if (dof[n] >= 0)
        for (int d = 0; d < 3; ++d)
          wa[dof[n] + d] = a1[3 * n + d] + tm.rayleigh_alpha * v1[3 * n + d];
    if (consistent && Mc_nodes.ok())
      Mc_nodes.apply(wa, Mwa);
    else if (consistent)
      Mwa.noalias() = Mc * wa;
    else
      Mwa = M.cwiseProduct(wa);
    for (std::size_t n = 0; n < nn; ++n) {
      if (dof[n] < 0) continue;
      const double* f = &fext[3 * n];
      const int i0 = dof[n];
      const double m = mass_of(n);
      const double* vn = &v1[3 * n];
      const double* v0 = &v[3 * n];
      for (int d = 0; d < 3; ++d)
        R[i0 + d] =
            Mwa[i0 + d] + Cd[i0 + d] * vn[d] + fint[3 * n + d] - f[d] + Ks[i0 + d] * u1[3 * n + d];
      for (const auto& nf : tm.node_forces) nf->add_residual(force_node(n, m), vn, v0, dt, &R[i0]);
      for (std::size_t p = 0; p < planes.size(); ++p)
        if (active[n * planes.size() + p]) contact_residual(n, planes[p], m, v0, i0);
    }
    if (clamp_faces) clamp_residual();
    bubble_residual();
  }

  //! A penalty contact's normal force and its Coulomb friction against the velocity at the
  //! step's start (explicit in direction, capped so it can at most stop the node).
  void contact_residual(std::size_t n, const Plane& pl, double m, const double* v0, int i0) {
    double gap = 0;
    for (int d = 0; d < 3; ++d) gap += (md_.X_[n][d] + u1[3 * n + d] - pl.p[d]) * pl.n[d];
    const double fn = -k_pen * gap;  // >= 0, along n
    double vt[3], vt2 = 0, v0n = 0;
    for (int d = 0; d < 3; ++d) v0n += v0[d] * pl.n[d];
    for (int d = 0; d < 3; ++d) vt[d] = v0[d] - v0n * pl.n[d], vt2 += vt[d] * vt[d];
    const double vt_norm = std::sqrt(vt2);
    const double ft = vt_norm > 0 ? std::min(pl.mu * fn, m * vt_norm / dt) / vt_norm : 0.0;
    for (int d = 0; d < 3; ++d) R[i0 + d] -= fn * pl.n[d] - ft * vt[d];
  }

  //! The clamp faces' foundation: k u + c v, integrated over each face.
  void clamp_residual() {
    for (std::size_t fi = 0; fi < md_.clamp_faces_.size(); ++fi)
      for (int q = 0; q < 4; ++q) {
        const auto& f = md_.clamp_faces_[fi];
        const int i0 = dof[static_cast<std::size_t>(f[q])];
        for (int r = 0; r < 4; ++r) {
          const std::size_t m3 = 3 * static_cast<std::size_t>(f[r]);
          const double w = foundation(fi, q, r);
          for (int d = 0; d < 3; ++d)
            R[i0 + d] += w * (clamp_k(fi, d) * u1[m3 + static_cast<std::size_t>(d)] +
                              tm.clamp_damping * v1[m3 + static_cast<std::size_t>(d)]);
        }
      }
  }

  //! Condensed residual: the bubbles' residual r_a carried to the nodes, R - L^T r_a.
  void bubble_residual() {
    for (std::size_t vx = 0; vx < al.size() / 9; ++vx) {
      double fr[24];
      bubble_lt_times(condLt[vx].data(), &ral[9 * vx], fr);
      for (int l = 0; l < 8; ++l) {
        const int dl = dof[static_cast<std::size_t>(md_.vox_node_[vx][l])];
        if (dl >= 0)
          for (int d = 0; d < 3; ++d) R[dl + d] -= fr[3 * l + d];
      }
    }
  }

  //! Solves for the correction and applies it to the nodes and the bubbles; the largest
  //! correction (m).
  double correct() {
    {
      PhaseTimer timer(tr.time_solve);
      solver.solve(R, du);  // the correction is -du
    }
    double dmax = 0;
    for (std::size_t n = 0; n < nn; ++n)
      if (dof[n] >= 0)
        for (int d = 0; d < 3; ++d) {
          u1[3 * n + d] -= du[dof[n] + d];
          dmax = std::max(dmax, std::abs(du[dof[n] + d]));
        }
    // Bubbles: delta alpha = -Kaa^-1 r_a - L delta u (delta u = -du); Kaa carries the step
    // matrix's factor for stiffness damping like the rest of the tangent.
    const double kscale = 1.0 / (1.0 + cv * tm.rayleigh_beta);
    for (std::size_t vx = 0; vx < al.size() / 9; ++vx) {
      Vec24 due;
      for (int l = 0; l < 8; ++l) {
        const int dl = dof[static_cast<std::size_t>(md_.vox_node_[vx][l])];
        for (int d = 0; d < 3; ++d) due[3 * l + d] = dl >= 0 ? du[dl + d] : 0.0;
      }
      double Ld[9], Kr[9];
      bubble_l_times(condL[vx].data(), due.data(), 1.0, Ld);
      bubble_kinv_times(condKinv[vx].data(), &ral[9 * vx], kscale, Kr);
      for (int i = 0; i < 9; ++i) {
        const double da = Ld[i] - Kr[i];
        al1[9 * vx + static_cast<std::size_t>(i)] += da;
        dmax = std::max(dmax, std::abs(da));
      }
    }
    return dmax;
  }

  //! Newton with a lagged tangent from the predictor (attempt 0); if it diverges (with plastic
  //! unloading, a stale bubble stiffness can over-correct the bubbles) or stalls, the step
  //! starts again from the predictor with the tangent rebuilt at every iterate (attempt 1).
  //! Whether it converged.
  bool newton(int attempt) {
    const bool full_newton = attempt == 1;
    bool refresh = full_newton;
    double dmax_prev = 0;
    for (int it = 0; it < 60; ++it) {
      trial_rates();
      if (!internal(it == 0)) return false;
      const bool changed = it < 8 && update_contacts();  // then the contact set stays fixed
      if (refresh && !tangent()) return false;
      if ((changed || refresh) && !factor()) return false;
      refresh = false;
      residual();
      const double dmax = correct();
      ++tr.newton_iterations;
      if (!std::isfinite(dmax)) return false;
      if (dmax < tol_du || (linear_steps && !full_newton)) return true;
      if (attempt == 0 && it >= 1 && dmax > 2 * dmax_prev && dmax > 100 * tol_du) return false;
      // A stale tangent shows as slow contraction: rebuild it at the current state.
      if ((full_newton && dmax > 0.1 * dmax_prev) ||
          (it > 1 && dmax > ph.refresh_contraction * dmax_prev))
        refresh = true;
      dmax_prev = dmax;
    }
    return false;
  }

  //! Step s: to t = s dt, then the state moves on; false (tr says why) if it did not converge.
  bool step(long s) {
    const double t1 = dt * static_cast<double>(s);
    predict(true);
    for (std::size_t n = 0; n < nn; ++n)  // the step's applied loads
      if (dof[n] >= 0) external(t1, n, &fext[3 * n]);
    bool converged = false;
    for (int attempt = 0; attempt < 2 && !converged; ++attempt) {
      if (attempt == 1) {
        predict(false);
        ++tr.restarts;
      }
      converged = newton(attempt);
    }
    if (!converged) {
      const auto [jmin, at] = most_compressed();
      return fail(fmt::format(
          "step {} (t = {:.4g} s) did not converge (smallest volume ratio {:.3g} of the last "
          "converged step, in the voxel at ({:.4g}, {:.4g}, {:.4g}) m)",
          s, t1, jmin, at[0], at[1], at[2]));
    }
    trial_rates();
    al.swap(al1);
    ald.swap(ald1);
    a_prev = a;
    u.swap(u1);
    v.swap(v1);
    a.swap(a1);
    if (plastic) fp_inv.swap(fp_inv_new), pstate.swap(pstate_new);
    if (visco) qv.swap(qv_new);
    tr.max_mises = std::max(tr.max_mises, step_max_mises);
    tr.continued_points += step_continued;
    for (std::size_t n = 0; n < nn; ++n) {
      const double* vn = &v[3 * n];
      tr.max_speed =
          std::max(tr.max_speed, std::sqrt(vn[0] * vn[0] + vn[1] * vn[1] + vn[2] * vn[2]));
    }
    record(s);
    ++tr.steps;
    return true;
  }

  //! Samples: cubic Hermite between steps for positions, linear for accelerations.
  void sample(const std::vector<ChannelRequest>& req) {
    tr.channel.resize(req.size());
    for (std::size_t c = 0; c < req.size(); ++c) {
      const ChannelRequest& r = req[c];
      auto& out = tr.channel[c];
      out.resize(3 * r.t.size());
      for (std::size_t k = 0; k < r.t.size(); ++k) sample_at(r, r.t[k], &out[3 * k]);
    }
  }

  void sample_at(const ChannelRequest& r, double t_recording, double* out) const {
    const double t = t_recording + ph.time_offset;
    if (t < 0 && r.acceleration) {  // at rest before the model's start
      out[0] = out[1] = out[2] = 0.0;
      return;
    }
    const double tt = std::max(0.0, t);
    long s0 = std::min(static_cast<long>(std::floor(tt / dt)), std::max(0L, nsteps - 1));
    if (nsteps == 0) s0 = 0;
    const long s1 = std::min(s0 + 1, nsteps);
    const double th =
        s1 > s0 ? std::clamp((tt - dt * static_cast<double>(s0)) / dt, 0.0, 1.0) : 0.0;
    const double h00 = 2 * th * th * th - 3 * th * th + 1, h10 = th * th * th - 2 * th * th + th,
                 h01 = -2 * th * th * th + 3 * th * th, h11 = th * th * th - th * th;
    for (int d = 0; d < 3; ++d) {
      double val = 0;
      for (int l = 0; l < 8; ++l) {
        const std::size_t n = static_cast<std::size_t>(r.at.node[l]);
        const std::size_t slot = static_cast<std::size_t>(sample_slot[n]);
        const double* A0s = &hist_u[9 * ns * static_cast<std::size_t>(s0) + 9 * slot];
        const double* A1s = &hist_u[9 * ns * static_cast<std::size_t>(s1) + 9 * slot];
        double x;
        if (r.acceleration)
          x = (1 - th) * A0s[6 + d] + th * A1s[6 + d];
        else
          x = md_.X_[n][d] + h00 * A0s[d] + h10 * dt * A0s[3 + d] + h01 * A1s[d] +
              h11 * dt * A1s[3 + d];
        val += r.at.w[l] * x;
      }
      out[d] = val;
    }
  }
};

namespace {

//! A law known only by its registry entry (called through std::function).
struct RegistryLaw {
  materials::MaterialInstance m;
  materials::Mat3 pk1(const materials::Mat3& F) const { return m.pk1(F); }
};

}  // namespace

std::vector<double> VoxelModel::stiffness_factors(const ModelTerms& tm) const {
  std::vector<double> f(vox_node_.size(), 1.0);
  if (!tm.stiffness_boxes.empty())
    for (std::size_t v = 0; v < f.size(); ++v) f[v] = tm.stiffness_factor(voxel_center(v));
  return f;
}

bool VoxelModel::rest_matrices(const Physics& ph, SpMat& K, SpMat& M, std::vector<int>& dof,
                               int& ndof) const {
  const ModelTerms tm = model_terms(ph);
  if (std::isfinite(tm.clamp_stiffness) || std::isfinite(tm.clamp_normal_stiffness) ||
      !tm.planes.empty() || !cfg_.colliders.empty() || !tm.added_masses.empty())
    return false;
  dof = free_dofs(fixed_, false, ndof);
  if (ndof == 0) return false;
  const double nu = ph.poisson_ratio, E = ph.youngs_modulus;
  Condensed c0;
  if (!rest_element(ph.element == Element::incompatible, h_, E * nu / ((1 + nu) * (1 - 2 * nu)),
                    E / (2 * (1 + nu)), c0))
    return false;
  std::vector<Eigen::Triplet<double>> trip;
  K = assemble_stiffness(vox_node_, dof, ndof, stiffness_factors(tm), c0.Kc, trip);
  M = assemble_mass(vox_node_, dof, ndof, mass_, ph.density,
                    std::clamp(ph.consistent_mass_fraction, 0.0, 1.0), h_, point_mass_);
  return true;
}

double VoxelModel::rest_frequency(const Physics& ph, const Vec3d& direction) const {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  SpMat K, M;
  std::vector<int> dof;
  int ndof = 0;
  if (!rest_matrices(ph, K, M, dof, ndof)) return nan;
  BlockLDLT solver;
  solver.analyze(K);
  if (!solver.factorize(K)) return nan;
  // Inverse iteration K y = M x from a uniform displacement along `direction`; the Rayleigh
  // quotient y'K y / y'M y = y'M x / y'M y converges at (omega_1 / omega_2)^2 per step.
  Eigen::VectorXd x(ndof), y;
  for (std::size_t n = 0; n < dof.size(); ++n)
    if (dof[n] >= 0)
      for (int a = 0; a < 3; ++a) x[dof[n] + a] = direction[static_cast<std::size_t>(a)];
  double lambda = 0;
  for (int it = 0; it < 100; ++it) {
    const Eigen::VectorXd Mx = M * x;
    solver.solve(Mx, y);
    const double yMy = y.dot(M * y);
    if (!(yMy > 0) || !std::isfinite(yMy)) return nan;
    const double next = y.dot(Mx) / yMy;
    x = y / std::sqrt(yMy);
    const bool done = std::abs(next - lambda) <= 1e-13 * std::abs(next);
    lambda = next;
    if (done) break;
  }
  return lambda > 0 && std::isfinite(lambda) ? std::sqrt(lambda) : nan;
}

std::vector<double> VoxelModel::rest_modes(const Physics& ph, int count) const {
  SpMat K, M;
  std::vector<int> dof;
  int ndof = 0;
  if (count <= 0 || !rest_matrices(ph, K, M, dof, ndof)) return {};
  BlockLDLT solver;
  solver.analyze(K);
  if (!solver.factorize(K)) return {};
  // Subspace iteration: X <- K^-1 M X, then Rayleigh-Ritz on span(X), with count + 4 vectors
  // from smooth start fields (uniform and linear in the rest position along each axis).
  const int m = std::min(ndof, count + 4);
  Eigen::MatrixXd X(ndof, m);
  for (std::size_t n = 0; n < dof.size(); ++n)
    if (dof[n] >= 0)
      for (int j = 0; j < m; ++j)
        for (int a = 0; a < 3; ++a)
          X(dof[n] + a, j) =
              (j % 3 == a ? 1.0 : 0.1) *
              std::pow(X_[n][(j / 3) % 3] - bounds_.lo[(j / 3) % 3] + 1e-3, 1 + j / 3);
  Eigen::VectorXd lambda = Eigen::VectorXd::Zero(m), y;
  for (int it = 0; it < 100; ++it) {
    Eigen::MatrixXd Y(ndof, m);
    for (int j = 0; j < m; ++j) {
      solver.solve(M * X.col(j), y);
      Y.col(j) = y;
    }
    const Eigen::MatrixXd Kr = Y.transpose() * (K * Y), Mr = Y.transpose() * (M * Y);
    const Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> ritz(Kr, Mr);
    if (ritz.info() != Eigen::Success) return {};
    X = Y * ritz.eigenvectors();
    const Eigen::VectorXd next = ritz.eigenvalues();
    const bool done =
        ((next - lambda).head(count).array().abs() <= 1e-10 * next.head(count).array().abs()).all();
    lambda = next;
    if (done) break;
  }
  std::vector<double> omega;
  for (int j = 0; j < count; ++j)
    omega.push_back(lambda[j] > 0 ? std::sqrt(lambda[j])
                                  : std::numeric_limits<double>::quiet_NaN());
  return omega;
}

Trace VoxelModel::run(const Physics& ph, const std::vector<ChannelRequest>& req) const {
  const double E = ph.youngs_modulus, nu = ph.poisson_ratio;
  RegistryLaw generic{materials::find_material(ph.law).build(E, nu)};  // validates E, nu
  const std::string law = materials::canonical_law(ph.law, materials::Solver::Voxel);
  const ModelTerms tm = model_terms(ph);
  // The common laws get their own instantiation of the element loops (inlined stress).
  if (law == materials::StVK::name)
    return VoxelRun<materials::StVK>(*this, ph, tm, materials::StVK::from_young_poisson(E, nu))
        .run(req);
  if (law == materials::NeoHookean::name)
    return VoxelRun<materials::NeoHookean>(*this, ph, tm,
                                           materials::NeoHookean::from_young_poisson(E, nu))
        .run(req);
  if (law == materials::FixedCorotated::name)
    return VoxelRun<materials::FixedCorotated>(*this, ph, tm,
                                               materials::FixedCorotated::from_young_poisson(E, nu))
        .run(req);
  if (law == materials::LinearElastic::name)
    return VoxelRun<materials::LinearElastic>(*this, ph, tm,
                                              materials::LinearElastic::from_young_poisson(E, nu))
        .run(req);
  return VoxelRun<RegistryLaw>(*this, ph, tm, generic).run(req);
}

}  // namespace gen4d::forward

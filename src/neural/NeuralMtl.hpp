//! NeuralMTL: a small MLP on the singular values of F that predicts a neural strain whose
//! quadratic energy reproduces a hyperelastic law (seed section "NeuralMTL & neural
//! projection", Eq. 5-9), and the fused CPU kernel that evaluates it inside the time loop.
//
// Definition (all quantities per unit reference volume, energies normalised by E):
//   input       x = sigma - 1, sigma = signed singular values of F, descending (SVD activation)
//   raw output  m(x) = W_L tanh(... tanh(W_1 x + b_1) ...) + b_L          (the MLP)
//   activation  n(sigma) = m(sigma - 1) - m(0): the material-space neural strain, placed on the
//               principal axes, S = V diag(n) V^T. It is symmetric by construction, depends on
//               F only through sigma (so it is invariant to rotations of F), and vanishes at rest.
//   energy      Psi_N(F) = E/2 |n(sigma)|^2 = E psi_N(sigma)
//   stress      P_N = E U diag(d psi_N / d sigma) V^T  (exact gradient; d psi_N/d sigma =
//               J_n^T n by one reverse pass through the MLP)
//   target      p = F - P_N / k = R V diag(sigma - (E/k) J_n^T n) V^T with R = U V^T: the
//               neural projection, rotation of F times a neural-strain-defined stretch.
// Because Psi of every supported law is linear in E at fixed nu, psi_N depends on nu only;
// E enters exactly through the scale factor.
#pragma once

#include <array>
#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include "materials/Mat3.hpp"
#include "neural/NeuralMtlKernel.hpp"

namespace gen4d::neural {

inline constexpr const char* kWeightsFormat = "gen4d-neuralmtl";
inline constexpr long kWeightsVersion = 1;

//! Laws a NeuralMTL can be fitted to (the hyperelastic laws of src/materials).
const std::vector<std::string>& neural_laws();
//! Index of `law` in neural_laws(); InputError naming `where` and the known laws otherwise.
int law_index(const std::string& law, const std::string& where);

//! Ground truth: psi(sigma) = Psi(diag(sigma)) / E for `law` at Poisson ratio nu, and its
//! gradient d psi / d sigma (the principal stresses over E). Any E gives the same values.
double law_energy(int law, double nu, const double sigma[3], double grad[3]);

struct Layer {
  int in = 0, out = 0;
  std::vector<double> W;  //!< out x in, row-major
  std::vector<double> b;  //!< out
};

struct NeuralMtlWeights {
  std::string law;           //!< one of neural_laws()
  double poisson_ratio = 0;  //!< nu the network represents
  std::string source;        //!< provenance: "train-material", "generator", "generator+finetune"
  double fit_error = -1;  //!< RMS of log(1+psi_N) - log(1+psi) on held-out samples (< 0: unknown)
  std::vector<Layer> layers;  //!< tanh between layers, none after the last

  //! Zero-initialised 3 -> hidden... -> 3 network.
  static NeuralMtlWeights architecture(const std::vector<int>& hidden);
  std::vector<int> hidden() const;
  std::size_t parameter_count() const;
  //! Layer by layer, W (row-major) then b.
  std::vector<double> flatten() const;
  //! Inverse of flatten() for this architecture; std::invalid_argument on a size mismatch.
  void unflatten(const std::vector<double>& flat);
  //! InputError naming `where` on a bad law, nu outside [0, 0.5), shapes that do not chain
  //! 3 -> ... -> 3, widths beyond the kernel's limits, or non-finite values.
  void validate(const std::string& where) const;
};

void write_weights(const std::string& path, const NeuralMtlWeights& w);
NeuralMtlWeights read_weights(const std::string& path);

//! The fused evaluator: MLP, activation, reverse pass and (in material form) target, for
//! batches of quadrature points. On the CPU, groups of points as wide as the vector registers
//! go through the network together (NeuralMtlKernel.hpp; built for AVX-512, AVX2 + FMA and the
//! baseline x86-64, picked at run time), and the groups are shared among the host threads
//! (exec::parallel_blocks). Every point's result is independent of the thread count.
class NeuralMtl {
 public:
  static constexpr int kLanes = 8;  //!< most points per NeuralMaterial::energy_and_pk1_cell

  explicit NeuralMtl(const NeuralMtlWeights& w);
  NeuralMtl(const NeuralMtl&) = delete;
  NeuralMtl& operator=(const NeuralMtl&) = delete;

  //! For n points (sigma: 3 per point): psi_N (may be null) and d psi_N / d sigma (3 per
  //! point; may be null), normalised by E.
  void evaluate(std::size_t n, const double* sigma, double* psi, double* dpsi) const;
  //! Raw outputs after the activation, n(sigma) (3 per point), as LibTorch's forward pass
  //! minus its value at rest.
  void strain(std::size_t n, const double* sigma, double* strain) const;

#if defined(GEN4D_CUDA)
  //! evaluate() on this rank's GPU (exec::use_device() must be true): sigma, psi and dpsi
  //! point to device memory (psi may be null). The weights are uploaded on the first call.
  //! Returns when the results are in place. Agrees with evaluate() to rounding (~1e-13).
  void evaluate_device(std::size_t n, const double* sigma, double* psi, double* dpsi) const;
#endif

  const std::string& law() const {
    return law_;
  }
  double poisson_ratio() const {
    return nu_;
  }
  //! Instruction set of the CPU kernel in use: "avx512", "avx2" or "baseline" (the widest
  //! this CPU runs, unless GEN4D_NEURAL_ISA names another or select_isa() chose one).
  static const char* isa();
  //! The instruction sets this CPU runs, "baseline" first.
  static std::vector<std::string> isas();
  //! Switches every NeuralMtl to one of isas() (for tests and benchmarks; not thread-safe);
  //! std::invalid_argument otherwise.
  static void select_isa(const std::string& isa);

  //! The network in the kernel's layout (host memory).
  const NetView& view() const {
    return view_;
  }

 private:
  struct DeviceCache;
  std::string law_;
  double nu_ = 0;
  std::array<std::vector<double>, kMaxLayers> W_, Wt_, b_;
  NetView view_;
  mutable std::shared_ptr<DeviceCache> device_;  // weights on the GPU, on first use
};

//! NeuralMTL as a pointwise material for the voxel solver: psi = E psi_N, P = E U diag(grad) V^T.
//! `projection_stiffness` is the k of the true law (the local model's weight).
struct NeuralMaterial {
  const NeuralMtl* net = nullptr;
  double youngs_modulus = 0;
  double stiffness = 0;

  double projection_stiffness() const { return stiffness; }
  double energy_and_pk1(const materials::Mat3& F, materials::Mat3& P) const;
  //! Eight quadrature points of one voxel at once (F, P: 9 per point, row-major); returns the
  //! sum of their energy densities.
  double energy_and_pk1_cell(const double* F, double* P, int count) const;
};

}  // namespace gen4d::neural

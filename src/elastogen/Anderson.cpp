#include "elastogen/Anderson.hpp"

#include <Eigen/Dense>

namespace gen4d::elastogen {

AndersonMixer::AndersonMixer(int depth, const VoxelSystem& sys, parallel::Reducer& reducer)
    : depth_(depth), sys_(sys), red_(reducer) {}

void AndersonMixer::reset() {
  has_prev_ = false;
  df_.clear();
  dg_.clear();
}

bool AndersonMixer::mix(const std::vector<double>& x, const std::vector<double>& delta,
                        std::vector<double>& x_next) {
  const Box& O = sys_.owned();
  const Box& G = sys_.ghosted();
  const auto& free = sys_.free_mask();
  x_next = x;
  std::vector<double> g(x.size(), 0.0);
  parallel_owned(O, G, [&](std::size_t n, long, long, long) {
    for (int d = 0; d < 3; ++d) g[3 * n + d] = x[3 * n + d] + delta[3 * n + d];
  });
  if (depth_ > 0 && has_prev_) {
    std::vector<double> df(x.size(), 0.0), dg(x.size(), 0.0);
    parallel_owned(O, G, [&](std::size_t n, long, long, long) {
      for (int d = 0; d < 3; ++d) {
        const std::size_t q = 3 * n + d;
        df[q] = delta[q] - prev_f_[q];
        dg[q] = g[q] - prev_g_[q];
      }
    });
    df_.push_back(std::move(df));
    dg_.push_back(std::move(dg));
    if (static_cast<int>(df_.size()) > depth_) {
      df_.pop_front();
      dg_.pop_front();
    }
  }
  prev_f_ = delta;
  prev_g_ = g;
  has_prev_ = true;
  const int m = static_cast<int>(df_.size());
  if (m == 0) {
    parallel_owned(O, G, [&](std::size_t n, long, long, long) {
      for (int d = 0; d < 3; ++d) x_next[3 * n + d] = g[3 * n + d];
    });
    return false;
  }
  // Normal equations dF^T dF gamma = dF^T f: all m(m+1)/2 + m dots in one fused reduction.
  std::vector<parallel::ExactSum> local(static_cast<std::size_t>(m * (m + 1) / 2 + m));
  reduce_owned(O, G, local.size(), local.data(),
               [&](std::size_t n, long, long, long, parallel::ExactSum* acc) {
                 if (!free[n]) return;
                 for (int d = 0; d < 3; ++d) {
                   const std::size_t q = 3 * n + d;
                   int c = 0;
                   for (int i = 0; i < m; ++i) {
                     for (int j = 0; j <= i; ++j) acc[c++].add(df_[i][q] * df_[j][q]);
                     acc[m * (m + 1) / 2 + i].add(df_[i][q] * delta[q]);
                   }
                 }
               });
  std::vector<double> sums(local.size());
  red_.sum(local.data(), sums.data(), local.size());
  Eigen::MatrixXd A(m, m);
  Eigen::VectorXd b(m);
  int c = 0;
  for (int i = 0; i < m; ++i) {
    for (int j = 0; j <= i; ++j) A(i, j) = A(j, i) = sums[c++];
    b(i) = sums[m * (m + 1) / 2 + i];
  }
  // A small Tikhonov term keeps nearly dependent differences from blowing up gamma.
  A.diagonal().array() += 1e-12 * A.trace() / m + 1e-300;
  const Eigen::VectorXd gamma = A.ldlt().solve(b);
  parallel_owned(O, G, [&](std::size_t n, long, long, long) {
    if (!free[n]) return;
    for (int d = 0; d < 3; ++d) {
      const std::size_t q = 3 * n + d;
      double v = g[q];
      for (int i = 0; i < m; ++i) v -= gamma(i) * dg_[i][q];
      x_next[q] = v;
    }
  });
  return true;
}

}  // namespace gen4d::elastogen

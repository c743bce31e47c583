#include "elastogen/SplatEmbedding.hpp"
#include "parallel/Comm.hpp"

#include <algorithm>

namespace gen4d::elastogen {

SplatEmbedding::SplatEmbedding(const VoxelSystem& sys, const geometry::Shape& shape,
                               const gaussians::SplatSet& rest) {
  rest.check_sizes();
  const long n = static_cast<long>(rest.size());
  std::vector<PointAnchor> anchors;
  {
    PointPlacer placer(sys, shape);
    for (long i = 0; i < n; ++i) placer.add(i, &rest.position[3 * i]);
    long extrapolated = placer.extrapolated();
    double worst = placer.max_extrapolation();
    MPI_Comm comm = sys.grid().comm();
    extrapolated_ = parallel::sum_of(comm, static_cast<long long>(extrapolated));
    max_extrapolation_ = parallel::max_of(comm, worst);
    anchors = placer.take();
  }
  points_ = std::make_unique<PointEmbedding>(sys, std::move(anchors), n, true, "splat embedding");

  // The rest data of this rank's splats, in local id order.
  local_.sh_degree = rest.sh_degree;
  const std::size_t per = 3 * static_cast<std::size_t>(rest.coefficients());
  for (long id : points_->local_ids()) {
    const std::size_t i = static_cast<std::size_t>(id);
    local_.position.insert(local_.position.end(), &rest.position[3 * i], &rest.position[3 * i + 3]);
    local_.scale.insert(local_.scale.end(), &rest.scale[3 * i], &rest.scale[3 * i + 3]);
    local_.rotation.insert(local_.rotation.end(), &rest.rotation[4 * i], &rest.rotation[4 * i + 4]);
    local_.opacity.push_back(rest.opacity[i]);
    local_.sh.insert(local_.sh.end(), rest.sh.begin() + i * per, rest.sh.begin() + (i + 1) * per);
  }
}

gaussians::SplatFrame SplatEmbedding::frame(const double* x,
                                            const gaussians::KinematicsOptions& options) const {
  std::vector<double> pos, F;
  points_->evaluate(x, pos);
  points_->evaluate_gradients(x, F);
  gaussians::SplatFrame out;
  out.sh_degree = local_.sh_degree;
  const std::size_t n = local_.size();
  out.position.reserve(3 * n);
  out.covariance.reserve(6 * n);
  out.opacity.reserve(n);
  out.sh.reserve(local_.sh.size());
  if (options.rotate_harmonics) out.sh_rotation.reserve(9 * n);
  for (std::size_t i = 0; i < n; ++i)
    gaussians::append_deformed(local_, i, &pos[3 * i], &F[9 * i], options, out);
  return out;
}

void SplatEmbedding::gather(const double* x, std::vector<double>& positions,
                            std::vector<double>& F) const {
  std::vector<double> pos, grad;
  points_->evaluate(x, pos);
  points_->evaluate_gradients(x, grad);
  positions = points_->gather(pos, 3);
  F = points_->gather(grad, 9);
}

}  // namespace gen4d::elastogen

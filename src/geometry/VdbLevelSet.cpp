// OpenVDB level-set solid: reads one float level-set grid and samples it trilinearly.
#include "geometry/Shape.hpp"

#include <fmt/format.h>
#include <openvdb/io/Stream.h>
#include <openvdb/openvdb.h>
#include <openvdb/tools/Interpolation.h>

#include <filesystem>
#include <fstream>
#include <mutex>

#include "core/Error.hpp"

namespace gen4d::geometry {
namespace {

void initialize_openvdb_once() {
  static std::once_flag flag;
  std::call_once(flag, [] { openvdb::initialize(); });
}

std::string one_line(std::string s) {
  for (char& c : s)
    if (c == '\n' || c == '\r') c = ' ';
  return s;
}

std::string describe(const openvdb::GridBase& g) {
  return fmt::format("'{}' ({}, {})", g.getName(), g.valueType(),
                     openvdb::GridBase::gridClassToString(g.getGridClass()));
}

std::string list_grids(const openvdb::GridPtrVec& grids) {
  if (grids.empty()) return "none";
  std::string out;
  for (const auto& g : grids) out += (out.empty() ? "" : ", ") + describe(*g);
  return out;
}

// Picks the grid to read: by name, or the first float level set when the name is empty.
std::string choose_grid(const std::string& path, const std::string& wanted,
                        const openvdb::GridPtrVec& grids) {
  for (const auto& g : grids) {
    const bool level_set =
        g->isType<openvdb::FloatGrid>() && g->getGridClass() == openvdb::GRID_LEVEL_SET;
    if (wanted.empty() ? level_set : g->getName() == wanted) {
      if (!level_set)
        throw InputError(fmt::format("{}: grid {} is not a float level set", path, describe(*g)));
      return g->getName();
    }
  }
  if (wanted.empty())
    throw InputError(
        fmt::format("{}: no float level-set grid; grids present: {}", path, list_grids(grids)));
  throw InputError(
      fmt::format("{}: no grid named '{}'; grids present: {}", path, wanted, list_grids(grids)));
}

}  // namespace

struct VdbLevelSet::Impl {
  openvdb::FloatGrid::Ptr grid;
  // The tree-based sampler keeps no cache, so inside() stays safe to call concurrently.
  std::unique_ptr<openvdb::tools::GridSampler<openvdb::FloatTree, openvdb::tools::BoxSampler>>
      sampler;
};

VdbLevelSet::VdbLevelSet(const std::string& path, const std::string& grid, double scale,
                         const Eigen::Vector3d& translate)
    : impl_(std::make_unique<Impl>()), scale_(scale), translate_(translate) {
  initialize_openvdb_once();
  if (!(scale > 0) || !std::isfinite(scale))
    throw InputError(fmt::format("{}: VDB scale must be positive, got {}", path, scale));
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec) || !std::ifstream(path, std::ios::binary))
    throw InputError(fmt::format("{}: cannot open VDB file", path));
  try {
    // Read as a stream that throws at the end of the file: OpenVDB's tree readers loop over
    // the node counts a file declares without checking the stream, so a corrupt count in a
    // file of a few bytes would allocate nodes without bound. No delayed loading: the file may
    // change after we return.
    std::ifstream in(path, std::ios::binary);
    in.exceptions(std::ios::failbit | std::ios::badbit);
    openvdb::io::Stream stream(in, /*delayLoad=*/false);
    const openvdb::GridPtrVecPtr grids = stream.getGrids();
    grid_name_ = choose_grid(path, grid, *grids);
    impl_->grid =
        openvdb::gridPtrCast<openvdb::FloatGrid>(openvdb::findGridByName(*grids, grid_name_));
  } catch (const openvdb::Exception& e) {
    throw InputError(fmt::format("{}: not a readable VDB file: {}", path, one_line(e.what())));
  } catch (const std::ios_base::failure&) {
    throw InputError(fmt::format("{}: not a readable VDB file: truncated or corrupt", path));
  }
  if (!impl_->grid) throw InputError(fmt::format("{}: grid '{}' unreadable", path, grid_name_));
  const openvdb::CoordBBox active = impl_->grid->evalActiveVoxelBoundingBox();
  if (active.empty())
    throw InputError(fmt::format("{}: grid '{}' has no active voxels", path, grid_name_));
  // Interpolation reaches half a voxel past the outermost active centres; the corners of
  // that index box, mapped to world, bound the zero crossing for any affine transform.
  const openvdb::Vec3d lo = active.min().asVec3d() - openvdb::Vec3d(0.5);
  const openvdb::Vec3d hi = active.max().asVec3d() + openvdb::Vec3d(0.5);
  for (int corner = 0; corner < 8; ++corner) {
    const openvdb::Vec3d idx((corner & 1) ? hi.x() : lo.x(), (corner & 2) ? hi.y() : lo.y(),
                             (corner & 4) ? hi.z() : lo.z());
    const openvdb::Vec3d w = impl_->grid->transform().indexToWorld(idx);
    bounds_.extend(Eigen::Vector3d(w.x(), w.y(), w.z()) * scale + translate);
  }
  impl_->sampler =
      std::make_unique<openvdb::tools::GridSampler<openvdb::FloatTree, openvdb::tools::BoxSampler>>(
          impl_->grid->tree(), impl_->grid->transform());
}

VdbLevelSet::~VdbLevelSet() = default;

double VdbLevelSet::signed_distance(const Eigen::Vector3d& p) const {
  const Eigen::Vector3d local = (p - translate_) / scale_;
  return scale_ * impl_->sampler->wsSample(openvdb::Vec3d(local.x(), local.y(), local.z()));
}

bool VdbLevelSet::inside(const Eigen::Vector3d& p) const {
  return bounds_.contains(p) && signed_distance(p) < 0;
}

}  // namespace gen4d::geometry

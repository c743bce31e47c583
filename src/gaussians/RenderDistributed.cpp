// The collective renderer splits the image, not the splats: every rank projects its own splats,
// sends each projected splat to the ranks owning the tile rows it touches, and blends those
// rows; rank 0 gathers them. Each tile then sees exactly the splats, in exactly the order, of a
// serial render, so the image is the same bit for bit for any distribution and rank count.
// (Splitting the splats instead and compositing per-rank images is not exact: alpha blending
// with early termination is only reproduced by merging every pixel's depth-sorted fragments.)
#include <algorithm>
#include <chrono>
#include <cstdint>
#include <stdexcept>
#include <vector>

#include "core/Error.hpp"
#include "gaussians/Render.hpp"
#include "parallel/Distribute.hpp"
#include "gaussians/RenderDetail.hpp"
#include "parallel/Comm.hpp"

namespace gen4d::gaussians {

namespace {

double now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

//! Contiguous tile-row ranges [bounds[r], bounds[r + 1]) per rank, balancing the (splat, tile)
//! pairs plus one unit per tile; the same on every rank (integer sums).
std::vector<int> row_bounds(MPI_Comm comm, const std::vector<detail::Projected>& local,
                            const detail::View& view, int ranks) {
  std::vector<long long> cost(static_cast<std::size_t>(view.grid_y), view.grid_x);
  std::vector<long long> mine(cost.size(), 0);
  for (const auto& g : local)
    for (int ty = g.y0; ty < g.y1; ++ty) mine[static_cast<std::size_t>(ty)] += g.x1 - g.x0;
  std::vector<long long>& all = mine;
  parallel::sum_in_place(comm, all.data(), static_cast<int>(all.size()));
  long long total = 0;
  for (std::size_t i = 0; i < cost.size(); ++i) total += (cost[i] += all[i]);
  std::vector<int> bounds(static_cast<std::size_t>(ranks) + 1, view.grid_y);
  bounds[0] = 0;
  long long cum = 0;
  int row = 0;
  for (int r = 1; r < ranks; ++r) {
    // First row at which the cumulative cost reaches r / ranks of the total.
    const long double target = static_cast<long double>(total) * r / ranks;
    while (row < view.grid_y && static_cast<long double>(cum) < target)
      cum += cost[static_cast<std::size_t>(row++)];
    bounds[static_cast<std::size_t>(r)] = row;
  }
  return bounds;
}

}  // namespace

Image render_distributed(MPI_Comm comm, const SplatFrame& local, const Camera& camera,
                         const RenderOptions& options) {
  const int rank = parallel::rank(comm), ranks = parallel::size(comm);
  if (ranks == 1) return render(local, camera, options);

  const detail::View view(camera);
  const detail::ThreadScope threads(options.threads);
  RenderStats scratch;
  RenderStats& st = options.stats ? *options.stats : scratch;
  // On a GPU, the same kernels as a serial GPU render project and blend (the sort is
  // canonical on both), so the image does not depend on the rank count there either.
  const bool gpu = detail::on_device(options);
  double t0 = now();
  std::vector<detail::Projected> mine;
#if defined(GEN4D_CUDA)
  if (gpu) {
    detail::pointers(local);  // size checks
    detail::device_renderer().upload(local);
    const double t = now();
    st.transfer += t - t0;
    t0 = t;
    detail::device_renderer().preprocess(view, mine);
  }
#endif
  if (!gpu) detail::preprocess(local, view, mine);
  st.visible += mine.size();
  double t1 = now();
  st.preprocess += t1 - t0;

  // Send each projected splat to every rank whose tile rows its rectangle touches.
  const std::vector<int> bounds = row_bounds(comm, mine, view, ranks);
  auto first_rank = [&](int row) {  // the rank owning tile row `row`
    return static_cast<int>(std::upper_bound(bounds.begin() + 1, bounds.end(), row) -
                            (bounds.begin() + 1));
  };
  std::vector<detail::Projected> received;
  std::vector<int> dest;
  for (const auto& g : mine)
    for (int r = first_rank(g.y0); r < ranks && bounds[static_cast<std::size_t>(r)] < g.y1; ++r)
      if (bounds[static_cast<std::size_t>(r) + 1] > bounds[static_cast<std::size_t>(r)]) {
        received.push_back(g);
        dest.push_back(r);
      }
  std::vector<detail::Projected>().swap(mine);
  // Blending does not depend on the order of the splats (equal depths are ordered by their
  // data), so the exchange's order (kept rows first) is as good as any.
  parallel::RowExchange exchange;
  exchange.add(received, 1);
  exchange.exchange(comm, dest);
  double t2 = now();
  st.exchange += t2 - t1;

  // Blend this rank's rows.
  const int row0 = bounds[static_cast<std::size_t>(rank)];
  const int row1 = bounds[static_cast<std::size_t>(rank) + 1];
  std::vector<std::uint32_t> offsets, entries;
  detail::bin_tiles(received, view, row0, row1, offsets, entries, options.legacy);
  double t3 = now();
  st.sort += t3 - t2;
  st.tile_entries += entries.size();
  auto pixel_row = [&](int tile_row) { return std::min(tile_row * detail::kTile, view.height); };
  const std::size_t row_floats = static_cast<std::size_t>(view.width) * 3;
  std::vector<float> part(static_cast<std::size_t>(pixel_row(row1) - pixel_row(row0)) * row_floats);
#if defined(GEN4D_CUDA)
  if (gpu)
    detail::device_renderer().blend(received, view, row0, row1, offsets, entries, options,
                                    part.data());
#endif
  if (!gpu) detail::blend_tiles(received, view, row0, row1, offsets, entries, options, part.data());
  double t4 = now();
  st.blend += t4 - t3;

  // Rank 0 gathers the rows: the ranks' row ranges follow each other from the top.
  Image img;
  std::vector<float> rows = parallel::gather(comm, part);
  if (rank == 0) {
    img.width = view.width;
    img.height = view.height;
    if (rows.size() != static_cast<std::size_t>(view.height) * row_floats)
      throw std::logic_error("render_distributed: the ranks' rows do not cover the image");
    img.rgb = std::move(rows);
  }
  st.gather += now() - t4;
  return img;
}

}  // namespace gen4d::gaussians

// The renderer's CUDA back end: RenderDetail.hpp's kernels (ProjectKernel, BlendPixelKernel)
// run through exec::device_for; between them the splats are binned on the device as in
// forward.cu (a key per (splat, tile): tile << 32 | depth bits, radix sorted), with the
// host's canonical order restored among equal keys, so every tile lists the same splats in the
// same order as on the host.
#include <cub/device/device_radix_sort.cuh>
#include <cub/device/device_scan.cuh>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <vector>

#include "core/DeviceArray.hpp"
#include "core/Error.hpp"
#include "core/ParallelFor.hpp"
#include "gaussians/RenderDetail.hpp"

namespace gen4d::gaussians::detail {

namespace {

double now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

//! Waits for the device and reports any kernel's error.
void sync(const char* what) {
  exec::cuda_check(cudaGetLastError(), what);
  exec::cuda_check(cudaDeviceSynchronize(), what);
}

//! One key per (splat, tile): tile << 32 | depth bits (positive depths order like their
//! bits), the splat's index as the value, at the splat's place in the exclusive scan `first`.
struct EmitKeys {
  const Projected* proj;
  const unsigned long long* touched;
  const unsigned long long* first;
  unsigned long long* keys;
  std::uint32_t* values;
  int grid_x;
  GEN4D_HD void operator()(long i) const {
    if (touched[i] == 0) return;
    const Projected& g = proj[i];
    const unsigned long long depth = float_bits(g.depth);
    unsigned long long k = first[i];
    for (unsigned long long ty = g.y0; ty < g.y1; ++ty)
      for (unsigned long long tx = g.x0; tx < g.x1; ++tx, ++k) {
        keys[k] = ((ty * static_cast<unsigned long long>(grid_x) + tx) << 32) | depth;
        values[k] = static_cast<std::uint32_t>(i);
      }
  }
};

//! Runs of equal keys (one tile, one depth) put in the canonical order of their splats
//! (before(): the projected data bitwise), an insertion sort by the run's first entry.
struct CanonicalRuns {
  const unsigned long long* keys;
  std::uint32_t* values;
  const Projected* proj;
  long n;
  GEN4D_HD void operator()(long i) const {
    if (i > 0 && keys[i - 1] == keys[i]) return;
    long end = i + 1;
    while (end < n && keys[end] == keys[i]) ++end;
    for (long a = i + 1; a < end; ++a) {
      const std::uint32_t v = values[a];
      long b = a;
      for (; b > i && before(proj[v], proj[values[b - 1]]); --b) values[b] = values[b - 1];
      values[b] = v;
    }
  }
};

//! offsets[t]: the first sorted key of tile t or a later one (t = tiles: the count).
struct TileOffsets {
  const unsigned long long* keys;
  long n;
  std::uint32_t* offsets;
  GEN4D_HD void operator()(long t) const {
    const unsigned long long key = static_cast<unsigned long long>(t) << 32;
    long lo = 0, hi = n;
    while (lo < hi) {
      const long mid = lo + (hi - lo) / 2;
      if (keys[mid] < key)
        lo = mid + 1;
      else
        hi = mid;
    }
    offsets[t] = static_cast<std::uint32_t>(lo);
  }
};

//! The bits a sort key's tile part needs.
int tile_bits(long tiles) {
  int bits = 0;
  while (bits < 32 && (1LL << bits) < tiles) ++bits;
  return bits;
}

}  // namespace

struct DeviceRenderer::Buffers {
  long n = 0;
  int sh_degree = 0;
  bool rotated = false;
  exec::DeviceArray<float> position, covariance, opacity, sh, sh_rotation, rgb;
  exec::DeviceArray<Projected> proj;
  exec::DeviceArray<unsigned long long> touched, first, keys, keys_alt;
  exec::DeviceArray<std::uint32_t> values, values_alt, offsets;
  exec::DeviceArray<unsigned char> temp;

  SplatPointers pointers() const {
    SplatPointers p;
    p.position = position.data();
    p.covariance = covariance.data();
    p.opacity = opacity.data();
    p.sh = sh.data();
    p.sh_rotation = rotated ? sh_rotation.data() : nullptr;
    p.sh_degree = sh_degree;
    return p;
  }
  //! ProjectKernel over the uploaded splats into proj and touched.
  void project(const View& view) {
    proj.resize(static_cast<std::size_t>(n));
    touched.resize(static_cast<std::size_t>(n));
    exec::device_for(n, ProjectKernel{pointers(), view, proj.data(), touched.data()});
  }
  //! BlendPixelKernel over tile rows [row0, row1) into rgb, then copied to `out`.
  void blend(const Projected* splats, const std::uint32_t* entries, const View& view, int row0,
             int row1, const RenderOptions& options, float* out, RenderStats& st) {
    const int y_begin = row0 * kTile, y_end = std::min(row1 * kTile, view.height);
    const std::size_t floats = static_cast<std::size_t>(y_end - y_begin) * view.width * 3;
    rgb.resize(floats);
    BlendPixelKernel k{splats,      offsets.data(), entries, rgb.data(), view.width,
                       view.height, view.grid_x,    row0,    {}};
    for (int c = 0; c < 3; ++c) k.bg[c] = options.background[c];
    const double t0 = now();
    exec::device_for(static_cast<long>(row1 - row0) * view.grid_x * kTile * kTile, k);
    sync("render: blend");
    const double t1 = now();
    st.blend += t1 - t0;
    rgb.download(out, floats);
    st.transfer += now() - t1;
  }
};

DeviceRenderer::DeviceRenderer() : b_(new Buffers) {}
DeviceRenderer::~DeviceRenderer() = default;

void DeviceRenderer::upload(const SplatFrame& s) {
  Buffers& b = *b_;
  b.n = static_cast<long>(s.size());
  if (b.n > 0xffffffffL) throw RuntimeError("render: more than 2^32 splats for the GPU");
  b.sh_degree = s.sh_degree;
  b.rotated = !s.sh_rotation.empty();
  b.position.upload(s.position.data(), s.position.size());
  b.covariance.upload(s.covariance.data(), s.covariance.size());
  b.opacity.upload(s.opacity.data(), s.opacity.size());
  b.sh.upload(s.sh.data(), s.sh.size());
  if (b.rotated) b.sh_rotation.upload(s.sh_rotation.data(), s.sh_rotation.size());
}

Image DeviceRenderer::render(const View& view, const RenderOptions& options) {
  Buffers& b = *b_;
  RenderStats local;
  RenderStats& st = options.stats ? *options.stats : local;
  const long n = b.n;
  double t0 = now();
  b.project(view);
  // Each splat's first key: the exclusive scan of its tile counts.
  b.first.resize(static_cast<std::size_t>(n));
  unsigned long long total = 0;
  if (n > 0) {
    std::size_t bytes = 0;
    exec::cuda_check(
        cub::DeviceScan::ExclusiveSum(nullptr, bytes, b.touched.data(), b.first.data(), n),
        "render: scan");
    b.temp.resize(bytes);
    exec::cuda_check(
        cub::DeviceScan::ExclusiveSum(b.temp.data(), bytes, b.touched.data(), b.first.data(), n),
        "render: scan");
    unsigned long long last[2] = {0, 0};
    exec::cuda_check(
        cudaMemcpy(&last[0], b.first.data() + (n - 1), sizeof last[0], cudaMemcpyDeviceToHost),
        "render: scan total");
    exec::cuda_check(
        cudaMemcpy(&last[1], b.touched.data() + (n - 1), sizeof last[1], cudaMemcpyDeviceToHost),
        "render: scan total");
    total = last[0] + last[1];
  }
  sync("render: preprocess");
  double t1 = now();
  st.preprocess += t1 - t0;
  if (total > 0xffffffffULL) throw RuntimeError("render: too many tile entries");
  const long entries = static_cast<long>(total);
  const long tiles = static_cast<long>(view.grid_x) * view.grid_y;
  b.keys.resize(static_cast<std::size_t>(entries));
  b.keys_alt.resize(static_cast<std::size_t>(entries));
  b.values.resize(static_cast<std::size_t>(entries));
  b.values_alt.resize(static_cast<std::size_t>(entries));
  b.offsets.resize(static_cast<std::size_t>(tiles) + 1);
  const unsigned long long* sorted_keys = b.keys.data();
  const std::uint32_t* sorted_values = b.values.data();
  if (entries > 0) {
    exec::device_for(n, EmitKeys{b.proj.data(), b.touched.data(), b.first.data(), b.keys.data(),
                                 b.values.data(), view.grid_x});
    cub::DoubleBuffer<unsigned long long> keys(b.keys.data(), b.keys_alt.data());
    cub::DoubleBuffer<std::uint32_t> values(b.values.data(), b.values_alt.data());
    const int end_bit = 32 + tile_bits(tiles);
    std::size_t bytes = 0;
    exec::cuda_check(
        cub::DeviceRadixSort::SortPairs(nullptr, bytes, keys, values, entries, 0, end_bit),
        "render: sort");
    b.temp.resize(bytes);
    exec::cuda_check(
        cub::DeviceRadixSort::SortPairs(b.temp.data(), bytes, keys, values, entries, 0, end_bit),
        "render: sort");
    exec::device_for(entries,
                     CanonicalRuns{keys.Current(), values.Current(), b.proj.data(), entries});
    sorted_keys = keys.Current();
    sorted_values = values.Current();
  }
  exec::device_for(tiles + 1, TileOffsets{sorted_keys, entries, b.offsets.data()});
  sync("render: sort");
  st.sort += now() - t1;
  st.tile_entries += static_cast<std::size_t>(entries);
  Image img;
  img.width = view.width;
  img.height = view.height;
  img.rgb.resize(static_cast<std::size_t>(view.width) * view.height * 3);
  b.blend(b.proj.data(), sorted_values, view, 0, view.grid_y, options, img.rgb.data(), st);
  return img;
}

void DeviceRenderer::preprocess(const View& view, std::vector<Projected>& out) {
  Buffers& b = *b_;
  b.project(view);
  sync("render: preprocess");
  const std::size_t n = static_cast<std::size_t>(b.n);
  std::vector<Projected> proj(n);
  std::vector<unsigned long long> touched(n);
  b.proj.download(proj.data(), n);
  b.touched.download(touched.data(), n);
  for (std::size_t i = 0; i < n; ++i)
    if (touched[i] > 0) out.push_back(proj[i]);
}

void DeviceRenderer::blend(const std::vector<Projected>& splats, const View& view, int row0,
                           int row1, const std::vector<std::uint32_t>& offsets,
                           const std::vector<std::uint32_t>& entries, const RenderOptions& options,
                           float* rgb) {
  Buffers& b = *b_;
  RenderStats local;
  RenderStats& st = options.stats ? *options.stats : local;
  const double t0 = now();
  b.proj.upload(splats.data(), splats.size());
  b.offsets.upload(offsets.data(), offsets.size());
  b.values.upload(entries.data(), entries.size());
  st.transfer += now() - t0;
  b.blend(b.proj.data(), b.values.data(), view, row0, row1, options, rgb, st);
}

DeviceRenderer& device_renderer() {
  static DeviceRenderer renderer;
  return renderer;
}

}  // namespace gen4d::gaussians::detail

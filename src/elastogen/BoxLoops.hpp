//! Threaded loops over a rank's boxes for ElastoGen: rows (j, k) of a box are split into
//! contiguous blocks, one per host thread (exec::parallel_blocks). Every per-node or per-voxel
//! result depends on its own inputs only, and sums go into exact accumulators merged after the
//! loop, so results are bit-identical for any thread count (and rank count).
#pragma once

#include <cstddef>
#include <mutex>
#include <vector>

#include "core/ParallelFor.hpp"
#include "parallel/Grid.hpp"
#include "parallel/Reduce.hpp"

namespace gen4d::elastogen {

//! f(j, k) for every row of box B (rows of x), the rows spread over the host threads.
template <class F>
void parallel_box_rows(const parallel::Box& B, const F& f) {
  const long nx = B.count[0], ny = B.count[1], rows = B.count[1] * B.count[2];
  if (nx <= 0 || rows <= 0) return;
  // Blocks of nodes [b, e) of the row-major box map to the rows [b / nx, e / nx).
  exec::parallel_blocks(rows * nx, [&](long b, long e) {
    for (long r = b / nx; r < e / nx; ++r) f(B.start[1] + r % ny, B.start[2] + r / ny);
  });
}

//! f(linear index in G, i, j, k) for every node of O, the rows spread over the host threads.
template <class F>
void parallel_owned(const parallel::Box& O, const parallel::Box& G, const F& f) {
  parallel_box_rows(O, [&](long j, long k) {
    for (long i = O.start[0]; i < O.start[0] + O.count[0]; ++i) f(G.index(i, j, k), i, j, k);
  });
}

//! Exact sums over the rows of box B: f(j, k, acc) adds into acc[0 .. count); the blocks'
//! accumulators are summed exactly into out[0 .. count) (added to what out holds).
template <class F>
void reduce_box_rows(const parallel::Box& B, std::size_t count, parallel::ExactSum* out,
                     const F& f) {
  const long nx = B.count[0], ny = B.count[1], rows = B.count[1] * B.count[2];
  if (nx <= 0 || rows <= 0) return;
  std::mutex merge;
  exec::parallel_blocks(rows * nx, [&](long b, long e) {
    std::vector<parallel::ExactSum> acc(count);
    for (long r = b / nx; r < e / nx; ++r) f(B.start[1] + r % ny, B.start[2] + r / ny, acc.data());
    const std::lock_guard<std::mutex> lock(merge);  // exact sums: the order does not matter
    for (std::size_t c = 0; c < count; ++c) out[c].add(acc[c]);
  });
}

//! Exact sums over the nodes of O: f(n, i, j, k, acc) adds into acc[0 .. count), merged into
//! out[0 .. count) as reduce_box_rows does.
template <class F>
void reduce_owned(const parallel::Box& O, const parallel::Box& G, std::size_t count,
                  parallel::ExactSum* out, const F& f) {
  reduce_box_rows(O, count, out, [&](long j, long k, parallel::ExactSum* acc) {
    for (long i = O.start[0]; i < O.start[0] + O.count[0]; ++i) f(G.index(i, j, k), i, j, k, acc);
  });
}

}  // namespace gen4d::elastogen

//! Boxes of global grid indices owned by one rank, the unit of every parallel read and write.
#pragma once

#include <array>
#include <cstddef>

namespace gen4d::io {

//! A box of global grid indices [start, start + count) per axis (x, y, z). Rank-local arrays
//! over a box are x-fastest: entry (i, j, k) sits at ((k-k0)*cy + (j-j0))*cx + (i-i0).
//! A box with a zero count on any axis is empty; such a rank still joins collective calls.
struct NodeBox {
  std::array<long, 3> start{0, 0, 0};
  std::array<long, 3> count{0, 0, 0};

  bool empty() const { return count[0] <= 0 || count[1] <= 0 || count[2] <= 0; }
  std::size_t size() const {
    return empty() ? 0 : static_cast<std::size_t>(count[0] * count[1] * count[2]);
  }
  //! True when the box lies inside a grid of the given dims (an empty box always does).
  bool inside(const std::array<long, 3>& dims) const {
    if (empty()) return true;
    for (int a = 0; a < 3; ++a) {
      if (start[a] < 0 || count[a] < 0 || start[a] + count[a] > dims[a]) return false;
    }
    return true;
  }
};

//! Same layout as NodeBox, indexing cells (voxels) of a grid with one fewer cell than nodes.
using CellBox = NodeBox;

//! Cell dims of a node grid.
inline std::array<long, 3> cell_dims(const std::array<long, 3>& node_dims) {
  return {node_dims[0] - 1, node_dims[1] - 1, node_dims[2] - 1};
}

//! The global index of node `n` on a grid of `node_dims` nodes (x fastest).
inline long node_index(const std::array<long, 3>& n, const std::array<long, 3>& node_dims) {
  return (n[2] * node_dims[1] + n[1]) * node_dims[0] + n[0];
}

//! The node indices of the face of `cell` normal to `axis` on its low (side 0) or high (side 1)
//! end, ordered so that the right-hand normal points out of the cell.
inline std::array<long, 4> cell_face_nodes(const std::array<long, 3>& cell, int axis, int side,
                                           const std::array<long, 3>& node_dims) {
  const long corner[4][2] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
  const int b = (axis + 1) % 3, c = (axis + 2) % 3;  // b x c = axis: this order faces +axis
  std::array<long, 4> quad{};
  for (int q = 0; q < 4; ++q) {
    std::array<long, 3> n = cell;
    n[axis] += side;
    n[b] += corner[q][0];
    n[c] += corner[q][1];
    quad[side ? q : 3 - q] = node_index(n, node_dims);
  }
  return quad;
}

}  // namespace gen4d::io

//! Distributed node grid: a PETSc DMDA (box stencil, width 1) over the voxel corners.
#pragma once

#include <petscdmda.h>

#include <array>
#include <cstddef>
#include <vector>

namespace gen4d::parallel {

//! A box of global indices [start, start + count) per axis; storage is x-fastest.
struct Box {
  std::array<long, 3> start{0, 0, 0};
  std::array<long, 3> count{0, 0, 0};

  long size() const { return count[0] * count[1] * count[2]; }
  bool contains(long i, long j, long k) const {
    return i >= start[0] && i < start[0] + count[0] && j >= start[1] && j < start[1] + count[1] &&
           k >= start[2] && k < start[2] + count[2];
  }
  //! Linear index of global (i, j, k) inside this box (no bounds check).
  std::size_t index(long i, long j, long k) const {
    return static_cast<std::size_t>(((k - start[2]) * count[1] + (j - start[1])) * count[0] +
                                    (i - start[0]));
  }
};

//! Owns the DMDAs (1 and 3 dof) for a global node grid and describes this rank's boxes.
//! Nodes (i, j, k) are voxel corners; voxel (i, j, k) spans nodes i..i+1 per axis.
class NodeGrid {
 public:
  NodeGrid(MPI_Comm comm, const std::array<long, 3>& global_nodes);
  //! Same, with the node count of every process slab per axis given (static load balance):
  //! ownership[a] has one entry per process along axis a, summing to global_nodes[a].
  NodeGrid(MPI_Comm comm, const std::array<long, 3>& global_nodes,
           const std::array<std::vector<long>, 3>& ownership);
  //! PETSc's default process grid (processes per axis) for a node grid on `comm`.
  static std::array<int, 3> process_grid(MPI_Comm comm, const std::array<long, 3>& global_nodes);
  ~NodeGrid();
  NodeGrid(const NodeGrid&) = delete;
  NodeGrid& operator=(const NodeGrid&) = delete;

  MPI_Comm comm() const { return comm_; }
  int rank() const { return rank_; }
  int size() const { return size_; }
  //! The DMDA of `dof` values per node (1, 3 or 4), all with the same layout.
  DM dm(int dof) const { return dof == 4 ? dm4_ : dof == 3 ? dm3_ : dm1_; }

  const std::array<long, 3>& global_nodes() const { return global_; }
  std::array<long, 3> global_cells() const {
    return {global_[0] - 1, global_[1] - 1, global_[2] - 1};
  }
  const Box& owned_nodes() const { return owned_; }
  const Box& ghosted_nodes() const { return ghosted_; }
  //! Voxels touching an owned node: the cells whose 8 corners the rank needs. They lie in
  //! the ghosted node box, so one halo gather makes all their corners available.
  const Box& adjacent_cells() const { return cells_; }
  //! Cells this rank owns for output: lower corner owned and inside the grid.
  const Box& owned_cells() const { return owned_cells_; }
  //! First node index of every process slab per axis, plus the end (size = processes + 1).
  const std::array<std::vector<long>, 3>& slab_starts() const { return starts_; }
  //! Rank that owns node (i, j, k) (PETSc's x-fastest process numbering).
  int owner_of(long i, long j, long k) const;

 private:
  MPI_Comm comm_;
  int rank_ = 0, size_ = 1;
  std::array<long, 3> global_{};
  DM dm1_ = nullptr, dm3_ = nullptr, dm4_ = nullptr;
  Box owned_, ghosted_, cells_, owned_cells_;
  std::array<std::vector<long>, 3> starts_;

  void init(const std::array<std::vector<long>, 3>* ownership);
};

}  // namespace gen4d::parallel

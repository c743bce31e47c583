# Sourced by the job scripts: OpenMPI settings that let mpirun work as root in containers
# and on 2-core machines (oversubscription), without touching the user's shell.
export OMPI_ALLOW_RUN_AS_ROOT=1
export OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
export OMPI_MCA_rmaps_base_oversubscribe=1
export OMPI_MCA_btl_vader_single_copy_mechanism=none
GEN4D_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
GEN4D_BUILD="${GEN4D_BUILD:-$GEN4D_ROOT/build}"
GEN4D_JOBS="${GEN4D_JOBS:-$(nproc)}"

gen4d_build() {
  # shellcheck disable=SC2086  # GEN4D_CMAKE_ARGS is a list of options, one argument each
  cmake -S "$GEN4D_ROOT" -B "$GEN4D_BUILD" -DCMAKE_BUILD_TYPE=Release ${GEN4D_CMAKE_ARGS:-}
  cmake --build "$GEN4D_BUILD" -j "$GEN4D_JOBS"
}

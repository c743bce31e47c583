#!/usr/bin/env bash
# The GPU check, in one go, for the short windows in which a machine with an NVIDIA GPU is
# available (target: under 8 minutes on 16 cores and one H100):
#   1. build with the CUDA back end (GEN4D_CUDA=ON; the dependencies must be installed:
#      cmake/install-deps.sh);
#   2. the GPU test label: CPU against GPU for every kernel, at the tolerance each test states;
#   3. the benchmarks on the device: MPM at 1M and 8M particles, the NeuralMTL kernel, an
#      ElastoGen step of about 1M DoFs and the renderer at 1080p.
# Every result is written under OUT (default: gpu-check/), one JSON per benchmark plus the
# ctest log; the script goes on past a failing part and exits non-zero if any part failed.
#   usage: jobs/gpu/check.sh [OUT]
set -uo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/../env.sh"
OUT="${1:-${OUT:-gpu-check}}"
mkdir -p "$OUT"
export GEN4D_BUILD="${GEN4D_BUILD:-$GEN4D_ROOT/build-gpu}"
status=0
step() {  # step NAME TIMEOUT_S COMMAND...: runs, logs to OUT/NAME.log, records failure
  local name=$1 limit=$2
  shift 2
  local t0=$SECONDS
  timeout "$limit" "$@" >"$OUT/$name.log" 2>&1
  local rc=$?
  echo "$name: exit $rc, $((SECONDS - t0)) s" | tee -a "$OUT/summary.txt"
  [ $rc -eq 0 ] || status=1
  return $rc
}

nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv >"$OUT/gpu.txt" 2>&1 ||
  echo "nvidia-smi failed: no GPU visible" | tee -a "$OUT/summary.txt"
step configure 120 cmake -S "$GEN4D_ROOT" -B "$GEN4D_BUILD" -DCMAKE_BUILD_TYPE=Release \
  -DGEN4D_CUDA=ON || { echo "configure failed"; exit 1; }
step build 300 cmake --build "$GEN4D_BUILD" -j "$GEN4D_JOBS" --target \
  test_mpm_gpu bench_mpm bench_elastogen bench_render || exit 1
# bench_neural needs LibTorch (its same-run baseline); built where the package is installed.
cmake --build "$GEN4D_BUILD" -j "$GEN4D_JOBS" --target bench_neural >>"$OUT/build.log" 2>&1 ||
  echo "bench_neural: not built (no LibTorch)" | tee -a "$OUT/summary.txt"
# Test executables of the gpu label that exist in this tree (each module adds its own).
gpu_tests=$(cd "$GEN4D_BUILD" && ctest -N -L gpu | awk '/Test +#/ {print $3}' |
  sed 's/_np[0-9]*$//' | sort -u)
for t in $gpu_tests; do cmake --build "$GEN4D_BUILD" -j "$GEN4D_JOBS" --target "test_$t" \
  >>"$OUT/build.log" 2>&1; done
step gpu_tests 120 bash -c "cd '$GEN4D_BUILD' && ctest -L gpu --output-on-failure"
B="$GEN4D_BUILD/drivers"
export OMP_NUM_THREADS="${OMP_NUM_THREADS:-16}"
step bench_mpm_1M 90 "$B/bench_mpm" --particles 1000000 --substeps 20 --json "$OUT/bench_mpm_1M.json"
step bench_mpm_8M 150 "$B/bench_mpm" --particles 8000000 --substeps 10 --json "$OUT/bench_mpm_8M.json"
if [ -x "$B/bench_neural" ]; then
  step bench_neural 60 "$B/bench_neural" --weights "$GEN4D_ROOT/inputs/models/mtl/neo_hookean_0.30.h5" --device
fi
step bench_elastogen 90 "$B/bench_elastogen" --cells 72
step bench_render 90 "$B/bench_render"
echo "GPU check: $([ $status -eq 0 ] && echo passed || echo FAILED); results in $OUT"
exit $status

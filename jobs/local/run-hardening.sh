#!/usr/bin/env bash
# Hostile input: an AddressSanitizer + UndefinedBehaviorSanitizer build (clang) of the cheap
# serial unit-test suites, run at 1 rank, then a smoke run of every libFuzzer target of
# tests/fuzz on its seed corpus. Exits non-zero on any failing test, sanitizer report, leak,
# fuzz crash or hang. Prints the time of each phase.
#   FUZZ_SECONDS  seconds per fuzz target (default 30)
#   FUZZ_JOBS     fuzz targets run side by side (default 2)
#   GEN4D_ASAN_BUILD  build folder (default build-asan beside build)
set -euo pipefail
# shellcheck source=SCRIPTDIR/../env.sh
source "$(dirname "${BASH_SOURCE[0]}")/../env.sh"
build="${GEN4D_ASAN_BUILD:-$GEN4D_ROOT/build-asan}"
fuzz_seconds="${FUZZ_SECONDS:-30}"
fuzz_jobs="${FUZZ_JOBS:-2}"
# Serial (or 1-rank) suites of the modules below the solvers: deck reader, materials, io,
# gaussians. Each name is a gen4d_test; its _np1 test runs. GEN4D_HARDENING_SUITES (names
# separated by spaces) runs another set, e.g. with "geometry" added (clean too, but its OpenVDB
# test alone takes about as long to compile as the io suites together; the mesh and VDB readers
# are sanitized by fuzz_mesh and fuzz_vdb).
read -r -a suites <<<"${GEN4D_HARDENING_SUITES:-deck svd3 materials io_frames io_checkpoint \
io_bad_files io_png io_surface plot gaussians physgaussian_config}"

phase_start=$SECONDS
phase() {
  echo "== hardening: $1 took $((SECONDS - phase_start)) s"
  phase_start=$SECONDS
}

generator=()
if [[ ! -f "$build/CMakeCache.txt" ]] && command -v ninja >/dev/null; then generator=(-G Ninja); fi
cmake -S "$GEN4D_ROOT" -B "$build" "${generator[@]}" -DCMAKE_BUILD_TYPE=Debug \
  -DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++ -DGEN4D_CUDA=OFF -DGEN4D_TORCH=OFF \
  -DGEN4D_SANITIZE=ON -DGEN4D_FUZZ=ON
targets=(fuzz_targets)
for s in "${suites[@]}"; do targets+=("test_$s"); done
cmake --build "$build" -j "$GEN4D_JOBS" --target "${targets[@]}"
phase "configure + build"

# The slow unwinder: OpenMPI's exit-time allocations come from plugins it has unloaded by then,
# so only frames of libmpi (found without frame pointers) let tests/fuzz/lsan.supp match them.
export ASAN_OPTIONS="detect_leaks=1:abort_on_error=1:fast_unwind_on_malloc=0"
export LSAN_OPTIONS="suppressions=$GEN4D_ROOT/tests/fuzz/lsan.supp:print_suppressions=0"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
# Left out of the sanitized run (the Release suite runs them): winding numbers over the large
# meshes of ../shared take minutes each at -O1 with ASan, and a timing assertion (the donut PLY
# read in under 0.1 s) that a sanitized build cannot meet.
export GTEST_FILTER="-GeometryMesh.FastWindingNumberMatchesExact:GeometryMesh.StanfordBunnyWithHolesIsSolid:GeometryMesh.SuzanneOpenMultiPartMatchesExactWinding:GaussiansTest.PlyReadsTheDonut"
pattern="^($(IFS='|'; echo "${suites[*]}"))_np1\$"
(cd "$build" && ctest -R "$pattern" --output-on-failure -j "$GEN4D_JOBS" --timeout 900)
phase "sanitized unit tests"

"$GEN4D_ROOT/tests/fuzz/setup-corpus.sh" "$build"
"$GEN4D_ROOT/tests/fuzz/smoke.sh" "$build" "$fuzz_seconds" "$fuzz_jobs"
phase "fuzz smoke"

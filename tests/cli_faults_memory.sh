#!/usr/bin/env bash
# A deck whose memory estimate exceeds the machine's available memory is refused up front
# (exit 1, the estimate and what the machine has, nothing written); --skip-memory-check lets a
# run through; an ordinary deck passes the check.
set -u
gen4d="$1"; mpiexec="$2"; dir="$3"
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
board="$here/../inputs/jelly_board.toml"
rm -rf "$dir"; mkdir -p "$dir"
short=(--set simulation.end_time=0.02 --set output.surface=\"none\")

# 0.0005 m voxels: about 2.6e8 solid voxels, far beyond this machine.
start=$(date +%s.%N)
"$mpiexec" -n 2 "$gen4d" run "$board" --out "$dir/huge" "${short[@]}" --set domain.voxel_size=0.0005 \
  > "$dir/huge.log" 2>&1
code=$?
took=$(awk -v a="$start" -v b="$(date +%s.%N)" 'BEGIN { printf "%.1f", b - a }')
echo "huge deck: exit $code after $took s: $(grep -m1 error "$dir/huge.log")"
[[ $code -eq 1 ]] || { echo "FAIL exit $code, expected 1"; cat "$dir/huge.log"; exit 1; }
grep -qE "error: .*jelly_board\.toml: the run needs about [0-9.]+ (GiB|MiB) \([0-9.e+]+ solid voxels x [0-9]+ bytes.*this run has [0-9.]+ (GiB|MiB) available.*domain\.voxel_size.*--skip-memory-check" \
  "$dir/huge.log" || { echo "FAIL no refusal with the estimate"; cat "$dir/huge.log"; exit 1; }
[[ ! -e "$dir/huge" ]] || { echo "FAIL the refused run wrote $dir/huge"; exit 1; }
awk -v t="$took" 'BEGIN { exit !(t <= 30) }' || { echo "FAIL refusal took $took s"; exit 1; }

# The same refusal on a restart's stored deck made huge by --set.
"$mpiexec" -n 2 "$gen4d" run "$board" --out "$dir/small" "${short[@]}" > "$dir/small.log" 2>&1 ||
  { echo "FAIL an ordinary deck"; cat "$dir/small.log"; exit 1; }
"$mpiexec" -n 2 "$gen4d" restart "$dir/small/checkpoint_00000002.h5" --set domain.voxel_size=0.0005 \
  > "$dir/restart.log" 2>&1
code=$?
if [[ $code -ne 1 ]] || ! grep -q "the run needs about" "$dir/restart.log"; then
  echo "FAIL restart of a huge deck: exit $code"; cat "$dir/restart.log"; exit 1
fi

# --skip-memory-check: the check is skipped (the run then fails later, or runs, as it may).
"$mpiexec" -n 1 "$gen4d" run "$board" --out "$dir/skipped" "${short[@]}" --skip-memory-check \
  > "$dir/skipped.log" 2>&1 || { echo "FAIL --skip-memory-check"; cat "$dir/skipped.log"; exit 1; }
echo "1 passed, 0 failed"

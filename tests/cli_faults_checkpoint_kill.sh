#!/usr/bin/env bash
# kill -9 of a rank while a 2-rank run writes a checkpoint: the previous checkpoint stays
# intact, the half-written hidden temporary is never taken for a checkpoint, a restart from
# the previous one removes the temporary and ends with the final frame of an uninterrupted run
# (bit for bit: the same rank count).
# GEN4D_TEST_SLOW_CHECKPOINT (src/io/Checkpoint.cpp) holds each checkpoint write open for a
# few seconds, so the kill lands inside one.
set -u
gen4d="$1"; mpiexec="$2"; dir="$3"
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
# shellcheck source=tests/cli_faults_common.sh
source "$here/cli_faults_common.sh"
board="$here/../inputs/jelly_board.toml"
rm -rf "$dir"; mkdir -p "$dir"
sets=(--set simulation.end_time=0.15 --set output.frame_interval=0.05 --set domain.voxel_size=0.04
      --set output.checkpoint_every=5 --set output.checkpoint_keep=100 --set output.surface=\"none\")
"$mpiexec" -n 2 "$gen4d" run "$board" --out "$dir/full" "${sets[@]}" > "$dir/full.log" 2>&1 ||
  { echo "FAIL uninterrupted run"; cat "$dir/full.log"; exit 1; }

GEN4D_TEST_SLOW_CHECKPOINT=4 "$mpiexec" -n 2 "$gen4d" run "$board" --out "$dir/cut" "${sets[@]}" \
  > "$dir/cut.log" 2>&1 &
launcher=$!
victim=$(rank_pid "$launcher" 1)
[[ -n $victim ]] || { echo "FAIL no rank 1 process"; kill -9 "$launcher"; exit 1; }
# The first checkpoint (step 5) is complete once it has its final name; the kill lands while
# the second one (step 10) is still a temporary.
if ! wait_for_file "$dir/cut/checkpoint_00000005.h5" ||
   ! wait_for_file "$dir/cut/.checkpoint_00000010.h5.tmp"; then
  echo "FAIL no checkpoint write to interrupt"; kill -9 "$launcher"; cat "$dir/cut.log"; exit 1
fi
sleep 1
kill -9 "$victim"
start=$(now)
wait "$launcher"; code=$?
echo "killed rank 1 (pid $victim) during a checkpoint write: the job ended after $(elapsed "$start") s, exit $code"
[[ $code -ne 0 ]] || { echo "FAIL the killed run exited 0"; exit 1; }

visible=$(cd "$dir/cut" && ls checkpoint_*.h5)
[[ $visible == "checkpoint_00000005.h5" ]] ||
  { echo "FAIL visible checkpoints after the kill: $visible"; exit 1; }
[[ -e "$dir/cut/.checkpoint_00000010.h5.tmp" ]] ||
  { echo "FAIL the killed write left no temporary (the test did not hit the write)"; exit 1; }
h5_check "$dir/cut/checkpoint_00000005.h5" || { echo "FAIL previous checkpoint unreadable"; exit 1; }

"$mpiexec" -n 2 "$gen4d" restart "$dir/cut/checkpoint_00000005.h5" > "$dir/restart.log" 2>&1 ||
  { echo "FAIL restart"; cat "$dir/restart.log"; exit 1; }
grep -q "removed .*\.checkpoint_00000010\.h5\.tmp" "$dir/restart.log" ||
  { echo "FAIL the restart did not report the stale temporary"; cat "$dir/restart.log"; exit 1; }
if compgen -G "$dir/cut/.checkpoint_*" > /dev/null; then
  echo "FAIL temporaries left after the restart: $(ls -a "$dir/cut")"; exit 1
fi
/usr/bin/python3 - "$dir/full/frames.h5" "$dir/cut/frames.h5" <<'PY' || exit 1
import sys, h5py, numpy as np
a, b = h5py.File(sys.argv[1], "r"), h5py.File(sys.argv[2], "r")
fa, fb = sorted(a["frames"]), sorted(b["frames"])
assert len(fa) == len(fb), (len(fa), len(fb))
for name in ("position", "velocity"):
    pa, pb = a["frames"][fa[-1]][name][...], b["frames"][fb[-1]][name][...]
    assert np.array_equal(pa, pb), (name, np.abs(pa - pb).max())
print(f"final frame {fa[-1]} of {len(fa)}: bit-identical to the uninterrupted run")
PY
echo "1 passed, 0 failed"

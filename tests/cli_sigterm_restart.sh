#!/usr/bin/env bash
# kill -TERM during a 2-rank run, restart on 1 rank, and compare the final frame with an
# uninterrupted run (within 1e-12 relative: different rank counts at the restart).
set -u
gen4d="$1"; mpiexec="$2"; dir="$3"
board="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)/inputs/jelly_board.toml"  # an ElastoGen scene
rm -rf "$dir"; mkdir -p "$dir"
sets=(--set simulation.end_time=1.0 --set output.frame_interval=0.1 --set output.progress_interval=0.5)
"$mpiexec" -n 2 "$gen4d" run "$board" --out "$dir/full" "${sets[@]}" > "$dir/full.log" 2>&1 || { echo "FAIL full run"; exit 1; }
"$mpiexec" -n 2 "$gen4d" run "$board" --out "$dir/cut" "${sets[@]}" > "$dir/cut.log" 2>&1 &
pid=$!
# Wait until a few steps have run, then send the batch system's warning signal.
for _ in $(seq 1 600); do grep -q "step  *[1-9][0-9]*/" "$dir/cut.log" 2>/dev/null && break; sleep 0.1; done
kill -TERM $pid
wait $pid; code=$?
[[ $code -eq 1 ]] || { echo "FAIL interrupted run exit $code"; cat "$dir/cut.log"; exit 1; }
ck=$(ls "$dir/cut"/checkpoint_*.h5 | tail -1)
grep -q "received SIGTERM" "$dir/cut.log" || { echo "FAIL no SIGTERM message"; exit 1; }
"$gen4d" restart "$ck" > "$dir/restart.log" 2>&1 || { echo "FAIL restart"; cat "$dir/restart.log"; exit 1; }
/usr/bin/python3 - "$dir/full/frames.h5" "$dir/cut/frames.h5" <<'PY' || exit 1
import sys, h5py, numpy as np
a, b = h5py.File(sys.argv[1], "r"), h5py.File(sys.argv[2], "r")
fa, fb = sorted(a["frames"]), sorted(b["frames"])
assert len(fa) == len(fb), (len(fa), len(fb))
pa, pb = a["frames"][fa[-1]]["position"][...], b["frames"][fb[-1]]["position"][...]
err = np.abs(pa - pb).max() / np.abs(pa).max()
print(f"final frame: {len(fa)} frames, max relative difference {err:.3e}")
assert err <= 1e-12, err
PY
echo "1 passed, 0 failed"

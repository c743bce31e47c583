#!/usr/bin/env bash
# gen4d run/restart with the MPM solver: outputs for every viewer, 1- vs 2-rank bit-identity,
# restart at another rank count, particles leaving the grid, the instability guard on a
# deliberately unstable deck, and one-line errors (exit 2) for bad MPM decks.
set -u
gen4d="$1"; mpiexec="$2"; dir="$3"; deck="$4"
rm -rf "$dir"; mkdir -p "$dir"
fail() { echo "FAIL $*"; exit 1; }
small=(--set simulation.end_time=0.12 --set output.frame_interval=0.03
       --set output.progress_interval=0.5 --set domain.voxel_size=0.02)

"$mpiexec" -n 2 "$gen4d" run "$deck" --out "$dir/np2" "${small[@]}" > "$dir/np2.log" 2>&1 ||
  { cat "$dir/np2.log"; fail "2-rank run"; }
for f in particles.h5 particles.xdmf particles/particles_000004.ply volumes/volume_000004.vdb; do
  [[ -s "$dir/np2/$f" ]] || fail "missing $f"
done
ls "$dir/np2"/checkpoint_*.h5 > /dev/null || fail "no checkpoint"
grep -q "phase timers" "$dir/np2.log" || fail "no phase timers"
grep -q "substep .* t = .* substeps/s  ETA" "$dir/np2.log" || fail "no progress line"

"$gen4d" run "$deck" --out "$dir/np1" "${small[@]}" > "$dir/np1.log" 2>&1 || fail "1-rank run"
# Stop at t = 0.06 on 2 ranks, restart to 0.12 on 1 rank.
"$mpiexec" -n 2 "$gen4d" run "$deck" --out "$dir/cut" "${small[@]}" \
  --set simulation.end_time=0.06 > "$dir/cut.log" 2>&1 || fail "short run"
ck=$(ls "$dir/cut"/checkpoint_*.h5 | tail -1)
"$gen4d" restart "$ck" --set simulation.end_time=0.12 > "$dir/restart.log" 2>&1 ||
  { cat "$dir/restart.log"; fail "restart"; }
/usr/bin/python3 - "$dir/np2/particles.h5" "$dir/np1/particles.h5" "$dir/cut/particles.h5" <<'PY' || exit 1
import sys, h5py, numpy as np
files = [h5py.File(p, "r") for p in sys.argv[1:]]
last = []
for f in files:
    names = sorted(f["frames"])
    assert len(names) == 5, (f.filename, names)
    g = f["frames"][names[-1]]
    last.append((g["position"][...], g["velocity"][...], g["alive"][...]))
for other in last[1:]:
    for a, b in zip(last[0], other):
        assert a.shape == b.shape and np.array_equal(a, b), "frames differ"
moved = np.abs(last[0][1]).max()
assert moved > 0.05, moved
print(f"final frame identical at 2 ranks, 1 rank and after a 2 -> 1 rank restart; {last[0][0].shape[0]} particles")
PY

# Batch signals: SIGUSR1 writes a checkpoint and the run goes on; SIGTERM writes one and stops
# with exit 1; the restart then finishes the run.
"$mpiexec" -n 2 "$gen4d" run "$deck" --out "$dir/sig" "${small[@]}" --set simulation.end_time=5 \
  > "$dir/sig.log" 2>&1 &
pid=$!
for _ in $(seq 1 600); do grep -q "^substep" "$dir/sig.log" 2>/dev/null && break; sleep 0.1; done
kill -USR1 $pid
for _ in $(seq 1 600); do grep -q "received SIGUSR1" "$dir/sig.log" && break; sleep 0.1; done
grep -q "received SIGUSR1" "$dir/sig.log" || { kill -TERM $pid; fail "no SIGUSR1 checkpoint"; }
kill -TERM $pid
wait $pid; code=$?
[[ $code -eq 1 ]] || { cat "$dir/sig.log"; fail "SIGTERM run exit $code"; }
grep -q "received SIGTERM: .*; stopping" "$dir/sig.log" || fail "no SIGTERM message"
ck=$(ls "$dir/sig"/checkpoint_*.h5 | tail -1)
"$gen4d" restart "$ck" --set simulation.end_time=0.5 > "$dir/sig-restart.log" 2>&1 ||
  { cat "$dir/sig-restart.log"; fail "restart after SIGTERM"; }

# Thrown out of a grid without walls: removed and counted, never a crash.
"$mpiexec" -n 2 "$gen4d" run "$deck" --out "$dir/out" "${small[@]}" --set "mpm.velocity=[8.0, 0.0, 3.0]" \
  --set mpm.out_of_domain=remove --set mpm.boundary_layers=0 > "$dir/out.log" 2>&1 || { cat "$dir/out.log"; fail "leaving run"; }
grep -Eq "particles that left the grid: [1-9][0-9]* removed" "$dir/out.log" || fail "no removal count"

# Deliberately unstable: fixed substeps 30x the elastic limit.
"$mpiexec" -n 2 "$gen4d" run "$deck" --out "$dir/unstable" "${small[@]}" --set mpm.substep=fixed \
  --set simulation.dt=0.01 > "$dir/unstable.log" 2>&1
code=$?
[[ $code -eq 1 ]] || { cat "$dir/unstable.log"; fail "unstable run exit $code"; }
grep -q "MPM instability at t = .* id [0-9]* at (" "$dir/unstable.log" || fail "no instability report"
grep -q "last good frame" "$dir/unstable.log" || fail "no last-good checkpoint"
ls "$dir/unstable"/checkpoint_*.h5 > /dev/null || fail "no checkpoint after the instability"

expect2() {  # expect2 PATTERN ARGS...: exit 2 and a one-line message matching PATTERN
  local pat="$1"; shift
  "$gen4d" "$@" > "$dir/err.log" 2>&1
  local c=$?
  [[ $c -eq 2 ]] || { cat "$dir/err.log"; fail "exit $c for: $*"; }
  grep -q -- "$pat" "$dir/err.log" || { cat "$dir/err.log"; fail "message '$pat' for: $*"; }
}
expect2 "material.yield_stress" run "$deck" --out "$dir/e1" --set material.yield_stress=10
expect2 "unknown MPM material\|known\|not a" run "$deck" --out "$dir/e2" --set material.model=sandy
expect2 "friction_angle" run "$deck" --out "$dir/e3" --set material.friction_angle=95
expect2 "boundary" run "$deck" --out "$dir/e4" --set boundary.0.surface=glue
expect2 "only applies to solver.method" run "$deck" --out "$dir/e5" --set solver.method=elastogen
echo "not hdf5" > "$dir/bad.h5"
expect2 "bad.h5" restart "$dir/bad.h5"
echo "1 passed, 0 failed"

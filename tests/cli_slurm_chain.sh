#!/usr/bin/env bash
# A time-limit chain on a real (one-node) Slurm: jobs/slurm/gen4d.sbatch runs a 2-rank deck
# that needs about 105 s with --time=1 (60 s) and --signal=B:USR1@50. Slurm sends SIGUSR1
# before the limit (gen4d checkpoints and continues), SIGTERM at the limit (gen4d checkpoints
# and stops), and the script requeues the job, which continues from the newest checkpoint
# until the run ends. The final frame (and every other) must be bit-identical to an
# uninterrupted 2-rank run of the same deck. Slurm checks time limits about every 30 s, so
# the first segment ends 60 to 90 s after it starts. The job's steps are paced by the test
# hook GEN4D_TEST_STEP_SECONDS (a 0.8 s sleep per step, parallel/Signals.cpp), so that 130
# steps of a small deck outlast the limit on any machine without loading it; the
# uninterrupted run is not paced. Slurm holds a requeued job about 2 minutes; the
# uninterrupted run is made during that hold, and then the job is released (scontrol update
# StartTime=now). About 4 minutes in all, nearly all of it waiting.
set -u
gen4d="$(realpath "$1")"
mpiexec="$2"
dir="$3"
rm -rf "$dir"
mkdir -p "$dir"
source "$(dirname "${BASH_SOURCE[0]}")/cli_slurm_lib.sh"
slurm_start "$dir"
cd "$dir" || exit 1
deck="$root/inputs/jelly_board.toml"
base=(--set output.frame_interval=0.1 --set output.checkpoint_every=0 --set output.surface=none
  --set output.progress_interval=2)

# 130 steps (dt = 0.01 s) paced to 104 s: the first job ends 60 to 90 s after it starts.
pace=0.8
end_time=1.30
# ended STATE: true for a job state that is final (Slurm 22.05's list).
ended() {
  case "$1" in
    COMPLETED | FAILED | CANCELLED | TIMEOUT | NODE_FAIL | OUT_OF_MEMORY | PREEMPTED | \
      BOOT_FAIL | DEADLINE) return 0 ;;
  esac
  return 1
}
# submit: the chain job with the current end_time; then waits (at most 3 minutes) for its
# requeue (pending again with one restart). Sets id, log, sets, state and requeued.
submit() {
  sets=("${base[@]}" --set simulation.end_time="$end_time")
  rm -rf "$dir/chain"
  export GEN4D="$gen4d" GEN4D_ROOT="$root" DECK="$deck" OUT="$dir/chain" GEN4D_ARGS="${sets[*]}" \
    GEN4D_TEST_STEP_SECONDS="$pace"
  id="$(slurm_submit --ntasks=2 --time=1 --signal=B:USR1@50 --output="$dir/job-%j.log" \
    "$root/jobs/slurm/gen4d.sbatch")"
  echo "job $id submitted at $(date +%T) (end_time $end_time s)"
  log="$dir/job-$id.log"
  requeued=0
  for _ in $(seq 1 180); do
    state="$(slurm_field "$id" JobState)"
    if [[ "$(slurm_field "$id" Restarts)" -ge 1 ]]; then
      requeued=1
      return
    fi
    ended "$state" && return
    sleep 1
  done
}
submit
if [[ $requeued -ne 1 && $state == COMPLETED ]]; then
  # Slurm let the job run past its limit (it checks about every 30 s): twice as long.
  echo "job $id ended before its time limit; again with twice the simulated time"
  end_time="$(awk -v t="$end_time" 'BEGIN {printf "%.2f", 2 * t}')"
  submit
fi
[[ $requeued -eq 1 ]] || { cat "$log"; slurm_fail "job $id was not requeued (state $state)"; }
echo "job $id requeued at $(date +%T)"

# The uninterrupted run while Slurm holds the requeued job.
t0=$SECONDS
GEN4D_TEST_STEP_SECONDS=0 "$mpiexec" -n 2 "$gen4d" run "$deck" --out "$dir/full" "${sets[@]}" \
  > "$dir/full.log" 2>&1 ||
  { cat "$dir/full.log"; slurm_fail "uninterrupted run"; }
echo "uninterrupted run: $((SECONDS - t0)) s"

# Until the job ends, releasing each requeue hold at once.
state=""
for _ in $(seq 1 600); do
  state="$(slurm_field "$id" JobState)"
  ended "$state" && break
  if [[ $state == PENDING && "$(slurm_field "$id" Reason)" == BeginTime ]]; then
    scontrol update JobId="$id" StartTime=now
  fi
  sleep 1
done
echo "job $id ended at $(date +%T): $state"
cat "$log"
# A segment whose run ends within Slurm's check interval after its limit is marked TIMEOUT
# though its run finished (its last step and final checkpoint are written): the work is done.
if [[ $state == TIMEOUT ]] && grep "gen4d-job " "$log" | tail -n 1 | grep -q ": run finished"; then
  echo "job $id: the last segment finished its run and then passed its time limit (TIMEOUT)"
else
  [[ $state == COMPLETED ]] || slurm_fail "job $id: $state"
fi
grep -q "received SIGUSR1: checkpoint" "$log" || slurm_fail "no SIGUSR1 checkpoint in the log"
grep -q "received SIGTERM: checkpoint" "$log" || slurm_fail "no SIGTERM checkpoint in the log"
grep -q "stopping; resume with" "$log" || slurm_fail "no checkpoint-and-stop in the log"
grep -q "CANCELLED AT .* DUE TO TIME LIMIT" "$log" || slurm_fail "the job did not reach its time limit"
grep -q "requeueing job $id" "$log" || slurm_fail "the script did not requeue the job"
grep -q "gen4d-job .*: continuing from .*checkpoint_" "$log" || slurm_fail "no continuation"
grep -q "gen4d-job .*: run finished" "$log" || slurm_fail "the run did not finish"
echo "segments: $(grep -c "gen4d-job .*: job $id" "$log"), restarts $(slurm_field "$id" Restarts)"

/usr/bin/python3 - "$dir/full/frames.h5" "$dir/chain/frames.h5" <<'PY' || slurm_fail "frames differ"
import sys, h5py, numpy as np
a, b = h5py.File(sys.argv[1], "r"), h5py.File(sys.argv[2], "r")
fa, fb = sorted(a["frames"]), sorted(b["frames"])
assert fa == fb, (fa, fb)
for name in fa:
    pa, pb = a["frames"][name]["position"][...], b["frames"][name]["position"][...]
    assert a["frames"][name].attrs["step"] == b["frames"][name].attrs["step"], name
    assert np.array_equal(pa, pb), (name, np.abs(pa - pb).max())
last = a["frames"][fa[-1]]
print(f"{len(fa)} frames bit-identical; final frame t = {last.attrs['time']:.2f} s, "
      f"step {last.attrs['step']}")
PY
echo "1 passed, 0 failed"

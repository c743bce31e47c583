#!/usr/bin/env bash
# A time-limit chain on a real (one-node) Slurm: jobs/slurm/gen4d.sbatch runs a 2-rank deck
# that needs about 130 s with --time=1 (60 s) and --signal=B:USR1@50. Slurm sends SIGUSR1
# before the limit (gen4d checkpoints and continues), SIGTERM at the limit (gen4d checkpoints
# and stops), and the script requeues the job, which continues from the newest checkpoint
# until the run ends. The final frame (and every other) must be bit-identical to an
# uninterrupted 2-rank run of the same deck. Slurm checks time limits about every 30 s, so
# the first segment ends 60 to 90 s after it starts; the deck's length (about 130 s of
# stepping) is set from a short timing run so that the limit falls mid-run on a faster or
# slower machine too (and doubled once if the job still ends before its limit). Slurm holds a
# requeued job about 2 minutes; the uninterrupted run is made during that hold, and then the
# job is released (scontrol update StartTime=now). About 5 minutes in all.
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

# Timing: seconds per step at 2 ranks over 20 steps (gen4d's "done: N steps in S s"), started
# by srun as in the job.
srun --ntasks=2 "$gen4d" run "$deck" --out "$dir/timing" "${base[@]}" \
  --set simulation.end_time=0.2 > "$dir/timing.log" 2>&1 || { cat "$dir/timing.log"; slurm_fail "timing run"; }
per_step="$(sed -n 's/^done: 20 steps in \([0-9.]*\) s.*/\1/p' "$dir/timing.log" | awk '{print $1 / 20}')"
[[ -n $per_step ]] || { cat "$dir/timing.log"; slurm_fail "no 'done: 20 steps' in the timing run"; }
# 130 s of stepping: the first job ends 60 to 90 s after it starts, mid-run, even if the
# machine runs 30 % faster than in the timing run. A slower machine adds requeues.
end_time="$(awk -v s="$per_step" 'BEGIN {printf "%.2f", 0.01 * int(130 / s)}')"
echo "timing run: $per_step s per step; end_time $end_time s ($(awk -v s="$per_step" -v t="$end_time" 'BEGIN {printf "%d", t / 0.01 * s}') s of stepping)"
# submit: the chain job with the current end_time; then waits (at most 3 minutes) for its
# requeue (pending again with one restart). Sets id, log, sets, state and requeued.
submit() {
  sets=("${base[@]}" --set simulation.end_time="$end_time")
  rm -rf "$dir/chain"
  export GEN4D="$gen4d" GEN4D_ROOT="$root" DECK="$deck" OUT="$dir/chain" GEN4D_ARGS="${sets[*]}"
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
    [[ $state == COMPLETED || $state == FAILED || $state == CANCELLED ]] && return
    sleep 1
  done
}
submit
if [[ $requeued -ne 1 && $state == COMPLETED ]]; then
  # The machine ran much faster than in the timing run (other load ended): twice as long.
  echo "job $id ended before its time limit; again with twice the simulated time"
  end_time="$(awk -v t="$end_time" 'BEGIN {printf "%.2f", 2 * t}')"
  submit
fi
[[ $requeued -eq 1 ]] || { cat "$log"; slurm_fail "job $id was not requeued (state $state)"; }
echo "job $id requeued at $(date +%T)"

# The uninterrupted run while Slurm holds the requeued job.
t0=$SECONDS
"$mpiexec" -n 2 "$gen4d" run "$deck" --out "$dir/full" "${sets[@]}" > "$dir/full.log" 2>&1 ||
  { cat "$dir/full.log"; slurm_fail "uninterrupted run"; }
echo "uninterrupted run: $((SECONDS - t0)) s"

# Until the job ends, releasing each requeue hold at once.
state=""
for _ in $(seq 1 600); do
  state="$(slurm_field "$id" JobState)"
  [[ $state == COMPLETED || $state == FAILED || $state == CANCELLED ]] && break
  if [[ $state == PENDING && "$(slurm_field "$id" Reason)" == BeginTime ]]; then
    scontrol update JobId="$id" StartTime=now
  fi
  sleep 1
done
echo "job $id ended at $(date +%T): $state"
cat "$log"
[[ $state == COMPLETED ]] || slurm_fail "job $id: $state"
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

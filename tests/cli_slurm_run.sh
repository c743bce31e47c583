#!/usr/bin/env bash
# A deck run to its end through sbatch and jobs/slurm/gen4d.sbatch on a one-node Slurm cluster
# started here: the job completes, the log says the run finished, and the final frame is at
# the deck's end time.
set -u
gen4d="$(realpath "$1")"
dir="$3"
rm -rf "$dir"
mkdir -p "$dir"
source "$(dirname "${BASH_SOURCE[0]}")/cli_slurm_lib.sh"
slurm_start "$dir"
cd "$dir" || exit 1

deck="$root/inputs/jelly_board.toml"
export GEN4D="$gen4d" GEN4D_ROOT="$root" DECK="$deck" OUT="$dir/run"
export GEN4D_ARGS="--set simulation.end_time=0.3 --set output.frame_interval=0.05 --set domain.voxel_size=0.04"
id="$(slurm_submit --ntasks=2 --time=5 --output="$dir/job-%j.log" "$root/jobs/slurm/gen4d.sbatch")"
echo "job $id submitted"
state="$(slurm_wait "$id" 240)"
log="$dir/job-$id.log"
[[ $state == COMPLETED ]] || { cat "$log"; slurm_fail "job $id: $state, exit $(slurm_field "$id" ExitCode)"; }
grep -q "gen4d-job .*: run finished" "$log" || { cat "$log"; slurm_fail "no 'run finished' in $log"; }
/usr/bin/python3 - "$dir/run/frames.h5" <<'PY' || slurm_fail "final frame"
import sys, h5py
with h5py.File(sys.argv[1], "r") as f:
    names = sorted(f["frames"])
    last = f["frames"][names[-1]]
    t = float(last.attrs["time"])
    print(f"{len(names)} frames, final frame {names[-1]} at t = {t:.4f} s, step {int(last.attrs['step'])}")
    assert len(names) == 7, len(names)
    assert abs(t - 0.3) < 1e-9, t
    assert last["position"].shape[-1] == 3
PY
echo "1 passed, 0 failed"

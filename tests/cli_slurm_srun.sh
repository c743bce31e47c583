#!/usr/bin/env bash
# Two ranks started by srun inside a batch job (--ntasks=2), with the PMI that Debian's OpenMPI
# works with: srun --mpi=pmix is tried first, then pmi2 (`srun --mpi=list` shows the plugins).
# The run must really have 2 ranks (gen4d's log says so) and its frames must be bit-identical
# to the same deck run by mpirun -n 2.
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
sets=(--set simulation.end_time=0.3 --set output.frame_interval=0.05 --set output.surface=none
  --set domain.voxel_size=0.04)

srun --mpi=list 2>&1 | tr '\n' ' '
echo
mpi=""
for m in pmix pmi2; do
  if srun --mpi="$m" --ntasks=2 "$gen4d" info > "$dir/info-$m.log" 2>&1 &&
    grep -q "2 rank(s) in this run" "$dir/info-$m.log"; then
    mpi="$m"
    echo "srun --mpi=$m: 2 ranks"
    break
  fi
  echo "srun --mpi=$m does not start gen4d's MPI: $(grep -m1 -i -E "error|abort" "$dir/info-$m.log")"
done
[[ -n $mpi ]] || slurm_fail "neither srun --mpi=pmix nor --mpi=pmi2 starts 2 ranks"

export GEN4D="$gen4d" GEN4D_ROOT="$root" DECK="$deck" OUT="$dir/srun" SRUN_MPI="$mpi"
export GEN4D_ARGS="${sets[*]}"
id="$(slurm_submit --ntasks=2 --time=5 --output="$dir/job-%j.log" "$root/jobs/slurm/gen4d.sbatch")"
state="$(slurm_wait "$id" 240)"
log="$dir/job-$id.log"
[[ $state == COMPLETED ]] || { cat "$log"; slurm_fail "job $id: $state"; }
grep -q "gen4d-job .*: job $id .*, 2 task(s)" "$log" || { cat "$log"; slurm_fail "the job did not have 2 tasks"; }
grep -q "' on 2 rank(s): grid" "$log" || { cat "$log"; slurm_fail "gen4d's log does not show 2 ranks"; }
grep -m1 "' on 2 rank(s): grid" "$log"
# The same deck by mpirun, after the job (the two would share the cores).
"$mpiexec" -n 2 "$gen4d" run "$deck" --out "$dir/mpirun" "${sets[@]}" > "$dir/mpirun.log" 2>&1 ||
  { cat "$dir/mpirun.log"; slurm_fail "mpirun run"; }

/usr/bin/python3 - "$dir/mpirun/frames.h5" "$dir/srun/frames.h5" <<'PY' || slurm_fail "frames differ"
import sys, h5py, numpy as np
a, b = h5py.File(sys.argv[1], "r"), h5py.File(sys.argv[2], "r")
fa, fb = sorted(a["frames"]), sorted(b["frames"])
assert fa == fb and len(fa) == 7, (fa, fb)
for name in fa:
    pa, pb = a["frames"][name]["position"][...], b["frames"][name]["position"][...]
    assert np.array_equal(pa, pb), (name, np.abs(pa - pb).max())
print(f"{len(fa)} frames bit-identical between srun --mpi and mpirun -n 2")
PY
echo "1 passed, 0 failed"

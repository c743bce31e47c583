#!/usr/bin/env bash
# A job array sweeping Young's modulus over four values (x4 apart) (jobs/slurm/sweep.sbatch, one output
# folder per task) and the summary job that starts after all four succeed
# (--dependency=afterok, jobs/slurm/sweep-summary.sbatch): four folders, a table of four rows,
# and a peak displacement that falls as the modulus rises.
set -u
gen4d="$(realpath "$1")"
dir="$3"
rm -rf "$dir"
mkdir -p "$dir"
source "$(dirname "${BASH_SOURCE[0]}")/cli_slurm_lib.sh"
slurm_start "$dir"
cd "$dir" || exit 1

values="1e5 4e5 1.6e6 6.4e6"
export GEN4D="$gen4d" GEN4D_ROOT="$root" DECK="$root/inputs/jelly_board.toml" OUT="$dir/sweep"
export VALUES="$values"
GEN4D_ARGS="--set simulation.end_time=0.3 --set output.frame_interval=0.02"
export GEN4D_ARGS+=" --set output.surface=none --set domain.voxel_size=0.04"
array="$(slurm_submit --time=5 --output="$dir/sweep-%A_%a.log" "$root/jobs/slurm/sweep.sbatch")"
summary="$(slurm_submit --time=5 --dependency=afterok:"$array" --output="$dir/summary-%j.log" \
  "$root/jobs/slurm/sweep-summary.sbatch")"
echo "array job $array, summary job $summary (afterok:$array)"
state="$(slurm_wait "$summary" 300)"
cat "$dir/summary-$summary.log"
[[ $state == COMPLETED ]] || { tail -n 20 "$dir"/sweep-*.log; slurm_fail "summary job $summary: $state"; }
for task in 0 1 2 3; do
  [[ "$(slurm_field "${array}_$task" JobState)" == COMPLETED ]] || slurm_fail "task $task not COMPLETED"
done

/usr/bin/python3 - "$dir/sweep" "$values" <<'PY' || slurm_fail "summary"
import csv, pathlib, sys
out, values = pathlib.Path(sys.argv[1]), sys.argv[2].split()
folders = sorted(p.name for p in out.glob("task_*"))
want = sorted(f"task_{i}_E{v}" for i, v in enumerate(values))
assert folders == want, (folders, want)
for f in folders:
    assert (out / f / "frames.h5").is_file(), f
rows = list(csv.DictReader(open(out / "summary.csv")))
assert len(rows) == 4, len(rows)
assert [r["task"] for r in rows] == ["0", "1", "2", "3"], rows
assert [r["value"] for r in rows] == values, rows
assert all(abs(float(r["final_time_s"]) - 0.3) < 1e-9 for r in rows), rows
md = (out / "summary.md").read_text().splitlines()
assert len(md) == 2 + 4, md
peak = [float(r["peak_displacement_m"]) for r in rows]
print("E:", values, "peak displacement (m):", peak)
assert all(a > b for a, b in zip(peak, peak[1:])), peak
assert peak[-1] > 0, peak
PY
echo "1 passed, 0 failed"

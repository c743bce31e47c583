#!/usr/bin/python3
"""Tabulates a sweep written by jobs/slurm/sweep.sbatch.

Usage: sweep_summary.py OUT
Reads OUT/task_*/task.txt and OUT/task_*/frames.h5; writes OUT/summary.csv and
OUT/summary.md, one row per task in task order: the swept value, the final frame's time and
step, the peak displacement (largest |x(t) - x(0)| over every node and frame), the final
frame's largest displacement, the run's wall time and exit code. Exits 1 naming the folder when
a task's files are missing or its run failed.
"""
import csv
import pathlib
import sys

import h5py
import numpy as np


def read_task(folder):
    info_path = folder / "task.txt"
    if not info_path.is_file():
        raise SystemExit(f"sweep_summary: {info_path}: missing (did the task run?)")
    info = {}
    for n, line in enumerate(info_path.read_text().splitlines(), 1):
        if "=" not in line:
            raise SystemExit(f"sweep_summary: {info_path}:{n}: expected key=value, got {line!r}")
        key, value = line.split("=", 1)
        info[key] = value
    if info.get("exit_code") != "0":
        raise SystemExit(f"sweep_summary: {folder}: gen4d exited {info.get('exit_code')} "
                         f"(see {folder / 'gen4d.log'})")
    frames_path = folder / "frames.h5"
    if not frames_path.is_file():
        raise SystemExit(f"sweep_summary: {frames_path}: missing")
    with h5py.File(frames_path, "r") as f:
        names = sorted(f["frames"])
        if len(names) < 2:
            raise SystemExit(f"sweep_summary: {frames_path}: {len(names)} frame(s), need 2+")
        rest = f["frames"][names[0]]["position"][...]
        peak = 0.0
        for name in names:
            d = np.linalg.norm(f["frames"][name]["position"][...] - rest, axis=-1).max()
            peak = max(peak, float(d))
        last = f["frames"][names[-1]]
        final = float(np.linalg.norm(last["position"][...] - rest, axis=-1).max())
        return {
            "task": int(info["task"]),
            "param": info["param"],
            "value": info["value"],
            "final_time_s": float(last.attrs["time"]),
            "final_step": int(last.attrs["step"]),
            "frames": len(names),
            "peak_displacement_m": peak,
            "final_displacement_m": final,
            "wall_seconds": float(info["wall_seconds"]),
        }


def main():
    if len(sys.argv) != 2:
        raise SystemExit("usage: sweep_summary.py OUT")
    out = pathlib.Path(sys.argv[1])
    folders = sorted(out.glob("task_*"), key=lambda p: int(p.name.split("_")[1]))
    if not folders:
        raise SystemExit(f"sweep_summary: {out}: no task_* folders")
    rows = [read_task(p) for p in folders]
    keys = list(rows[0])
    with open(out / "summary.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keys)
        w.writeheader()
        w.writerows(rows)
    fmt = {"final_time_s": "{:.4f}", "peak_displacement_m": "{:.6e}",
           "final_displacement_m": "{:.6e}", "wall_seconds": "{:.2f}"}
    lines = ["| " + " | ".join(keys) + " |", "|" + "---|" * len(keys)]
    for r in rows:
        lines.append("| " + " | ".join(fmt.get(k, "{}").format(r[k]) for k in keys) + " |")
    (out / "summary.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()

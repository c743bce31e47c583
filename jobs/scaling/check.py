#!/usr/bin/env python3
"""Checks that a scaling study's outputs exist and are well-formed (no timing is judged):

    /usr/bin/python3 jobs/scaling/check.py OUT_DIR "1 2 4"

scaling.csv has a row for every code, kind and rank count with positive times, phases that
parse, speed-up 1 at 1 rank and `oversubscribed` set exactly where ranks exceed the cores;
mpi.csv, checkpoint.csv, counts.tsv, model.json (finite fitted constants and residuals),
projection.csv (1 .. 1,024 ranks for every code and kind on both networks) and the PNG plots
are there. Prints every failed check and exits 1 if any failed.
"""
import csv
import json
import math
import os
import sys

CODES = ("elastogen", "mpm", "render")
PLOTS = ("speedup.png", "efficiency.png", "phases.png", "mpi.png", "projection.png")


def main(out, ranks):
    errors = []

    def check(cond, what):
        if not cond:
            errors.append(what)
        return cond

    def rows(name):
        path = os.path.join(out, name)
        if not check(os.path.isfile(path), f"{path}: missing"):
            return []
        with open(path, newline="") as f:
            r = list(csv.DictReader(f, delimiter="\t" if name.endswith(".tsv") else ","))
        check(r, f"{path}: no rows")
        return r

    cores = int({r["key"]: r["value"] for r in rows("params.tsv")}.get("cores", "0"))
    check(cores > 0, "params.tsv: no core count")
    sc = rows("scaling.csv")
    for code in CODES:
        for kind in ("strong", "weak"):
            for p in ranks:
                sel = [r for r in sc if r["code"] == code and r["kind"] == kind and int(r["ranks"]) == p]
                if not check(len(sel) == 1, f"scaling.csv: {len(sel)} rows for {code} {kind} {p} ranks"):
                    continue
                r = sel[0]
                where = f"scaling.csv: {code} {kind} {p} ranks"
                check(int(r["oversubscribed"]) == int(p > cores), f"{where}: oversubscribed flag")
                for key in ("time_per_step_s", "throughput_per_s", "speedup", "efficiency", "size"):
                    v = float(r[key])
                    check(math.isfinite(v) and v > 0, f"{where}: {key} = {r[key]}")
                check(float(r["load1_start"]) >= 0, f"{where}: load average")
                phases = dict(kv.split("=") for kv in r["phase_seconds_per_step"].split(";"))
                check(len(phases) >= 3, f"{where}: phases '{r['phase_seconds_per_step']}'")
                check(all(math.isfinite(float(v)) and float(v) >= 0 for v in phases.values()),
                      f"{where}: a phase time is not a finite non-negative number")
                if p == 1:
                    check(abs(float(r["speedup"]) - 1) < 1e-9, f"{where}: speed-up at 1 rank")

    mpi = rows("mpi.csv")
    for p in (q for q in ranks if q >= 2):
        pp = [r for r in mpi if int(r["ranks"]) == p and r["measure"] == "pingpong"]
        check(len(pp) >= 2, f"mpi.csv: no ping-pong sizes at {p} ranks")
        check(all(float(r["one_way_us"]) > 0 and float(r["MBps"]) > 0 for r in pp),
              f"mpi.csv: non-positive ping-pong at {p} ranks")
        for m in ("allreduce_1_double", "allgather_exact_sum"):
            c = [r for r in mpi if int(r["ranks"]) == p and r["measure"] == m]
            check(len(c) == 1 and float(c[0]["one_way_us"]) > 0, f"mpi.csv: {m} at {p} ranks")
        check(all(int(r["oversubscribed"]) == int(p > cores) for r in mpi if int(r["ranks"]) == p),
              f"mpi.csv: oversubscribed flag at {p} ranks")

    ck = rows("checkpoint.csv")
    check(any(r["writer"].startswith("gen4d") for r in ck), "checkpoint.csv: no gen4d row")
    check(sum(r["writer"].startswith("dd") for r in ck) == 2, "checkpoint.csv: not two dd rows")
    # Sizes only: a tiny checkpoint's time is below the timer's millisecond resolution.
    check(all(int(r["bytes"]) > 0 and math.isfinite(float(r["seconds"])) for r in ck),
          "checkpoint.csv: a non-positive size or a time that is not a number")

    counts = rows("counts.tsv")
    check({r["code"] for r in counts} == {"elastogen", "mpm"}, "counts.tsv: codes")

    path = os.path.join(out, "model.json")
    if check(os.path.isfile(path), f"{path}: missing"):
        with open(path) as f:
            model = json.load(f)
        for code in CODES:
            m = model["codes"].get(code)
            if not check(m is not None, f"model.json: no {code}"):
                continue
            check(math.isfinite(m["rate_per_rank"]) and m["rate_per_rank"] > 0,
                  f"model.json: {code} rate {m['rate_per_rank']}")
            res = m["compute_residuals_s"]
            check(res and all(math.isfinite(x) for x in res), f"model.json: {code} residuals {res}")
            check(all(math.isfinite(v) and v >= 0 for v in m["fit"].values()),
                  f"model.json: {code} fitted communication constants {m['fit']}")
            check(all(math.isfinite(x) for x in m["comm_residuals_s"]),
                  f"model.json: {code} communication residuals {m['comm_residuals_s']}")
        for key in ("alpha_s", "beta_Bps", "alpha_coll_s"):
            v = model["machine"][key]
            check(math.isfinite(v) and v > 0, f"model.json: machine {key} = {v}")
        check(all(math.isfinite(x) for x in model["transport_fit_relative_residuals"]),
              "model.json: transport fit residuals")
        check(model.get("counts_check_2_ranks"), "model.json: no communication-count check")

    proj = rows("projection.csv")
    for net in ("cluster", "machine"):
        for code in CODES:
            for kind in ("strong", "weak"):
                sel = sorted(int(r["ranks"]) for r in proj
                             if r["network"] == net and r["code"] == code and r["kind"] == kind)
                check(sel == [2 ** i for i in range(11)],
                      f"projection.csv: {net} {code} {kind} ranks {sel}")
    check(all(float(r["compute_s"]) > 0 and float(r["comm_s"]) >= 0 for r in proj),
          "projection.csv: non-positive times")

    for name in PLOTS:
        path = os.path.join(out, name)
        ok = os.path.isfile(path) and os.path.getsize(path) > 2000
        if ok:
            with open(path, "rb") as f:
                ok = f.read(8) == b"\x89PNG\r\n\x1a\n"
        check(ok, f"{path}: missing or not a PNG")

    for e in errors:
        print(f"check.py: {e}", file=sys.stderr)
    print(f"check.py: {out}: {'FAILED, ' + str(len(errors)) + ' problem(s)' if errors else 'all outputs well-formed'}")
    return 1 if errors else 0


if __name__ == "__main__":
    if len(sys.argv) != 3:
        print('usage: check.py OUT_DIR "RANKS"', file=sys.stderr)
        sys.exit(2)
    sys.exit(main(sys.argv[1], [int(x) for x in sys.argv[2].split()]))

#!/usr/bin/env python3
"""Collects a scaling study (jobs/scaling/study.sh) into CSV files, fits the performance model,
projects time per step to 1,024 ranks and draws the plots.

    /usr/bin/python3 jobs/scaling/model.py OUT_DIR

Reads OUT_DIR/runs.tsv and the raw outputs under OUT_DIR/raw (gen4d logs, bench JSON),
OUT_DIR/checkpoint_runs.tsv and OUT_DIR/dd.tsv when present. Writes into OUT_DIR:
  scaling.csv      one row per run: code, kind, ranks, oversubscribed, size, time per step,
                   per-phase seconds per step, throughput, speed-up, efficiency, load average
  mpi.csv          ping-pong one-way time and bandwidth per message size, collectives
  checkpoint.csv   gen4d's parallel HDF5 checkpoint write against dd in the same folder
  model.json       fitted constants, counted constants, assumptions, residuals
  projection.csv   projected compute and communication time per step, 1 .. 1,024 ranks
  speedup.png, efficiency.png, phases.png, mpi.png, projection.png
and prints the tables. Exit status 1 with a message naming the file when an input is missing
or malformed.

The model (per step of each code, p ranks, the slowest rank):
  T(p) = T_compute(p) + T_comm(p)
  T_compute = local work / (fitted per-rank rate); local work from a 3D block decomposition
  T_comm = sum over the code's exchanges of (messages x alpha + bytes / beta + o + g x bytes)
          + sum over its collectives of their latency (alpha_c log2 p, plus the bytes of the
            all-gathers, which grow with p)
  with the message and byte counts taken from the code (see the counts below, checked against
  a run by mpi_count.c) and o, g fitted on the 2-rank runs (software cost per exchange and per
  byte: packing, unpacking and the waiting for the slowest rank). The projection is printed
  with the fitted o, g and with the transport alone ("cluster_transport_only").
"""
import csv
import json
import math
import os
import re
import sys

import numpy as np

# ---------------------------------------------------------------------------------------------
# Counts from the code (per step; file references are relative to the repository root).
# ElastoGen, RNN-1 with Jacobi relaxation, anderson_depth = 0, O outer loops of S sweeps, K modes:
#   halo gathers (parallel/Halo.cpp: DMDA box stencil of width 1, 3 doubles a node, one
#   DMLocalToLocal per gather): 1 after the prediction + O x (S sweeps + 1 final delta + 1 of x)
#   + 1 of v            (elastogen/Elastodynamics.cpp step(), GlobalSolver.cpp jacobi())
#   exact global sums (parallel/Reduce.cpp: one MPI_Allgather of 68 int64 per rank each):
#   1 initial residual + O x (1 |r| + [K>0] subspace start + ceil(S/8) residual checks
#   + 1 residual + 2 change norms) + 1 |f_ext| + 2 accuracy
# MPM substep (mpm/Solver.cpp substep()):
#   halo: one scatter_add of 4 doubles a node = DMLocalToGlobal(ADD) + DMGlobalToLocal, so
#   2 x 32 B per ghost node; collectives: stable_dt max, P2G quantum max, migration:
#   MPI_Alltoall of counts + MPI_Allreduce (size check) + MPI_Alltoallv + sum_of (4 latencies
#   of small collectives, 1 all-to-all with p-1 messages); migration rows (parallel/
#   Distribute.cpp RowExchange, mpm/Particles.hpp columns): id 8 + x 24 + v 24 + C 72 + F 72
#   + state 32 + mass 8 + vol0 8 + flag 1 + material 1 = 250 B per particle sent.
# Renderer frame (gaussians/RenderDistributed.cpp): projected splats (52 B, RenderDetail.hpp
#   Projected) sent to the ranks owning the tile rows they touch (one RowExchange), the
#   image rows (3 floats a pixel) gathered on rank 0.
ELASTOGEN_BYTES_PER_GHOST_NODE = 24.0
EXACT_SUM_BYTES = 544.0
MPM_HALO_BYTES_PER_GHOST_NODE = 64.0
MPM_HALO_EXCHANGES = 2     # messages per neighbour and substep
MPM_SMALL_COLLECTIVES = 5   # MPI_Allreduce a substep, counted by the interposer
MPM_BENCH_CASES = 2         # bench_mpm runs an elastic and a sand block, each --substeps
ELASTOGEN_ALLREDUCES = 1    # parallel/Signals.cpp pending(): one MPI_Allreduce a step
MPM_BYTES_PER_PARTICLE = 250.0
MPM_CFL = 0.3  # mpm/Solver.hpp SolverOptions::cfl
RENDER_BYTES_PER_SPLAT = 52.0
RENDER_BYTES_PER_PIXEL = 12.0
RENDER_PIXELS = 1920 * 1080


def eg_counts(outer, sweeps, modes):
    gathers = 2 + outer * (sweeps + 2)
    sums = 4 + outer * (4 + math.ceil(sweeps / 8) + (1 if modes > 0 else 0))
    return gathers, sums



# Assumed cluster network (stated, not measured): InfiniBand HDR100-class fabric, every halo
# message and collective stage crossing it (pessimistic: ranks on one node would use memory).
CLUSTER = {
    "name": "InfiniBand HDR100-class cluster (assumed)",
    "alpha_s": 1.5e-6,        # one-way small-message latency
    "beta_Bps": 12.0e9,       # point-to-point bandwidth per rank
    "alpha_coll_s": 2.0e-6,   # latency per log2 p stage of a small collective
}
# Production sizes the projection holds fixed (strong: global; weak: per rank).
PROJECTION = {
    "elastogen": {"strong": 256 ** 3, "weak": 64 ** 3, "unit": "voxels"},
    "mpm": {"strong": 100_000_000, "weak": 1_000_000, "unit": "particles"},
    "render": {"strong": 10_000_000, "weak": 1_000_000, "unit": "splats"},
}
RANKS = [2 ** i for i in range(11)]


class InputProblem(Exception):
    pass


def need(path):
    if not os.path.isfile(path):
        raise InputProblem(f"{path}: missing")
    return path


def read_tsv(path):
    with open(need(path), newline="") as f:
        rows = list(csv.DictReader(f, delimiter="\t"))
    if not rows:
        raise InputProblem(f"{path}: no rows")
    return rows


def load_json(path):
    try:
        with open(need(path)) as f:
            return json.load(f)
    except json.JSONDecodeError as e:
        raise InputProblem(f"{path}: line {e.lineno}: not JSON ({e.msg})") from None


TIMER_HEAD = re.compile(r"phase timers \(max over ranks, wall ([0-9.eE+-]+) s")


def gen4d_timers(path):
    """(wall, {phase: seconds}) from the phase-timer table at the end of a gen4d run log."""
    with open(need(path)) as f:
        lines = f.read().splitlines()
    for i, line in enumerate(lines):
        m = TIMER_HEAD.search(line)
        if not m:
            continue
        phases = {}
        for row in lines[i + 1:]:
            r = re.search(r"\s([a-z0-9+_]+)\s+([0-9.eE+-]+) s\s+[0-9.]+ %", row)
            if not r:
                break
            phases[r.group(1)] = float(r.group(2))
        if not phases:
            raise InputProblem(f"{path}: line {i + 2}: no phase rows after the timer header")
        return float(m.group(1)), phases
    raise InputProblem(f"{path}: no 'phase timers' table (did the run finish?)")


# ---------------------------------------------------------------------------------------------
# Collection


def collect_run(r, code, path):
    """One row of scaling.csv from a runs.tsv entry and its raw output."""
    ranks, steps = int(r["ranks"]), int(r["steps"])
    size = float(r["size"])
    if code == "elastogen":
        wall, ph = gen4d_timers(path)
        names = ["stencil+svd", "subspace", "sweeps", "halo", "reduction"]
        per = {n: ph.get(n, 0.0) / steps for n in names}
        # The wall clock covers the steps and the last frame and checkpoint (in "io"); the
        # timer table has millisecond resolution, so tiny runs fall back on the phases.
        t = max(wall - ph.get("io", 0.0), sum(ph.get(n, 0.0) for n in names)) / steps
        per["other"] = max(0.0, t - sum(per.values()))
    elif code == "mpm":
        js = load_json(path)
        cases = [c for c in js.get("cases", []) if c.get("case") == "elastic_block"]
        if not cases:
            raise InputProblem(f"{path}: no elastic_block case")
        c = cases[0]
        steps = int(c["substeps"])
        size = float(c["particles"])
        per = {k: v / steps for k, v in c["phase_seconds"].items()}
        t = c["seconds"] / steps
        per["other"] = max(0.0, t - sum(per.values()))
    elif code == "render":
        js = load_json(path)
        cases = [c for c in js.get("cases", []) if c.get("case") == "synthetic"]
        if not cases:
            raise InputProblem(f"{path}: no synthetic case")
        c = cases[0]
        per = dict(c["phases_s"])
        t = c["frame_s"]
        per["other"] = max(0.0, t - sum(per.values()))
    else:
        raise InputProblem(f"runs.tsv: unknown code '{code}'")
    return {
        "code": code, "kind": r["kind"], "ranks": ranks,
        "oversubscribed": int(r["oversubscribed"]), "size": int(size), "unit": r["unit"],
        "steps": steps, "time_per_step_s": t, "throughput_per_s": size / t,
        "load1_start": float(r["load1"]), "load5_start": float(r["load5"]), "phases": per,
    }


def collect(out):
    runs = read_tsv(os.path.join(out, "runs.tsv"))
    rows = []
    for r in runs:
        code = r["code"]
        if code in ("mpi", "checkpoint"):
            continue
        path = os.path.join(out, "raw", r["file"])
        try:
            rows.append(collect_run(r, code, path))
        except (KeyError, TypeError, ValueError) as e:
            raise InputProblem(f"{path}: malformed ({type(e).__name__}: {e})") from None
    for row in rows:
        base = [b for b in rows if b["code"] == row["code"] and b["kind"] == row["kind"]
                and b["ranks"] == 1]
        if base:
            t1, tp, p = base[0]["time_per_step_s"], row["time_per_step_s"], row["ranks"]
            if row["kind"] == "strong":
                row["speedup"], row["efficiency"] = t1 / tp, t1 / tp / p
            else:  # scaled speed-up p T1/Tp, efficiency T1/Tp
                row["speedup"], row["efficiency"] = p * t1 / tp, t1 / tp
        else:
            row["speedup"] = row["efficiency"] = float("nan")
    return rows


def write_scaling_csv(out, rows):
    path = os.path.join(out, "scaling.csv")
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["code", "kind", "ranks", "oversubscribed", "size", "unit", "steps",
                    "time_per_step_s", "throughput_per_s", "speedup", "efficiency",
                    "load1_start", "load5_start", "phase_seconds_per_step"])
        for r in rows:
            w.writerow([r["code"], r["kind"], r["ranks"], r["oversubscribed"], r["size"],
                        r["unit"], r["steps"], f"{r['time_per_step_s']:.6g}",
                        f"{r['throughput_per_s']:.6g}", f"{r['speedup']:.4f}",
                        f"{r['efficiency']:.4f}", r["load1_start"], r["load5_start"],
                        ";".join(f"{k}={v:.6g}" for k, v in r["phases"].items())])
    return path


def collect_mpi(out):
    runs = [r for r in read_tsv(os.path.join(out, "runs.tsv")) if r["code"] == "mpi"]
    res = []
    for r in runs:
        js = load_json(os.path.join(out, "raw", r["file"]))
        for key in ("pingpong", "allreduce_1_double_us", "allgather_exact_sum"):
            if key not in js:
                raise InputProblem(f"{os.path.join(out, 'raw', r['file'])}: no '{key}'")
        res.append({"ranks": int(js["ranks"]), "oversubscribed": int(r["oversubscribed"]),
                    "transport": js["transport"], "load1_start": float(r["load1"]), "json": js})
    if not res:
        raise InputProblem(f"{out}/runs.tsv: no bench_mpi run (needs a rank count >= 2)")
    path = os.path.join(out, "mpi.csv")
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["ranks", "oversubscribed", "transport", "measure", "bytes", "one_way_us",
                    "MBps", "load1_start"])
        for m in res:
            for p in m["json"]["pingpong"]:
                w.writerow([m["ranks"], m["oversubscribed"], m["transport"], "pingpong",
                            p["bytes"], p["one_way_us"], p["MBps"], m["load1_start"]])
            w.writerow([m["ranks"], m["oversubscribed"], m["transport"], "allreduce_1_double",
                        8, m["json"]["allreduce_1_double_us"], "", m["load1_start"]])
            ag = m["json"]["allgather_exact_sum"]
            w.writerow([m["ranks"], m["oversubscribed"], m["transport"], "allgather_exact_sum",
                        ag["bytes_per_rank"], ag["us"], "", m["load1_start"]])
    return res


def collect_checkpoint(out):
    path = os.path.join(out, "checkpoint_runs.tsv")
    if not os.path.isfile(path):
        return None
    rows = []
    for r in read_tsv(path):
        _, every = gen4d_timers(os.path.join(out, "raw", r["log_every_step"]))
        _, final = gen4d_timers(os.path.join(out, "raw", r["log_final_only"]))
        n = int(r["checkpoints"])
        if n < 1:
            raise InputProblem(f"{path}: checkpoints must be >= 1")
        seconds = (every.get("io", 0.0) - final.get("io", 0.0)) / n
        b = int(r["bytes"])
        rows.append({"writer": f"gen4d checkpoint, {r['ranks']} rank(s)", "bytes": b,
                     "seconds": seconds, "MBps": b / seconds / 1e6 if seconds > 0 else float("nan"),
                     "load1_start": float(r["load1"])})
    for r in read_tsv(need(os.path.join(out, "dd.tsv"))):
        b, s = int(r["bytes"]), float(r["seconds"])
        rows.append({"writer": f"dd bs=1M ({r['mode'].replace('_', ' ')})", "bytes": b,
                     "seconds": s, "MBps": b / s / 1e6, "load1_start": float(r["load1"])})
    with open(os.path.join(out, "checkpoint.csv"), "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["writer", "bytes", "seconds", "MBps", "load1_start"])
        for r in rows:
            w.writerow([r["writer"], r["bytes"], f"{r['seconds']:.5f}", f"{r['MBps']:.1f}",
                        r["load1_start"]])
    return rows


# ---------------------------------------------------------------------------------------------
# Model pieces


def fit_transport(pingpong):
    """alpha (s), beta (B/s) of t = alpha + bytes / beta, least squares in relative error."""
    b = np.array([p["bytes"] for p in pingpong], float)
    t = np.array([p["one_way_us"] for p in pingpong], float) * 1e-6
    A = np.stack([1.0 / t, b / t], axis=1)
    (alpha, inv_beta), *_ = np.linalg.lstsq(A, np.ones_like(t), rcond=None)
    alpha = max(alpha, float(t.min()) * 0.5)
    inv_beta = max(inv_beta, 1e-13)
    resid = (alpha + b * inv_beta - t) / t
    return float(alpha), float(1.0 / inv_beta), resid


def process_grid(dims, p):
    """Factorisation of p into a 3D process grid minimising the halo surface (PETSc's DMDA
    picks the same kind of near-cubic split)."""
    best, best_cost = None, None
    for px in range(1, p + 1):
        if p % px:
            continue
        for py in range(1, p // px + 1):
            if (p // px) % py:
                continue
            pz = p // px // py
            g = (px, py, pz)
            loc = [math.ceil(dims[a] / g[a]) for a in range(3)]
            cost = sum((g[a] > 1) * loc[(a + 1) % 3] * loc[(a + 2) % 3] for a in range(3))
            if best_cost is None or cost < best_cost:
                best, best_cost = g, cost
    return best


def halo_shape(dims, p):
    """(ghost nodes, neighbour messages) of the most connected rank of a p-way 3D split of a
    node box `dims`, ghost width 1 and a box stencil (edges and corners included)."""
    g = process_grid(dims, p)
    loc = [math.ceil(dims[a] / g[a]) for a in range(3)]
    faces = [min(2, g[a] - 1) for a in range(3)]
    ghosts = np.prod([loc[a] + faces[a] for a in range(3)]) - np.prod(loc)
    msgs = np.prod([1 + faces[a] for a in range(3)]) - 1
    return float(ghosts), int(msgs), loc


def exchange_time(net, msgs, nbytes):
    return msgs * net["alpha_s"] + nbytes / net["beta_Bps"]


def allgather_time(net, p, words_bytes):
    if p == 1:
        return 0.0
    return net["alpha_coll_s"] * math.ceil(math.log2(p)) + (p - 1) * words_bytes / net["beta_Bps"]


def small_collective(net, p):
    return 0.0 if p == 1 else net["alpha_coll_s"] * math.ceil(math.log2(p))


def fit_overhead(points):
    """Non-negative (o, g) of  measured = o + g x bytes + transport  over (measured, bytes,
    transport) points: o a software cost per call, g a local cost per byte (packing,
    unpacking, waiting that grows with the message). One point or no spread in bytes: g = 0."""
    if not points:
        return 0.0, 0.0
    y = np.array([m - t for m, _, t in points], float)
    b = np.array([q for _, q, _ in points], float)
    if len(points) >= 2 and np.ptp(b) > 0.1 * max(b.max(), 1.0):
        A = np.stack([np.ones_like(b), b], axis=1)
        (o, g), *_ = np.linalg.lstsq(A, y, rcond=None)
        if o < 0:
            o, g = 0.0, float(np.dot(b, y) / np.dot(b, b))
        if g < 0:
            o, g = float(y.mean()), 0.0
        return max(float(o), 0.0), max(float(g), 0.0)
    return max(float(y.mean()), 0.0), 0.0


def fit_per_item(points):
    """Non-negative c of  measured = c x items + transport  over (measured, items, transport)."""
    if not points:
        return 0.0
    num = sum(q * (m - t) for m, q, t in points)
    den = sum(q * q for _, q, _ in points)
    return max(num / den, 0.0) if den > 0 else 0.0


def fit_rate(points):
    """Per-rank rate r of t = work / r over (work, t) points; returns r and the residuals."""
    w = np.array([a for a, _ in points], float)
    t = np.array([b for _, b in points], float)
    c = float(np.dot(w, t) / np.dot(w, w))
    return 1.0 / c, t - c * w


# ElastoGen -----------------------------------------------------------------------------------

def eg_geometry(kind, size, p):
    """Node box of the deck: `size` voxels (a cube; per rank and a bar of p cubes along x when
    weak), one voxel of padding a side."""
    s = round(size ** (1.0 / 3.0))
    if kind == "weak":
        return [s * p + 3, s + 3, s + 3]
    return [s + 3, s + 3, s + 3]


def eg_comm(net, fit, dims, p, outer, sweeps, modes):
    """{halo, reduction} seconds per step; fit: o_halo, g_halo, o_reduction (zeros: transport
    alone)."""
    if p == 1:
        return {"halo": 0.0, "reduction": 0.0}
    gathers, sums = eg_counts(outer, sweeps, modes)
    ghosts, msgs, _ = halo_shape(dims, p)
    nbytes = ELASTOGEN_BYTES_PER_GHOST_NODE * ghosts
    halo = gathers * (fit["o_halo"] + fit["g_halo"] * nbytes + exchange_time(net, msgs, nbytes))
    red = sums * (fit["o_reduction"] + allgather_time(net, p, EXACT_SUM_BYTES)) \
        + ELASTOGEN_ALLREDUCES * small_collective(net, p)
    return {"halo": halo, "reduction": red}


# MPM -----------------------------------------------------------------------------------------

def mpm_dims(particles):
    n = max(4, round((particles / 8.0) ** (1.0 / 3.0)))
    return [n + 13, n + 13, n + 13], n  # bench_mpm pads 6 cells a side


def mpm_crossing(particles, p):
    """Particles a rank sends per substep: 8 a cell in the layer a substep can cross (cfl x dx)
    on the faces it shares, half of them moving outwards (an estimate, see the README)."""
    dims = mpm_dims(particles)[0]
    g = process_grid(dims, p)
    loc = [math.ceil(dims[a] / g[a]) for a in range(3)]
    face_cells = sum(min(2, g[a] - 1) * loc[(a + 1) % 3] * loc[(a + 2) % 3] for a in range(3))
    occupied = min(1.0, particles / 8.0 / float(np.prod(dims)))
    return 8.0 * face_cells * occupied * MPM_CFL * 0.5


def mpm_comm(net, fit, particles, p):
    """{halo, migration, collectives} seconds per substep."""
    if p == 1:
        return {"halo": 0.0, "migration": 0.0, "collectives": 0.0}
    dims = mpm_dims(particles)[0]
    ghosts, msgs, _ = halo_shape(dims, p)
    nbytes = MPM_HALO_BYTES_PER_GHOST_NODE * ghosts
    halo = fit["o_halo"] + fit["g_halo"] * nbytes + exchange_time(net, MPM_HALO_EXCHANGES * msgs, nbytes)
    mig = fit["c_migration"] * particles / p \
        + exchange_time(net, min(p - 1, msgs), MPM_BYTES_PER_PARTICLE * mpm_crossing(particles, p)) \
        + (p - 1) * net["alpha_s"]  # the all-to-all of the row counts
    return {"halo": halo, "migration": mig,
            "collectives": MPM_SMALL_COLLECTIVES * small_collective(net, p)}


# Renderer ------------------------------------------------------------------------------------

def render_comm(net, fit, splats, p):
    """{exchange, gather} seconds per frame."""
    if p == 1:
        return {"exchange": 0.0, "gather": 0.0}
    ex = fit["c_exchange"] * splats / p + (p - 1) * net["alpha_s"] \
        + RENDER_BYTES_PER_SPLAT * splats / p * (p - 1) / p / net["beta_Bps"]
    ga = fit["o_gather"] + (p - 1) * net["alpha_s"] \
        + RENDER_BYTES_PER_PIXEL * RENDER_PIXELS * (p - 1) / p / net["beta_Bps"]
    return {"exchange": ex, "gather": ga}


def read_params(out):
    """The study's settings (params.tsv: key, value)."""
    path = os.path.join(out, "params.tsv")
    p = {r["key"]: r["value"] for r in read_tsv(path)}
    for key in ("size", "eg_outer", "eg_sweeps", "eg_modes"):
        if key not in p:
            raise InputProblem(f"{path}: no '{key}'")
    return p


def rms(x):
    x = np.asarray(x, float)
    return float(np.sqrt(np.mean(x ** 2))) if x.size else 0.0


def fit_models(rows, mpi, params):
    two = [m for m in mpi if m["ranks"] == 2] or mpi
    mj = two[0]["json"]
    alpha, beta, tr_resid = fit_transport(mj["pingpong"])
    allreduce = mj["allreduce_1_double_us"] * 1e-6
    ag = mj["allgather_exact_sum"]["us"] * 1e-6
    ranks_ag = two[0]["ranks"]
    alpha_coll = max(allreduce, 1e-9) / math.ceil(math.log2(ranks_ag))
    local = {"name": f"this machine, {two[0]['transport']}, measured",
             "alpha_s": alpha, "beta_Bps": beta, "alpha_coll_s": alpha_coll,
             "allgather_exact_sum_s": ag}
    model = {"machine": local, "cluster": CLUSTER, "allreduce_1_double_s": allreduce,
             "transport_fit_relative_residuals": [float(x) for x in tr_resid], "codes": {}}
    fair = [r for r in rows if not r["oversubscribed"]]
    multi = [r for r in fair if r["ranks"] >= 2]
    outer, sweeps, modes = (int(params[k]) for k in ("eg_outer", "eg_sweeps", "eg_modes"))

    def comm_residuals(sel, fn, names):
        out = []
        for r in sel:
            c = fn(r)
            out += [r["phases"].get(n, 0.0) - c[n] for n in names]
        return out

    # ElastoGen.
    eg = [r for r in fair if r["code"] == "elastogen"]
    if eg:
        comp = ["stencil+svd", "subspace", "sweeps", "other"]
        rate, resid = fit_rate([(r["size"] / r["ranks"], sum(r["phases"][c] for c in comp)) for r in eg])
        gathers, sums = eg_counts(outer, sweeps, modes)
        zero = {"o_halo": 0.0, "g_halo": 0.0, "o_reduction": 0.0}
        hp, rp = [], []
        egm = [r for r in multi if r["code"] == "elastogen"]
        dims_of = {}
        for r in egm:
            per_rank = r["size"] / (r["ranks"] if r["kind"] == "weak" else 1)
            dims = eg_geometry(r["kind"], per_rank, r["ranks"])
            dims_of[id(r)] = dims
            ghosts, msgs, _ = halo_shape(dims, r["ranks"])
            nb = ELASTOGEN_BYTES_PER_GHOST_NODE * ghosts
            hp.append((r["phases"]["halo"] / gathers, nb, exchange_time(local, msgs, nb)))
            rp.append(((r["phases"]["reduction"] - ELASTOGEN_ALLREDUCES * small_collective(local, r["ranks"])) / sums,
                       0.0, allgather_time(local, r["ranks"], EXACT_SUM_BYTES)))
        o_h, g_h = fit_overhead(hp)
        o_r, _ = fit_overhead(rp)
        fit = {"o_halo": o_h, "g_halo": g_h, "o_reduction": o_r}
        model["codes"]["elastogen"] = {
            "rate_per_rank": rate, "rate_unit": "voxel-steps/s per rank (at the study's loops)",
            "compute_residuals_s": [float(x) for x in resid], "fit": fit,
            "comm_residuals_s": comm_residuals(
                egm, lambda r: eg_comm(local, fit, dims_of[id(r)], r["ranks"], outer, sweeps, modes),
                ["halo", "reduction"]),
            "comm_transport_only_s": [eg_comm(local, zero, dims_of[id(r)], r["ranks"], outer, sweeps, modes)
                                      for r in egm],
            "work_per_step": {"outer": outer, "sweeps": sweeps, "modes": modes,
                              "halo_gathers": gathers, "exact_sums": sums,
                              "allreduces": ELASTOGEN_ALLREDUCES},
            "halo_bytes_per_ghost_node_per_gather": ELASTOGEN_BYTES_PER_GHOST_NODE}
    # MPM.
    mp = [r for r in fair if r["code"] == "mpm"]
    if mp:
        comp = ["material", "p2g", "grid", "g2p", "guard", "other"]
        rate, resid = fit_rate([(r["size"] / r["ranks"], sum(r["phases"].get(c, 0.0) for c in comp)) for r in mp])
        mpm_multi = [r for r in multi if r["code"] == "mpm"]
        hp, mgp = [], []
        for r in mpm_multi:
            p = r["ranks"]
            ghosts, msgs, _ = halo_shape(mpm_dims(r["size"])[0], p)
            nb = MPM_HALO_BYTES_PER_GHOST_NODE * ghosts
            hp.append((r["phases"].get("halo", 0.0), nb, exchange_time(local, MPM_HALO_EXCHANGES * msgs, nb)))
            tr = exchange_time(local, min(p - 1, msgs), MPM_BYTES_PER_PARTICLE * mpm_crossing(r["size"], p)) \
                + (p - 1) * local["alpha_s"]
            mgp.append((r["phases"].get("migration", 0.0), r["size"] / p, tr))
        o_h, g_h = fit_overhead(hp)
        fit = {"o_halo": o_h, "g_halo": g_h, "c_migration": fit_per_item(mgp)}
        model["codes"]["mpm"] = {
            "rate_per_rank": rate, "rate_unit": "particle-substeps/s per rank",
            "compute_residuals_s": [float(x) for x in resid], "fit": fit,
            "comm_residuals_s": comm_residuals(mpm_multi, lambda r: mpm_comm(local, fit, r["size"], r["ranks"]),
                                               ["halo", "migration"]),
            "migration_bytes_per_particle": MPM_BYTES_PER_PARTICLE,
            "halo_bytes_per_ghost_node": MPM_HALO_BYTES_PER_GHOST_NODE,
            "small_collectives_per_substep": MPM_SMALL_COLLECTIVES}
    # Renderer: compute = a splats/p + b pixels/p.
    rd = [r for r in fair if r["code"] == "render"]
    if rd:
        comp = ["preprocess", "sort", "blend", "other"]
        A = np.array([[r["size"] / r["ranks"], RENDER_PIXELS / r["ranks"]] for r in rd], float)
        t = np.array([sum(r["phases"].get(c, 0.0) for c in comp) for r in rd], float)
        coef, *_ = np.linalg.lstsq(A, t, rcond=None)
        if coef[1] < 0 or coef[0] <= 0:  # not separable from these points: splats only
            coef = np.array([float(np.dot(A[:, 0], t) / np.dot(A[:, 0], A[:, 0])), 0.0])
        resid = t - A @ coef
        rmulti = [r for r in multi if r["code"] == "render"]
        zero = {"c_exchange": 0.0, "o_gather": 0.0}
        ep = [(r["phases"].get("exchange", 0.0), r["size"] / r["ranks"],
               render_comm(local, zero, r["size"], r["ranks"])["exchange"]) for r in rmulti]
        gp = [(r["phases"].get("gather", 0.0), 0.0, render_comm(local, zero, r["size"], r["ranks"])["gather"])
              for r in rmulti]
        fit = {"c_exchange": fit_per_item(ep), "o_gather": fit_overhead(gp)[0]}
        model["codes"]["render"] = {
            "seconds_per_splat_per_rank": float(coef[0]),
            "seconds_per_pixel_per_rank": float(coef[1]),
            "rate_per_rank": 1.0 / coef[0], "rate_unit": "splats/s per rank (pixel term apart)",
            "compute_residuals_s": [float(x) for x in resid], "fit": fit,
            "comm_residuals_s": comm_residuals(rmulti, lambda r: render_comm(local, fit, r["size"], r["ranks"]),
                                               ["exchange", "gather"]),
            "bytes_per_splat": RENDER_BYTES_PER_SPLAT, "bytes_per_pixel": RENDER_BYTES_PER_PIXEL}
    return model


def project(model, net_key, transport_only=False):
    """Projected compute and communication per step on network `net_key` ("cluster" or
    "machine"); transport_only drops the fitted software overheads (only the counted messages
    and bytes on the network remain)."""
    net = model[net_key]
    label = net_key + ("_transport_only" if transport_only else "")
    out = []
    for code, m0 in model["codes"].items():
        m = dict(m0)
        if transport_only:
            m["fit"] = {k: 0.0 for k in m0["fit"]}
        for kind in ("strong", "weak"):
            n0 = PROJECTION[code][kind]
            for p in RANKS:
                n = n0 if kind == "strong" else n0 * p
                if code == "elastogen":
                    w = m["work_per_step"]
                    comp = n / p / m["rate_per_rank"]
                    comm = eg_comm(net, m["fit"], eg_geometry(kind, n0, p), p, w["outer"],
                                   w["sweeps"], w["modes"])
                elif code == "mpm":
                    comp = n / p / m["rate_per_rank"]
                    comm = mpm_comm(net, m["fit"], n, p)
                else:
                    comp = (m["seconds_per_splat_per_rank"] * n / p
                            + m["seconds_per_pixel_per_rank"] * RENDER_PIXELS / p)
                    comm = render_comm(net, m["fit"], n, p)
                tc = sum(comm.values())
                out.append({"network": label, "code": code, "kind": kind, "ranks": p,
                            "size": n, "unit": PROJECTION[code]["unit"], "compute_s": comp,
                            "comm_s": tc, "time_per_step_s": comp + tc,
                            "comm_bound": int(tc > comp),
                            "comm_parts": ";".join(f"{a}={b:.3g}" for a, b in comm.items())})
    return out


def check_counts(out, params):
    """Per-step communication counted by the PMPI interposer (counts.tsv, 2 ranks, runs of 2 and
    4 steps) against the counts the model takes from the code; None without counts.tsv."""
    path = os.path.join(out, "counts.tsv")
    if not os.path.isfile(path):
        return None
    rows = read_tsv(path)
    fields = ["allgather", "allreduce", "alltoall", "alltoallv", "other", "p2p_messages",
              "p2p_bytes"]
    res = {}
    for code in sorted({r["code"] for r in rows}):
        by = {}
        for r in rows:
            if r["code"] == code:
                by.setdefault(int(r["steps"]), []).append(r)
        if len(by) != 2:
            raise InputProblem(f"{path}: {code} needs runs at two step counts")
        (s0, a), (s1, b) = sorted(by.items())
        per = {f: max((float(y[f]) - float(x[f])) / (s1 - s0)
                      for x, y in zip(sorted(a, key=lambda r: r["rank"]),
                                      sorted(b, key=lambda r: r["rank"]))) for f in fields}
        entry = {"measured_per_step": per}
        if code == "elastogen":
            outer, sweeps, modes = (int(params[k]) for k in ("eg_outer", "eg_sweeps", "eg_modes"))
            gathers, sums = eg_counts(outer, sweeps, modes)
            nx, ny, nz = (int(v) for v in a[0]["cells"].split("x"))
            dims = [nx + 3, ny + 3, nz + 3]
            ghosts, msgs, _ = halo_shape(dims, 2)
            entry["model_per_step"] = {"allgather": sums, "allreduce": ELASTOGEN_ALLREDUCES,
                                       "p2p_messages": gathers * msgs,
                                       "p2p_bytes": gathers * ELASTOGEN_BYTES_PER_GHOST_NODE * ghosts}
        elif code == "mpm":
            dims = mpm_dims(float(a[0]["cells"]))[0]
            ghosts, msgs, _ = halo_shape(dims, 2)
            entry["model_per_step"] = {
                "allreduce": MPM_SMALL_COLLECTIVES, "alltoall": 1, "alltoallv": 1,
                "p2p_messages": MPM_HALO_EXCHANGES * msgs,
                "p2p_bytes": MPM_HALO_BYTES_PER_GHOST_NODE * ghosts}
            # bench_mpm's steps run once per case.
            entry["measured_per_step"] = {k: v / MPM_BENCH_CASES for k, v in per.items()}
        res[code] = entry
    return res


# ---------------------------------------------------------------------------------------------
# Plots


def plots(out, rows, mpi, proj):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    codes = sorted({r["code"] for r in rows})
    colors = {"elastogen": "C0", "mpm": "C1", "render": "C2"}
    for what, fname in (("speedup", "speedup.png"), ("efficiency", "efficiency.png")):
        fig, axes = plt.subplots(1, 2, figsize=(10, 4))
        for ax, kind in zip(axes, ("strong", "weak")):
            for code in codes:
                sel = sorted((r for r in rows if r["code"] == code and r["kind"] == kind),
                             key=lambda r: r["ranks"])
                if not sel:
                    continue
                x = [r["ranks"] for r in sel]
                y = [r[what] for r in sel]
                ax.plot(x, y, "-", color=colors.get(code), label=code)
                for r in sel:
                    ax.plot(r["ranks"], r[what], "o", color=colors.get(code),
                            mfc="white" if r["oversubscribed"] else colors.get(code))
            xs = sorted({r["ranks"] for r in rows})
            if what == "speedup":
                ax.plot(xs, xs, "k:", label="ideal")
            else:
                ax.axhline(1.0, color="k", ls=":", label="ideal")
            ax.set_xscale("log", base=2)
            ax.set_xlabel("ranks (hollow: oversubscribed, more ranks than cores)")
            ax.set_title(f"{kind} scaling: {'scaled ' if kind == 'weak' and what == 'speedup' else ''}{what}")
            ax.grid(alpha=0.3)
            ax.legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(os.path.join(out, fname), dpi=110)
        plt.close(fig)

    sets = [(c, k) for c in codes for k in ("strong", "weak")
            if any(r["code"] == c and r["kind"] == k for r in rows)]
    fig, axes = plt.subplots(1, len(sets), figsize=(3.2 * len(sets), 4), squeeze=False)
    for ax, (code, kind) in zip(axes[0], sets):
        sel = sorted((r for r in rows if r["code"] == code and r["kind"] == kind),
                     key=lambda r: r["ranks"])
        names = list(dict.fromkeys(n for r in sel for n in r["phases"]))
        bottom = np.zeros(len(sel))
        for i, name in enumerate(names):
            vals = np.array([r["phases"].get(name, 0.0) for r in sel])
            ax.bar(range(len(sel)), vals, bottom=bottom, label=name, color=f"C{i % 10}")
            bottom += vals
        ax.set_ylim(0, 1.25 * max(bottom.max(), 1e-9))
        ax.set_xticks(range(len(sel)))
        ax.set_xticklabels([f"{r['ranks']}{'*' if r['oversubscribed'] else ''}" for r in sel])
        ax.set_xlabel("ranks (* oversubscribed)")
        ax.set_ylabel("s per step")
        ax.set_title(f"{code} {kind}", fontsize=9)
        ax.legend(fontsize=6)
    fig.tight_layout()
    fig.savefig(os.path.join(out, "phases.png"), dpi=110)
    plt.close(fig)

    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    for m in mpi:
        pp = m["json"]["pingpong"]
        lab = f"{m['ranks']} ranks{' (oversubscribed)' if m['oversubscribed'] else ''}"
        axes[0].loglog([p["bytes"] for p in pp], [p["one_way_us"] for p in pp], "o-", label=lab)
        axes[1].semilogx([p["bytes"] for p in pp], [p["MBps"] for p in pp], "o-", label=lab)
    axes[0].set_ylabel("one-way time (us)")
    axes[1].set_ylabel("bandwidth (MB/s)")
    for ax in axes:
        ax.set_xlabel("message bytes (ping-pong, ranks 0 and 1, shared memory)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(out, "mpi.png"), dpi=110)
    plt.close(fig)

    pcodes = sorted({p["code"] for p in proj})
    fig, axes = plt.subplots(2, len(pcodes), figsize=(4.2 * len(pcodes), 7), squeeze=False)
    for j, code in enumerate(pcodes):
        for i, kind in enumerate(("strong", "weak")):
            ax = axes[i][j]
            for net, ls in (("cluster", "-"), ("cluster_transport_only", ":"), ("machine", "--")):
                sel = [p for p in proj if p["code"] == code and p["kind"] == kind and p["network"] == net]
                x = [p["ranks"] for p in sel]
                ax.loglog(x, [p["compute_s"] for p in sel], ls, color="C0",
                          label=f"compute ({net})")
                multi = [p for p in sel if p["ranks"] >= 2]  # no communication at 1 rank
                ax.loglog([p["ranks"] for p in multi], [p["comm_s"] for p in multi], ls, color="C3",
                          label=f"comm ({net})")
                cross = [p["ranks"] for p in sel if p["comm_bound"]]
                if cross and net == "cluster":
                    ax.axvline(cross[0], color="C3", alpha=0.3, lw=6)
            u = PROJECTION[code]
            ax.set_title(f"{code} {kind}: {u[kind]:.3g} {u['unit']}{' per rank' if kind == 'weak' else ''}",
                         fontsize=9)
            ax.set_xlabel("ranks (shaded: communication-bound, cluster)")
            ax.set_ylabel("s per step")
            ax.grid(alpha=0.3)
            ax.legend(fontsize=6)
    fig.tight_layout()
    fig.savefig(os.path.join(out, "projection.png"), dpi=110)
    plt.close(fig)


# ---------------------------------------------------------------------------------------------


def main(argv):
    if len(argv) != 2:
        print("usage: model.py OUT_DIR (the folder jobs/scaling/study.sh wrote)", file=sys.stderr)
        return 2
    out = argv[1]
    rows = collect(out)
    if not rows:
        raise InputProblem(f"{out}/runs.tsv: no code runs")
    write_scaling_csv(out, rows)
    mpi = collect_mpi(out)
    ck = collect_checkpoint(out)
    params = read_params(out)
    model = fit_models(rows, mpi, params)
    model["counts_check_2_ranks"] = check_counts(out, params)
    proj = project(model, "cluster") + project(model, "cluster", transport_only=True) \
        + project(model, "machine")
    crossover = {}
    for net in ("cluster", "cluster_transport_only", "machine"):
        crossover[net] = {}
        for code in model["codes"]:
            for kind in ("strong", "weak"):
                sel = [p for p in proj if p["code"] == code and p["kind"] == kind and p["network"] == net]
                first = [p["ranks"] for p in sel if p["comm_bound"]]
                crossover[net][f"{code}/{kind}"] = first[0] if first else None
    model["comm_bound_from_ranks"] = crossover
    model["projection_sizes"] = PROJECTION
    with open(os.path.join(out, "model.json"), "w") as f:
        json.dump(model, f, indent=2)
    with open(os.path.join(out, "projection.csv"), "w", newline="") as f:
        w = csv.writer(f)
        keys = ["network", "code", "kind", "ranks", "size", "unit", "compute_s", "comm_s",
                "time_per_step_s", "comm_bound", "comm_parts"]
        w.writerow(keys)
        for p in proj:
            w.writerow([f"{p[k]:.5g}" if isinstance(p[k], float) else p[k] for k in keys])
    plots(out, rows, mpi, proj)

    # Tables.
    print("\nmeasured (OMP_NUM_THREADS=1; * = oversubscribed)")
    print(f"{'code':<10}{'kind':<7}{'ranks':>6}{'size':>10} {'unit':<10}{'s/step':>10}{'rate/s':>11}"
          f"{'speed-up':>9}{'eff.':>7}{'load1':>7}  phases s/step")
    for r in rows:
        ph = " ".join(f"{k}={v:.3g}" for k, v in r["phases"].items() if v > 0)
        print(f"{r['code']:<10}{r['kind']:<7}{str(r['ranks']) + ('*' if r['oversubscribed'] else ''):>6}"
              f"{r['size']:>10} {r['unit']:<10}{r['time_per_step_s']:>10.4g}{r['throughput_per_s']:>11.4g}"
              f"{r['speedup']:>9.2f}{r['efficiency']:>7.2f}{r['load1_start']:>7.2f}  {ph}")
    print("\nMPI (shared memory on this machine)")
    for m in mpi:
        pp = {p["bytes"]: p for p in m["json"]["pingpong"]}
        small = min(pp)
        big = max(pp)
        print(f"  {m['ranks']} ranks{' (oversubscribed)' if m['oversubscribed'] else ''}: "
              f"latency {pp[small]['one_way_us']:.2f} us ({small} B), bandwidth "
              f"{pp[big]['MBps']:.0f} MB/s ({big} B), best {max(p['MBps'] for p in pp.values()):.0f} MB/s; "
              f"allreduce(1 double) {m['json']['allreduce_1_double_us']:.2f} us; exact-sum allgather "
              f"{m['json']['allgather_exact_sum']['us']:.2f} us")
    mm = model["machine"]
    print(f"  fit t = alpha + bytes/beta: alpha {mm['alpha_s'] * 1e6:.2f} us, beta {mm['beta_Bps'] / 1e9:.2f} GB/s")
    if ck:
        print("\ncheckpoint write vs dd (same folder)")
        for r in ck:
            print(f"  {r['writer']:<34}{r['bytes'] / 1e6:>9.1f} MB {r['seconds']:>9.3f} s {r['MBps']:>9.1f} MB/s")
    if model["counts_check_2_ranks"]:
        print("\ncommunication per step at 2 ranks: counted in a run (PMPI) / taken from the code")
        for code, e in model["counts_check_2_ranks"].items():
            print(f"  {code}: " + "; ".join(
                f"{k} {e['measured_per_step'].get(k, float('nan')):.6g} / {v:.6g}"
                for k, v in e["model_per_step"].items()))
    print("\nmodel fit")
    for code, m in model["codes"].items():
        res = np.array(m["compute_residuals_s"])
        print(f"  {code}: {m['rate_per_rank']:.4g} {m['rate_unit']}; fitted "
              + ", ".join(f"{a} {b:.3g}" for a, b in m["fit"].items())
              + f"; residuals rms: compute {rms(res):.3g} s, comm {rms(m['comm_residuals_s']):.3g} s")
    print(f"\nprojection on the {CLUSTER['name']}: alpha {CLUSTER['alpha_s'] * 1e6:.1f} us, "
          f"beta {CLUSTER['beta_Bps'] / 1e9:.0f} GB/s, collectives {CLUSTER['alpha_coll_s'] * 1e6:.1f} us x log2 p")
    print("(comm: with the overheads fitted on this machine / transport only: the counted messages "
          "and bytes alone)")
    print(f"{'code':<10}{'kind':<7}{'ranks':>6}{'size':>12}{'compute s':>11}{'comm s':>11}"
          f"{'total s':>11}  bound   {'comm s':>10}  bound (transport only)")
    bare = {(p["code"], p["kind"], p["ranks"]): p for p in proj if p["network"] == "cluster_transport_only"}
    for p in proj:
        if p["network"] != "cluster":
            continue
        q = bare[(p["code"], p["kind"], p["ranks"])]
        print(f"{p['code']:<10}{p['kind']:<7}{p['ranks']:>6}{p['size']:>12.4g}{p['compute_s']:>11.4g}"
              f"{p['comm_s']:>11.4g}{p['time_per_step_s']:>11.4g}  {'COMM   ' if p['comm_bound'] else 'compute'}"
              f" {q['comm_s']:>10.4g}  {'COMM' if q['comm_bound'] else 'compute'}")
    for net, c in crossover.items():
        print(f"\ncommunication-bound from ({net}):",
              ", ".join(f"{k} {'p=' + str(v) if v else 'never up to 1024'}" for k, v in c.items()))
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main(sys.argv))
    except InputProblem as e:
        print(f"model.py: {e}", file=sys.stderr)
        sys.exit(1)
    except (KeyError, ValueError, TypeError) as e:
        print(f"model.py: malformed input ({type(e).__name__}: {e})", file=sys.stderr)
        sys.exit(1)

#!/usr/bin/env python3
"""Markdown tables of a scaling study (jobs/scaling/study.sh --out DIR, after model.py DIR).

    /usr/bin/python3 jobs/scaling/tables.py DIR                       # print every region
    /usr/bin/python3 jobs/scaling/tables.py DIR --update jobs/scaling/README.md
    /usr/bin/python3 jobs/scaling/tables.py DIR --machine "2-core AMD EPYC VM, 24 GiB" --update ...

With --update, the text between `<!-- tables:NAME begin -->` and `<!-- tables:NAME end -->` in the
file is replaced by the region NAME (every pair found must be a known region; text outside the
markers is kept). Reads scaling.csv, runs.tsv, mpi.csv, checkpoint.csv, params.tsv,
uptime_start.txt / uptime_end.txt, model.json and projection.csv; a missing optional file leaves
its region with a one-line note. The machine's CPU is taken from --machine, else from DIR/lscpu.txt
(`lscpu > DIR/lscpu.txt`, its "Model name") if present, else omitted.
Whether the machine was quiet is decided from the 1-minute load average recorded at the runs'
starts: max > LOAD_QUIET (2.5) => the "not quiet" paragraphs, else one-line quiet statements.
"""
import argparse
import csv
import datetime
import decimal
import json
import math
import os
import re
import sys

# The 1-minute load average at a run's start includes the study's own previous runs (up to its
# ranks, 2 on this 2-core machine), so "quiet" is judged above that: other work adds to it.
LOAD_QUIET = 2.5
BENCH_README = "[../../drivers/bench/README.md](../../drivers/bench/README.md)"


# ---------------------------------------------------------------- number formatting

def fx(v, d):
    """v with d decimals, halves rounded up as written in the CSV (0.9355 -> 0.936, 9.25 -> 9.3)."""
    q = decimal.Decimal(str(v)).quantize(decimal.Decimal(1).scaleb(-d), rounding=decimal.ROUND_HALF_UP)
    return f"{q:f}"


def sig(v, n=3):
    """v with n significant digits, trailing zeros kept (0.50, 1.30, 169, 16.6)."""
    v = float(v)
    if v == 0:
        return "0"
    d = math.floor(math.log10(abs(v)))
    # rounding may carry into the next decade (0.0999 -> 0.100)
    if round(abs(v), max(0, n - 1 - d)) >= 10 ** (d + 1):
        d += 1
    return fx(v, max(0, n - 1 - d))


def sci(v, n=3):
    """6.84e4 style."""
    m, e = f"{float(v):.{n - 1}e}".split("e")
    return f"{m}e{int(e)}"


def commas(v):
    return f"{int(round(float(v))):,}"


def dur(s, n=3):
    """Seconds with a unit: 2.62 us, 4.61 ms, 0.39 s."""
    s = float(s)
    if s == 0:
        return "0 s"
    for unit, f, low in (("s", 1.0, 0.1), ("ms", 1e-3, 1e-3), ("us", 1e-6, 0)):
        if abs(s) >= low:
            return f"{sig(s / f, n)} {unit}"


def dur_us(s, n=3):
    """MPI times: us below 1 ms, else ms (169 us, 4.61 ms, 0.499 us)."""
    return f"{sig(s * 1e3, n)} ms" if s >= 1e-3 else f"{sig(s * 1e6, n)} us"


def rate(bps):
    """Bytes/s as MB/s (below 1 GB/s, no decimals) or GB/s (2 decimals)."""
    mb = float(bps) / 1e6
    return f"{mb / 1e3:.2f} GB/s" if mb >= 1000 else f"{mb:.0f} MB/s"


def phase_value(v):
    if v >= 1:
        return sig(v, 3)
    if round(v, 3) > 0:
        return fx(v, 3)
    return f"{v:.1g}"


# ---------------------------------------------------------------- reading

def read_csv(path, delim=","):
    with open(path, newline="") as f:
        return list(csv.DictReader(f, delimiter=delim))


class Study:
    def __init__(self, out, machine=None):
        self.out = out
        p = lambda name: os.path.join(out, name)  # noqa: E731
        self.has = lambda name: os.path.exists(p(name))  # noqa: E731
        self.rows = read_csv(p("scaling.csv"))
        self.runs = read_csv(p("runs.tsv"), "\t") if self.has("runs.tsv") else []
        self.mpi = read_csv(p("mpi.csv")) if self.has("mpi.csv") else []
        self.ckpt = read_csv(p("checkpoint.csv")) if self.has("checkpoint.csv") else []
        self.proj = read_csv(p("projection.csv")) if self.has("projection.csv") else []
        self.model = json.load(open(p("model.json"))) if self.has("model.json") else None
        self.params = {}
        if self.has("params.tsv"):
            for r in read_csv(p("params.tsv"), "\t"):
                self.params[r["key"]] = r["value"]
        self.cores = int(self.params.get("cores", 0)) or None
        self.machine = machine
        if not self.machine and self.has("lscpu.txt"):
            for line in open(p("lscpu.txt")):
                if line.lower().startswith("model name"):
                    self.machine = line.split(":", 1)[1].strip()
                    break
        # 1-minute load average at every run's start (runs.tsv has the MPI and checkpoint runs too)
        src = self.runs if self.runs else self.rows
        key = "load1" if self.runs else "load1_start"
        self.loads = [float(r[key]) for r in src if r.get(key)]
        for r in self.mpi + self.ckpt:
            if not self.runs and r.get("load1_start"):
                self.loads.append(float(r["load1_start"]))
        self.quiet = bool(self.loads) and max(self.loads) <= LOAD_QUIET

    def times(self):
        """(start, end) datetimes of the study from its uptime files, or None."""
        res = []
        for name in ("uptime_start.txt", "uptime_end.txt"):
            if not self.has(name):
                return None
            path = os.path.join(self.out, name)
            mtime = datetime.datetime.fromtimestamp(os.path.getmtime(path), datetime.timezone.utc)
            m = re.match(r"\s*(\d\d):(\d\d):(\d\d)", open(path).read())
            if m:  # uptime prints local time; trust it only when it agrees with the mtime (UTC)
                t = mtime.replace(hour=int(m[1]), minute=int(m[2]), second=int(m[3]), microsecond=0)
                if abs((t - mtime).total_seconds()) < 120:
                    mtime = t
            res.append(mtime)
        return tuple(res)

    def command(self):
        args = ["jobs/scaling/study.sh", "--out", "scaling-out"]
        if self.params.get("size", "full") != "full":
            args += ["--size", self.params["size"]]
        ranks = sorted({int(r["ranks"]) for r in self.rows})
        if ranks != [1, 2, 4]:
            args += ["--ranks", '"' + " ".join(map(str, ranks)) + '"']
        codes = []
        for c in ("elastogen", "mpm", "render"):
            if any(r["code"] == c for r in self.rows):
                codes.append(c)
        if codes != ["elastogen", "mpm", "render"]:
            args += ["--codes", '"' + " ".join(codes) + '"']
        if not self.ckpt:
            args += ["--no-checkpoint"]
        return " ".join(args)

    def load_range(self):
        if not self.loads:
            return "not recorded"
        lo, hi = min(self.loads), max(self.loads)
        a, b = fx(lo, 1), fx(hi, 1)
        return a if a == b else f"{a} - {b}"


# ---------------------------------------------------------------- regions

def region_header(s):
    parts = [f"Command: `{s.command()}`"]
    t = s.times()
    if t:
        a, b = t
        wall = int(round((b - a).total_seconds()))
        parts.append(f"run {a:%Y-%m-%d} {a:%H:%M} - {b:%H:%M} UTC ({wall // 60} min {wall % 60:02d} s wall)")
    mach = []
    if s.cores:
        mach.append(f"{s.cores} cores")
    if s.machine:
        mach.append(s.machine)
    if mach:
        parts.append("on " + ", ".join(mach))
    parts.append(f"load average (1 min) at the runs' starts {s.load_range()}"
                 f" ({'quiet' if s.quiet else 'disturbed'})")
    return wrap("; ".join(parts) + ". Tables generated by "
            "`/usr/bin/python3 jobs/scaling/tables.py scaling-out"
            " --update jobs/scaling/README.md`.")


def strong_row(s, code, p):
    for r in s.rows:
        if r["code"] == code and r["kind"] == "strong" and int(r["ranks"]) == p:
            return r
    return None


def region_load(s):
    lr = s.load_range()
    if s.quiet:
        return wrap(f"**Quiet machine**: the 1-minute load average at the runs' starts was {lr} "
                f"(at most {LOAD_QUIET}), so the compute and communication phases below are "
                "the codes' own.")
    cores = f"{s.cores} cores" if s.cores else "the node's cores"
    slow = [name for code, name in (("elastogen", "ElastoGen"), ("mpm", "MPM"), ("render", "renderer"))
            if strong_row(s, code, 2) and float(strong_row(s, code, 2)["speedup"]) < 1]
    slower = ""
    if slow:
        names = slow[0] if len(slow) == 1 else ", ".join(slow[:-1]) + " and " + slow[-1]
        slower = (" and makes the 2-rank " + names + " run"
                  + ("s" if len(slow) > 1 else "") + " slower than 1 rank")
    mpm1 = strong_row(s, "mpm", 1)
    mpm = ""
    if mpm1:
        mpm = (f" (compare MPM's 1-rank rate here, {sci(mpm1['throughput_per_s'], 2)} particle-substeps/s, "
               f"with the quiet-machine rate per rank in {BENCH_README})")
    return wrap(f"**The machine was not quiet.** The 1-minute load average at the starts of the study's "
            f"runs was {lr} on {cores} (recorded per row; the threshold for quiet is {LOAD_QUIET}), "
            "so these numbers are **disturbed**: with more runnable processes than cores, a rank "
            "is often descheduled, and its partner waits at every halo exchange and global sum. "
            f"That waiting lands in the `halo` and `reduction` phases{slower}. The compute phases "
            f"are slowed too{mpm}. Rerun on a quiet machine before using the numbers; the command "
            "is the same.")


CODE_ORDER = {"elastogen": 0, "mpm": 1, "render": 2}
KIND_ORDER = {"strong": 0, "weak": 1}
COMM_PHASES = {"halo", "reduction"}


def phases_text(r):
    t = float(r["time_per_step_s"])
    out = []
    for item in r["phase_seconds_per_step"].split(";"):
        if "=" not in item:
            continue
        name, v = item.split("=", 1)
        v = float(v)
        if v <= 0 or (v < 0.005 * t and name not in COMM_PHASES) or v < 1e-5:
            continue
        out.append(f"{name} {phase_value(v)}")
    return ", ".join(out)


def region_scaling(s):
    rows = sorted(s.rows, key=lambda r: (CODE_ORDER.get(r["code"], 9), r["code"],
                                         KIND_ORDER.get(r["kind"], 9), int(r["ranks"])))
    lines = ["| code | kind | ranks | size | s / step | rate / s | speed-up | eff. | load1 | phases, s per step |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    seen = set()
    for r in rows:
        size = commas(r["size"])
        if r["code"] not in seen:
            size += " " + r["unit"]
            seen.add(r["code"])
        ranks = r["ranks"] + ("*" if r["oversubscribed"] == "1" else "")
        lines.append(f"| {r['code']} | {r['kind']} | {ranks} | {size} | {fx(r['time_per_step_s'], 3)} "
                     f"| {sci(r['throughput_per_s'])} | {fx(r['speedup'], 2)} | {fx(r['efficiency'], 2)} "
                     f"| {fx(r['load1_start'], 1)} | {phases_text(r)} |")
    lines.append("")
    over = sorted({int(r["ranks"]) for r in s.rows if r["oversubscribed"] == "1"})
    notes = []
    if over:
        on = f" on {s.cores} cores" if s.cores else ""
        notes.append(f"`*` oversubscribed ({', '.join(map(str, over))} ranks{on}).")
        if not s.quiet:
            notes.append("The oversubscribed rows can beat the 2-rank ones here because more ranks get "
                         "a larger share of the contended cores; they say nothing about scaling.")
        else:
            notes.append("Oversubscribed rows say nothing about scaling.")
    o, sw = s.params.get("eg_outer", "3"), s.params.get("eg_sweeps", "40")
    notes.append(f"Rates: voxel-steps/s (ElastoGen, at {o} x {sw} sweeps a step), "
                 "particle-substeps/s, splats/s.")
    lines.append(wrap(" ".join(notes)))
    return "\n".join(lines)


def region_mpi(s):
    if not s.mpi:
        return "(no `mpi.csv` in this study)"
    sizes = [(8, "8 B one-way"), (1024, "1 KiB"), (65536, "64 KiB"), (1 << 20, "1 MiB"), (1 << 24, "16 MiB")]
    ag = [r for r in s.mpi if r["measure"] == "allgather_exact_sum"]
    agb = int(ag[0]["bytes"]) if ag else 544
    head = ["ranks"] + [h for _, h in sizes] + ["`MPI_Allreduce` 1 double",
                                                f"exact-sum `MPI_Allgather` ({agb} B / rank)"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for p in sorted({int(r["ranks"]) for r in s.mpi}):
        rs = [r for r in s.mpi if int(r["ranks"]) == p]
        over = rs[0]["oversubscribed"] == "1"
        cells = [f"{p}{'*' if over else ''}"]
        for b, _ in sizes:
            m = [r for r in rs if r["measure"] == "pingpong" and int(r["bytes"]) == b]
            if not m:
                cells.append("-")
                continue
            us = float(m[0]["one_way_us"])
            c = dur_us(us * 1e-6)
            if b >= 1024:
                c += f" ({rate(b / (us * 1e-6))})"
            cells.append(c)
        for meas in ("allreduce_1_double", "allgather_exact_sum"):
            m = [r for r in rs if r["measure"] == meas]
            cells.append(dur_us(float(m[0]["one_way_us"]) * 1e-6) if m else "-")
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def region_mpi_fit(s):
    if not s.model:
        return "(no `model.json`: run `model.py` on the study)"
    m = s.model["machine"]
    return wrap(f"The fit t = alpha + bytes / beta over all sizes (relative least squares) gives "
            f"alpha = {dur(m['alpha_s'])} and beta = {m['beta_Bps'] / 1e9:.2f} GB/s.")


def region_checkpoint(s):
    if not s.ckpt:
        return "(no checkpoint part in this study: `--no-checkpoint`)"
    lines = ["| writer | bytes | seconds | MB/s | load1 |", "|---|---|---|---|---|"]
    for r in s.ckpt:
        w = r["writer"]
        m = re.match(r"gen4d checkpoint, (\d+) rank", w)
        if m:
            n = int(m[1])
            w = f"`gen4d run` checkpoint, {n} rank" + ("s (collective MPI-IO)" if n > 1 else "")
        elif "page cache" in w:
            w = "`dd bs=1M`, page cache"
        elif "fdatasync" in w:
            w = "`dd bs=1M conv=fdatasync`"
        lines.append(f"| {w} | {commas(r['bytes'])} | {fx(r['seconds'], 3)} | {sig(r['MBps'])} "
                     f"| {fx(r['load1_start'], 1)} |")
    return "\n".join(lines)


def region_checkpoint_ratio(s):
    if not s.ckpt:
        return ""
    gen = [(re.search(r"(\d+) rank", r["writer"]), float(r["MBps"])) for r in s.ckpt
           if r["writer"].startswith("gen4d")]
    gen = [(int(m[1]), v) for m, v in gen if m]
    dd = {("cache" if "page cache" in r["writer"] else "sync"): float(r["MBps"])
          for r in s.ckpt if r["writer"].startswith("dd")}
    if not gen or "cache" not in dd:
        return ""
    pc = lambda v, ref: f"{100 * v / ref:.0f} %"  # noqa: E731
    a = " and ".join(f"{pc(v, dd['cache'])} ({n} rank{'s' if n > 1 else ''})" for n, v in gen)
    txt = f"Against dd through the page cache, the checkpoint reaches **{a}** of its rate"
    if "sync" in dd:
        txt += ", " + " / ".join(pc(v, dd["sync"]) for _, v in gen) + " of dd with `fdatasync`"
    return wrap(txt + ".")


def region_counts(s):
    if not s.model or "counts_check_2_ranks" not in s.model:
        return None  # leave as is
    cc = s.model["counts_check_2_ranks"]
    o, sw = int(s.params.get("eg_outer", 3)), int(s.params.get("eg_sweeps", 40))
    modes = s.params.get("eg_modes", "6")
    lines = ["| code | what | counted (PMPI) | from the code |", "|---|---|---|---|"]
    cells = {}
    if s.has("counts.tsv"):
        for r in read_csv(os.path.join(s.out, "counts.tsv"), "\t"):
            cells[r["code"]] = r["cells"]
    n = lambda v: commas(v)  # noqa: E731
    if "elastogen" in cc:
        m, c = cc["elastogen"]["measured_per_step"], cc["elastogen"]["model_per_step"]
        gathers = int(c["p2p_messages"])
        ghost = c["p2p_bytes"] / (gathers * 24) if gathers else 0
        side = int(round(math.sqrt(ghost))) if ghost else 0
        ghost_s = f"{side} x {side}" if side * side == round(ghost) else n(ghost)
        lines += [
            f"| ElastoGen, {cells.get('elastogen', '?')} voxels, {o} outer x {sw} sweeps, {modes} modes "
            f"| exact sums (`MPI_Allgather`) | {n(m['allgather'])} "
            f"| 4 + {o} x (4 + ceil({sw}/8) + 1) = {n(c['allgather'])} |",
            f"| | `MPI_Allreduce` (the step's signal check) | {n(m['allreduce'])} | {n(c['allreduce'])} |",
            f"| | halo messages (per rank) | {n(m['p2p_messages'])} "
            f"| 2 + {o} x ({sw} + 2) = {n(c['p2p_messages'])} gathers x 1 neighbour |",
            f"| | halo bytes (per rank) | {n(m['p2p_bytes'])} | {n(gathers)} x 24 B x {ghost_s} ghost nodes |",
        ]
    if "mpm" in cc:
        m, c = cc["mpm"]["measured_per_step"], cc["mpm"]["model_per_step"]
        parts = f"{cells.get('mpm', '?')}"
        try:
            parts = f"{int(parts) // 1000}k"
        except ValueError:
            pass
        trio = lambda d: " / ".join(n(d.get(k, 0)) for k in ("allreduce", "alltoall", "alltoallv"))  # noqa: E731
        msgs = int(c["p2p_messages"])
        ghost = c["p2p_bytes"] / 64 / max(msgs // 2, 1) if msgs else 0
        lines += [
            f"| MPM, {parts} particles (per substep) | `MPI_Allreduce` / `MPI_Alltoall` / `MPI_Alltoallv` "
            f"| {trio(m)} | {trio(c)} |",
            f"| | halo messages / bytes (per rank) | {n(m['p2p_messages'])} / {n(m['p2p_bytes'])} "
            f"| {n(msgs)} / 64 B x {n(ghost)} ghost nodes |",
        ]
    return "\n".join(lines)


def rms(v):
    return math.sqrt(sum(x * x for x in v) / len(v)) if v else 0.0


def region_fitted(s):
    if not s.model:
        return "(no `model.json`: run `model.py` on the study)"
    c = s.model["codes"]
    e, m, r = c.get("elastogen"), c.get("mpm"), c.get("render")
    comp, over = [], []
    if e:
        comp.append(f"ElastoGen {sci(e['rate_per_rank'])} voxel-steps/s per rank (residual rms "
                    f"{sig(rms(e['compute_residuals_s']), 2)} s)")
        f = e["fit"]
        over.append(f"ElastoGen o = {dur(f['o_halo'])} per halo exchange, g = {sci(f['g_halo'], 2)} s/B, "
                    f"o = {dur(f['o_reduction'], 2)} per global sum")
    if m:
        comp.append(f"MPM {sci(m['rate_per_rank'])} particle-substeps/s per rank "
                    f"({sig(rms(m['compute_residuals_s']), 3)} s)")
        f = m["fit"]
        t = f"MPM o = {dur(f['o_halo'], 2)} per halo exchange"
        if f.get("g_halo"):
            t += f", g = {sci(f['g_halo'], 2)} s/B"
        over.append(t + f", {dur(f['c_migration'], 2)} per particle in migration")
    if r:
        comp.append(f"renderer {dur(r['seconds_per_splat_per_rank'])} per splat + "
                    f"{dur(r['seconds_per_pixel_per_rank'], 2)} per pixel per rank "
                    f"({sig(rms(r['compute_residuals_s']), 2)} s)")
        f = r["fit"]
        over.append(f"renderer {dur(f['c_exchange'], 2)} per local splat in the exchange, "
                    f"o = {dur(f['o_gather'], 2)} per image gather")
    run = "this run" if s.quiet else "this (loaded) run"
    txt = (f"Fitted on {run}: compute rates (the study's loops) " + ", ".join(comp)
           + "; communication overheads " + "; ".join(over) + ".")
    if e:
        g = e["fit"]["g_halo"]
        beta = s.model["machine"]["beta_Bps"]
        eff = f"ElastoGen's g is an effective {rate(1 / g)} where the transport moves {rate(beta)}" if g else ""
        if not s.quiet:
            halo1 = [float(dict(x.split("=") for x in row["phase_seconds_per_step"].split(";")).get("halo", 0))
                     / float(row["time_per_step_s"])
                     for row in s.rows if row["code"] == "elastogen" and row["ranks"] == "1"]
            h = ""
            if halo1:
                h = f"; at 1 rank the same runs spend under {math.ceil(100 * max(halo1))} % of a step in halo"
            txt += (" **These fitted overheads are mostly the waiting for descheduled ranks described "
                    f"above** ({eff}{h}), so the projection is shown twice: with them, and with the "
                    "transport alone.")
        else:
            txt += (f" {eff + '. ' if eff else ''}The projection is shown twice: with the fitted overheads, "
                    "and with the transport alone.")
    return wrap(txt)


CODE_NAME = {"elastogen": "ElastoGen", "mpm": "MPM", "render": "renderer"}


def size_label(s, code, kind):
    ps = (s.model or {}).get("projection_sizes", {}).get(code, {})
    v = ps.get(kind)
    if v is None:
        return ""
    v = int(v)
    side = round(v ** (1 / 3))
    lab = f"{side}^3" if code == "elastogen" and side ** 3 == v else f"{v:.0e}".replace("e+0", "e").replace("e+", "e")
    return lab + (" / rank" if kind == "weak" else "")


def proj_rows(s, net, code, kind):
    return {int(r["ranks"]): r for r in s.proj if r["network"] == net and r["code"] == code and r["kind"] == kind}


def comm_bound(s, net, code, kind):
    cb = (s.model or {}).get("comm_bound_from_ranks", {}).get(net, {})
    if f"{code}/{kind}" in cb:
        return cb[f"{code}/{kind}"]
    rows = proj_rows(s, net, code, kind)
    for p in sorted(rows):
        if rows[p]["comm_bound"] == "1":
            return p
    return None


def region_projection(s):
    if not s.proj:
        return "(no `projection.csv`: run `model.py` on the study)"
    lines = ["| code, kind | ranks | compute | comm, fitted overheads | comm, transport only |",
             "|---|---|---|---|---|"]
    for code in ("elastogen", "mpm", "render"):
        for kind in ("strong", "weak"):
            fit, tro = proj_rows(s, "cluster", code, kind), proj_rows(s, "cluster_transport_only", code, kind)
            if not fit:
                continue
            pmax = max(fit)
            want = {pmax}
            pb = comm_bound(s, "cluster", code, kind)
            if kind == "strong" and code != "mpm":
                want |= {32} | ({1} if code == "elastogen" else set())
                if pb:
                    want |= {pb, pb // 2}
            first = True
            for p in sorted(x for x in want if x in fit):
                r, t = fit[p], tro.get(p)
                label = f"{CODE_NAME[code]} {kind} {size_label(s, code, kind)}" if first else ""
                first = False
                comp, comm = sig(r["compute_s"]), sig(r["comm_s"])
                ranks = str(p)
                if p == pb:
                    ranks, comm = f"**{p}**", f"**{comm} (comm-bound)**"
                tcomm = sig(t["comm_s"], 2) if t else "-"
                lines.append(f"| {label} | {ranks} |".replace("|  |", "| |") + f" {comp} | {comm} | {tcomm} |")
    return "\n".join(lines)


def region_comm_bound(s):
    if not s.proj:
        return "(no `projection.csv`: run `model.py` on the study)"
    cols = [(c, k) for c in ("elastogen", "mpm", "render") for k in ("strong", "weak")
            if proj_rows(s, "cluster", c, k)]
    lines = ["| | " + " | ".join(f"{CODE_NAME[c]} {k}" for c, k in cols) + " |", "|---|" + "---|" * len(cols)]
    for net, label in (("cluster", "with the overheads fitted here"), ("cluster_transport_only", "transport only")):
        cells, first_never = [], True
        for c, k in cols:
            rows = proj_rows(s, net, c, k)
            pmax = max(rows)
            pb = comm_bound(s, net, c, k)
            if pb:
                cells.append(f"p = {pb}")
                continue
            t = "never"
            if first_never:
                t += f" up to {pmax:,}"
                first_never = False
            r = rows[pmax]
            ratio = float(r["comm_s"]) / float(r["compute_s"]) if float(r["compute_s"]) else 0
            if ratio >= 0.75:
                t += f" (comm {100 * ratio:.0f} % of compute at {pmax:,})"
            cells.append(t)
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def region_model_notes(s):
    """The first 'what the model says' bullet: transport-only ElastoGen strong at the largest p."""
    if not s.model or not s.proj or "elastogen" not in s.model["codes"]:
        return ""
    w = s.model["codes"]["elastogen"]["work_per_step"]
    tro = proj_rows(s, "cluster_transport_only", "elastogen", "strong")
    if not tro:
        return ""
    pmax = max(tro)
    r = tro[pmax]
    syncs = w["halo_gathers"] + w["exact_sums"] + w["allreduces"]
    comp, comm = float(r["compute_s"]), float(r["comm_s"])
    even = (comp - comm) / syncs
    never = all(x["comm_bound"] != "1" for x in s.proj if x["network"] == "cluster_transport_only")
    head = (f"With the counted bytes and messages alone, no code is communication-bound up to {pmax:,} ranks "
            "at these sizes" if never else "With the counted bytes and messages alone")
    pb = comm_bound(s, "cluster", "elastogen", "strong")
    fitted = (f"this run's fitted costs, whose per-byte term grows with the ghost layer, make it so from "
              f"{pb} ranks" if pb else f"this run's fitted costs do not make it so up to {pmax:,} ranks")
    vox = int(float(r["size"]) / pmax)
    txt = (f"* {head}: ElastoGen strong at {pmax:,} ranks ({vox / 1000:.0f}k voxels a rank) makes "
           f"{w['halo_gathers']} halo exchanges of up to 26 messages and {w['exact_sums']} global sums a step, "
           f"{dur(comm, 2)} against {dur(comp, 2)} of compute. What decides strong scaling is the **cost per "
           "synchronisation** (PETSc's scatter, the exact sum's packing, and above all the waiting for the "
           f"slowest rank at each of the {syncs} synchronisation points a step): ElastoGen strong at "
           f"{pmax:,} ranks turns communication-bound at about {dur(even, 2)} per exchange and per sum; "
           f"{fitted}.")
    return wrap(txt, indent="  ")


def region_not_done(s):
    if s.quiet:
        return ""
    return wrap(f"* A run on a quiet machine: the 1-minute load average at the runs' starts was "
                f"{s.load_range()} (quiet: at most {LOAD_QUIET}).", indent="  ")


def wrap(text, width=100, indent=""):
    """Greedy line wrap (markdown paragraphs; tables are not passed here)."""
    out, line = [], ""
    words = []
    for word in text.split(" "):  # never break before a unit sign
        if words and word in ("%", "%,", "%)", "%.", "%;"):
            words[-1] += "\u00a0" + word
        else:
            words.append(word)
    for word in words:
        if line and len(line) + 1 + len(word) > width:
            out.append(line)
            line = indent + word
        else:
            line = f"{line} {word}" if line else word
    if line:
        out.append(line)
    return "\n".join(out).replace("\u00a0", " ")


REGIONS = {
    "header": region_header,
    "load": region_load,
    "scaling": region_scaling,
    "mpi": region_mpi,
    "mpi-fit": region_mpi_fit,
    "checkpoint": region_checkpoint,
    "checkpoint-ratio": region_checkpoint_ratio,
    "counts": region_counts,
    "fitted": region_fitted,
    "projection": region_projection,
    "comm-bound": region_comm_bound,
    "model-notes": region_model_notes,
    "not-done": region_not_done,
}

MARK = re.compile(r"(<!-- tables:([a-z-]+) begin -->\n)(.*?)(<!-- tables:\2 end -->)", re.S)


def update(path, texts):
    src = open(path).read()
    found = set()

    def sub(m):
        name = m[2]
        if name not in texts:
            sys.exit(f"tables.py: {path}: unknown region '{name}'")
        found.add(name)
        body = texts[name]
        if body is None:  # leave as is
            return m[0]
        return m[1] + (body + "\n" if body else "") + m[4]

    new = MARK.sub(sub, src)
    begins = set(re.findall(r"<!-- tables:([a-z-]+) begin -->", src))
    if begins - found:
        sys.exit(f"tables.py: {path}: unmatched begin marker(s): {', '.join(sorted(begins - found))}")
    if new != src:
        tmp = path + ".tmp"
        with open(tmp, "w") as f:
            f.write(new)
        os.replace(tmp, path)
    missing = sorted(set(texts) - found)
    print(f"tables.py: {path}: {len(found)} region(s) updated"
          + (f"; no markers for: {', '.join(missing)}" if missing else ""))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("dir", help="a study folder (study.sh --out, after model.py)")
    ap.add_argument("--update", metavar="README", help="rewrite the marked regions of this file")
    ap.add_argument("--machine", help="CPU / machine description for the header line")
    a = ap.parse_args()
    s = Study(a.dir, a.machine)
    texts = {name: f(s) for name, f in REGIONS.items()}
    if a.update:
        update(a.update, texts)
    else:
        for name, t in texts.items():
            print(f"<!-- tables:{name} -->")
            print(t if t is not None else "(left as is)")
            print()


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Plots of the MPM validation drivers' CSV files.

  plot_mpm.py taylor TABLE.csv PROFILES.csv OUT.png   (validate_mpm_taylor --csv --profile-csv)
  plot_mpm.py collapse RUNOUT.csv OUT.png              (validate_mpm_collapse --csv)
  plot_mpm.py slump SLUMP.csv OUT.png                  (validate_mpm_slump --csv)
  plot_mpm.py bar MOMENTUM.csv OUT.png                 (validate_mpm_bar --csv)
"""
import math
import sys
from collections import defaultdict

from plotting import csv_rows, plt, save


def taylor(table, profiles, out):
    t = csv_rows(table, required=False)
    p = defaultdict(lambda: defaultdict(list))
    for r in csv_rows(profiles, required=False):
        p[(r["series"], r["test"])][r["kind"]].append((float(r["r_mm"]), float(r["z_mm"])))
    n = len(p)
    fig, axes = plt.subplots(1, n + 1, figsize=(4 * (n + 1), 4.5))
    ax = axes[0] if n else axes
    for series, marker in (("cu_wilkins", "o"), ("cu_jc", "s"), ("al_wilkins", "^")):
        rs = [r for r in t if r["series"] == series]
        if rs:
            ax.plot([float(r["Lf_measured"]) / float(r["L0"]) for r in rs],
                    [float(r["Lf_sim"]) / float(r["L0"]) for r in rs], marker, ls="",
                    label=series)
    ax.plot([0.3, 1], [0.3, 1], "k-", lw=0.8)
    ax.fill_between([0.3, 1], [0.3 * 0.95, 0.95], [0.3 * 1.05, 1.05], color="0.9",
                    label="+-5 %")
    ax.set_xlabel("Lf/L0 measured")
    ax.set_ylabel("Lf/L0 simulated")
    ax.legend(fontsize=8)
    ax.set_title("Taylor impact: final length")
    for ax, ((series, test), kinds) in zip(axes[1:] if n else [], sorted(p.items())):
        for kind, style in (("measured", "k-"), ("simulated", "r.")):
            pts = sorted(kinds[kind], key=lambda q: q[1])
            ax.plot([q[0] for q in pts], [q[1] for q in pts], style, ms=3, label=kind)
            ax.plot([-q[0] for q in pts], [q[1] for q in pts], style, ms=3)
        ax.set_aspect("equal")
        ax.set_xlabel("r (mm)")
        ax.set_ylabel("z (mm)")
        ax.set_title(f"{series} test {test}")
        ax.legend(fontsize=8)
    save(fig, out)


def collapse(path, out):
    r = csv_rows(path, required=False)
    a = [float(x["a"]) for x in r]
    fig, ax = plt.subplots(figsize=(5, 4))
    ax.loglog(a, [float(x["runout_ratio"]) for x in r], "o", label="gen4d MPM (Drucker-Prager)")
    aa = [0.3 * 1.05**k for k in range(80)]
    ax.loglog([x for x in aa if x < 1.8], [1.2 * x for x in aa if x < 1.8], "k-",
              label="Lube et al. 1.2 a")
    ax.loglog([x for x in aa if x > 2.8], [1.9 * x ** (2 / 3) for x in aa if x > 2.8], "k--",
              label="Lube et al. 1.9 a^(2/3)")
    ax.set_xlabel("aspect ratio a = h0/d0")
    ax.set_ylabel("(d_inf - d0)/d0")
    ax.legend(fontsize=8)
    save(fig, out)


def slump(path, out):
    r = csv_rows(path, required=False)
    fig, ax = plt.subplots(figsize=(5, 4))
    tt = [0.01 + 0.005 * k for k in range(98)]
    ax.plot(tt, [1 - 2 * t * (1 - math.log(2 * t)) for t in tt], "k-", label="Pashias et al. 1996")
    ax.plot([float(x["tau"]) for x in r], [float(x["s_over_h"]) for x in r], "o",
            label="gen4d MPM (Herschel-Bulkley)")
    ax.set_xlabel("tau_y / (rho g H)")
    ax.set_ylabel("slump s/H")
    ax.legend(fontsize=8)
    save(fig, out)


def bar(path, out):
    r = csv_rows(path, required=False)
    fig, ax = plt.subplots(figsize=(6, 3.5))
    ax.plot([float(x["t"]) for x in r], [float(x["left_half_momentum"]) for x in r])
    ax.set_xlabel("t (s)")
    ax.set_ylabel("left-half momentum (kg m/s)")
    save(fig, out)


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    kind, args = sys.argv[1], sys.argv[2:]
    table = {"taylor": (taylor, 3), "collapse": (collapse, 2), "slump": (slump, 2), "bar": (bar, 2)}
    if kind not in table or len(args) != table[kind][1]:
        sys.exit(__doc__)
    table[kind][0](*args)


if __name__ == "__main__":
    main()

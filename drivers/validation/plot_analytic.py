#!/usr/bin/env python3
"""Plot the grid-convergence table written by validate_analytic --csv: |error| vs h."""
from collections import defaultdict

from plotting import csv_rows, paths, plt, save


def main():
    csv_path, out = paths("plot_analytic.py ANALYTIC.csv OUT.png")
    rows = defaultdict(list)
    for r in csv_rows(csv_path):
        rows[r["check"]].append((float(r["h"]), 100 * float(r["error"])))
    fig, ax = plt.subplots(figsize=(5.5, 4))
    labels = {"static": "static tip deflection", "frequency": "first bending frequency"}
    for check, pts in sorted(rows.items()):
        pts.sort()
        h = [p[0] for p in pts]
        ax.loglog(h, [abs(p[1]) for p in pts], "o-", label=labels.get(check, check))
        for x, e in pts:
            ax.annotate(f"{e:+.2f}%", (x, abs(e)), fontsize=7, textcoords="offset points",
                        xytext=(4, 4))
    all_h = sorted({p[0] for pts in rows.values() for p in pts})
    if len(all_h) >= 2:
        ref = max(abs(p[1]) for pts in rows.values() for p in pts)
        ax.loglog(all_h, [ref * (x / all_h[-1]) ** 2 for x in all_h], "k--", lw=0.8,
                  label="slope 2")
    ax.axhline(3.0, color="r", lw=0.8, ls=":", label="3 % target")
    ax.set_xlabel("voxel size h [m]")
    ax.set_ylabel("|error| vs Euler-Bernoulli [%]")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    save(fig, out)


if __name__ == "__main__":
    main()

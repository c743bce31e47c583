#!/usr/bin/env python3
"""Plot the table written by validate_convergence --csv: trajectory error and true residual
against relaxation loops (sweeps per global step), log scales, one line per relaxation and
subspace setting, plus the plain-Jacobi search."""
from collections import defaultdict

from plotting import csv_rows, paths, plt, save


def main():
    csv_path, out = paths("plot_convergence.py CONVERGENCE.csv OUT.png")
    series = defaultdict(list)
    for r in csv_rows(csv_path):
        key = (r["series"], r["relaxation"], int(r["subspace_modes"]))
        series[key].append((int(r["loops"]), float(r["error"]), float(r["residual_mean"])))
    fig, (ax_e, ax_r) = plt.subplots(1, 2, figsize=(11, 4.2))
    for (kind, relaxation, K), rows in sorted(series.items()):
        rows.sort()
        loops = [r[0] for r in rows]
        if kind == "plain_jacobi":
            label, style = "plain Jacobi search (K = 0)", dict(ls=":", marker="x", color="gray")
        else:
            label = f"{relaxation}, K = {K}" if K else f"{relaxation}, no subspace"
            style = dict(ls="-" if K else "--", marker="o" if relaxation == "jacobi" else "s")
        ax_e.plot(loops, [100 * r[1] for r in rows], label=label, ms=4, **style)
        ax_r.plot(loops, [r[2] for r in rows], label=label, ms=4, **style)
    ax_e.axhline(1.0, color="red", lw=0.8, label="target (K = 18, 50 loops)")
    ax_e.set_ylabel("trajectory error vs Newton [% of max displacement]")
    ax_r.set_ylabel("true residual after the loops (mean over steps)")
    for ax in (ax_e, ax_r):
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("loops (relaxation sweeps per global step)")
        ax.grid(alpha=0.3, which="both")
    ax_e.legend(fontsize=7)
    fig.suptitle("Twisted Neo-Hookean beam: ElastoGen vs Newton reference")
    save(fig, out)


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Plot the tip trajectories written by validate_cantilever --csv (one panel per material);
with --neural runs, NeuralMTL targets appear as crosses beside the analytic-target dots."""
from collections import defaultdict

from plotting import csv_rows, paths, plt, save


def main():
    csv_path, out = paths("plot_cantilever.py TIP.csv OUT.png")
    rows = defaultdict(list)
    for r in csv_rows(csv_path):
        rows[(r["model"], float(r["nu"]))].append(r)
    models = sorted({m for m, _ in rows})
    fig, axes = plt.subplots(1, len(models), figsize=(5 * len(models), 4), sharey=True)
    for ax, model in zip(axes if len(models) > 1 else [axes], models):
        for (m, nu), rs in sorted(rows.items()):
            if m != model:
                continue
            t = [float(r["time"]) for r in rs]
            z0 = float(rs[0]["z_newton"])
            line, = ax.plot(t, [float(r["z_newton"]) - z0 for r in rs], label=f"Newton nu={nu}")
            ax.plot(t, [float(r["z_elastogen"]) - z0 for r in rs], "o", ms=3,
                    color=line.get_color(), label=f"ElastoGen nu={nu}")
            if "z_neural" in rs[0]:
                ax.plot(t[::4], [float(r["z_neural"]) - z0 for r in rs][::4], "x", ms=5,
                        color=line.get_color(), label=f"ElastoGen NeuralMTL nu={nu}")
        ax.set_title(model)
        ax.set_xlabel("time [s]")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("tip displacement z [m]") if len(models) > 1 else axes.set_ylabel("z [m]")
    axes[0].legend(fontsize=7) if len(models) > 1 else axes.legend(fontsize=7)
    save(fig, out)


if __name__ == "__main__":
    main()

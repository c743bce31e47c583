#!/usr/bin/env python3
"""Plot the tip trajectories written by validate_timestep --csv."""
from plotting import csv_rows, paths, plt, save


def main():
    csv_path, out = paths("plot_timestep.py TIMESTEP.csv OUT.png")
    rows = csv_rows(csv_path)
    t = [float(r["t"]) for r in rows]
    fig, ax = plt.subplots(figsize=(6, 4))
    z0 = float(rows[0]["tip_newton"])
    ax.plot(t, [float(r["tip_newton_fine"]) - z0 for r in rows], "k-", lw=0.8,
            label="Newton, dt/5")
    ax.plot(t, [float(r["tip_newton"]) - z0 for r in rows], "-", label="Newton, dt")
    ax.plot(t, [float(r["tip_elastogen"]) - z0 for r in rows], "o", ms=3, label="ElastoGen, dt")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("tip displacement z [m]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    save(fig, out)


if __name__ == "__main__":
    main()

"""Shared by the plot_*.py scripts: matplotlib without a display, the command line, the CSV
rows and the saved figure."""
import csv
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402,F401  (the scripts draw through this)


def paths(usage):
    """The (CSV, PNG) pair of a script's command line; exits with `usage` otherwise."""
    if len(sys.argv) != 3:
        sys.exit(f"usage: {usage}")
    return sys.argv[1], sys.argv[2]


def csv_rows(path, required=True):
    """The rows of a CSV file as dicts; exits when `required` and there are none."""
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    if required and not rows:
        sys.exit(f"{path}: no rows")
    return rows


def save(fig, out):
    """Lays out and writes the figure at 120 dpi."""
    fig.tight_layout()
    fig.savefig(out, dpi=120)
    print(f"wrote {out}")

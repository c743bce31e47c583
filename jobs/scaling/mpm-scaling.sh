#!/usr/bin/env bash
# MPM strong scaling: bench_mpm at 1 and 2 ranks (more with RANKS="1 2 4"), printing
# particle-substeps/s per case and the speed-up over 1 rank. Extra arguments go to bench_mpm
# (e.g. --particles 1000000 --substeps 20).
#   jobs/scaling/mpm-scaling.sh [--particles N] [--substeps S]
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/../env.sh"
BENCH="$GEN4D_BUILD/drivers/bench_mpm"
tmp=$(mktemp -d)
for np in ${RANKS:-1 2}; do
  mpirun -np "$np" "$BENCH" "$@" > "$tmp/np$np.json"
done
# shellcheck disable=SC2086  # RANKS is a list of rank counts, one argument each
python3 - "$tmp" ${RANKS:-1 2} <<'PY'
import json, sys
d, ranks = sys.argv[1], sys.argv[2:]
runs = {r: json.load(open(f"{d}/np{r}.json")) for r in ranks}
base = runs[ranks[0]]
print(f"{'case':<14} {'ranks':>5} {'particle-substeps/s':>20} {'speed-up':>9} {'of STREAM':>10}")
for i, c in enumerate(base["cases"]):
    for r in ranks:
        cr = runs[r]["cases"][i]
        print(f"{c['case']:<14} {r:>5} {cr['particle_substeps_per_s']:>20.4g} "
              f"{cr['particle_substeps_per_s'] / c['particle_substeps_per_s']:>9.2f} "
              f"{cr['fraction_of_stream']:>10.3f}")
PY
rm -rf "$tmp"

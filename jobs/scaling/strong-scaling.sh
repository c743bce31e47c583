#!/usr/bin/env bash
# Strong scaling: the same deck at 1 and 2 ranks (more with RANKS="1 2 4"), printing the
# steps/s of each and the speed-up. Extra arguments go to `gen4d run` (e.g. --set ...).
#   jobs/scaling/strong-scaling.sh [DECK] [--set key=value ...]
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/../env.sh"
GEN4D="$GEN4D_BUILD/drivers/gen4d"
deck=()
if [[ $# -gt 0 && "$1" != --* ]]; then deck=("$1"); shift; fi
base=""
printf "%6s %12s %10s\n" ranks steps_per_s speedup
for np in ${RANKS:-1 2}; do
  out=$(mktemp -d)
  rate=$(mpirun -np "$np" "$GEN4D" run "${deck[@]}" --out "$out" --overwrite \
           --set output.progress_interval=1e9 --set output.frame_interval=1e9 "$@" |
         sed -n 's/.*wall [0-9.]* s, \([0-9.]*\) steps\/s.*/\1/p')
  rm -rf "$out"
  [[ -z "$base" ]] && base=$rate
  printf "%6d %12s %10.2f\n" "$np" "$rate" "$(awk -v a="$rate" -v b="$base" 'BEGIN{print a/b}')"
done

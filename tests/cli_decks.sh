#!/usr/bin/env bash
# Decks end to end: --overwrite removes only an earlier run's checkpoints and frames; an MPM
# body resting on the grid floor is reported as held by the walls; a table the solver (or
# gen4d diagnose) does not read stops the command with exit 2, naming its line.
# Usage: cli_decks.sh GEN4D MPIEXEC SCRATCH
set -uo pipefail
gen4d=$1 mpiexec=$2 scratch=$3
rm -rf "$scratch" && mkdir -p "$scratch" && cd "$scratch" || exit 1
fail() { echo "FAIL: $*"; exit 1; }
source "$(dirname "${BASH_SOURCE[0]}")/cli_common.sh"
{
  jelly_deck 0.01 0.06 0.05 1e5 "$(box "[0, 0, 0]" "[0.2, 0.05, 0.05]")"
  printf '[[fixed]]\nlo = [-1, -1, -1]\nhi = [0.01, 1, 1]\n'
  printf '[output]\ncheckpoint_every = 2\ncheckpoint_keep = 10\nsurface = "ply"\n'
} > bar.toml
run() { "$mpiexec" -n 2 "$gen4d" run "$@"; }
run bar.toml --out out > run1.log 2>&1 || { cat run1.log; fail "first run"; }
[[ -f out/checkpoint_00000006.h5 && -f out/surface/surface_000006.ply ]] || fail "first run's files"
echo "keep" > out/notes.txt
echo "keep" > out/checkpoint_old.h5
echo "keep" > out/surface/surface_backup.ply
run bar.toml --out out --set simulation.end_time=0.02 > run2.log 2>&1
[[ $? -eq 2 ]] && grep -q "pass --overwrite" run2.log || { cat run2.log; fail "no refusal"; }
run bar.toml --out out --overwrite --set simulation.end_time=0.02 --set output.surface=none \
  > run3.log 2>&1 || { cat run3.log; fail "--overwrite run"; }
grep -q -- "--overwrite: removed 1[0-9] file(s) of the earlier run" run3.log || { cat run3.log; fail "no removal line"; }
[[ ! -e out/checkpoint_00000006.h5 && ! -e out/checkpoint_00000004.h5 ]] || fail "old checkpoints left"
[[ -f out/checkpoint_00000002.h5 && -f out/frames.h5 ]] || fail "new run's files"
ls out/surface/surface_0*.ply > /dev/null 2>&1 && fail "old surface frames left"
for f in out/notes.txt out/checkpoint_old.h5 out/surface/surface_backup.ply; do
  [[ -f $f ]] || fail "$f was removed"
done
echo "ok   overwrite"

{
  jelly_deck 0.01 0.2 0.05 2e5 "$(box "[0, 0, 0.1]" "[0.1, 0.1, 0.2]")" fixed_corotated
  printf '[output]\nframe_interval = 0.05\n'
} > drop.toml
run drop.toml --out drop > drop.log 2>&1 || { cat drop.log; fail "MPM drop"; }
[[ $(grep -c "particle(s) touch the grid walls" drop.log) -eq 1 ]] || { cat drop.log; fail "wall warning (once)"; }
grep -q "z-: [1-9]" drop.log || { cat drop.log; fail "wall named"; }
grep -q "particles touching the grid walls at the last frame: [1-9]" drop.log || fail "summary"
# A plane above the walls' reach (3.5 cells over the grid floor at z = -0.15) keeps it clear of them.
printf '[[collider]]\ntype = "plane"\npoint = [0, 0, 0.05]\nnormal = [0, 0, 1]\n' >> drop.toml
run drop.toml --out drop2 > drop2.log 2>&1 || { cat drop2.log; fail "MPM drop on a collider"; }
grep -q "touch the grid walls" drop2.log && { cat drop2.log; fail "collider run at the walls"; }
echo "ok   walls"

expect2() {  # expect2 PATTERN ARGS...: exit 2 and a one-line message matching PATTERN
  local pat="$1"; shift
  "$gen4d" "$@" > err.log 2>&1
  local c=$?
  [[ $c -eq 2 ]] || { cat err.log; fail "exit $c for: $*"; }
  grep -q -- "$pat" err.log || { cat err.log; fail "message '$pat' for: $*"; }
}
printf '[[fixed]]\nlo = [-1, -1, -1]\nhi = [1, 1, 0.11]\n' >> drop.toml
expect2 "drop.toml:23: \[\[fixed\]\] does not apply to solver.method = \"mpm\"" run drop.toml --out e1
printf '[[kinematic]]\nlo = [0.19, -1, -1]\nhi = [1, 1, 1]\nvelocity = [0, 0, 0.1]\n' >> bar.toml
echo "marker,X,Y,Z,t,x,y,z" > rec.csv
expect2 "bar.toml:21: \[\[kinematic\]\] does not apply to gen4d diagnose" diagnose bar.toml \
  --recording rec.csv --out e2
[[ -e e2/report.json ]] && fail "report written"
echo "ok   refusals"

#!/usr/bin/env bash
# gen4d diagnose's input checks: malformed recordings and options fail with exit 2 and a
# located one-line message, leaving no report (diagnose_blind_small runs it end to end).
# Usage: cli_diagnose.sh GEN4D MPIEXEC SCRATCH
set -uo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/cli_common.sh"
gen4d=$1 mpiexec=$2 scratch=$3
rm -rf "$scratch" && mkdir -p "$scratch" && cd "$scratch" || exit 1
fail=0
check() {  # check NAME EXPECTED_RC PATTERN -- command...
  local name=$1 want=$2 pat=$3
  shift 4
  "$@" > out.txt 2>&1
  local rc=$?
  if [ "$rc" != "$want" ] || ! grep -q -- "$pat" out.txt; then
    echo "FAIL $name: exit $rc (want $want), output:"; cat out.txt; fail=1
  else
    echo "ok   $name"
  fi
}
# The stage tests' cantilever (test_diagnose_stages.cpp): StVK, clamped at x = 0, its tip pulled
# for 0.1 s.
{
  jelly_deck 0.004 0.6 0.01 3e5 "$(box "[0, 0, 0]" "[0.08, 0.02, 0.02]")" "" \
    "$(printf 'name = "cli-diagnose"\ngravity = [0, 0, -9.81]')"
  printf 'model = "stvk"\n'
  region fixed "[-1, -1, -1]" "[0.001, 1, 1]"
  region force "[0.075, -1, -1]" "[1, 1, 1]" "$(printf 'force = [0, 0.01, -0.01]\nstart = 0\nend = 0.1')"
} > beam.toml
hdr="marker,X,Y,Z,t,x,y,z"
printf '%s\n1,0.08,0.01,0.02,0,0.08,0.01,0.02\n1,0.08,0.01,0.02,0.01,0.08,0.01,0.0199\n' "$hdr" > short.csv
# A value column may be left out (not measured); the reference point and time may not.
printf 'marker,X,Y,t,x,y,z\n1,0.08,0.01,0,0.08,0.01,0.02\n' > missing.csv
printf '%s\n1,0.08,0.01,0.02,0,0.08,0.01,0.02\n1,0.08,0.01,0.02,0.01,nan,0.01,0.02\n' "$hdr" > nan.csv
printf '%s\n1,0.08,0.01,0.02,0.02,0.08,0.01,0.02\n1,0.08,0.01,0.02,0.01,0.08,0.01,0.02\n' "$hdr" > backwards.csv
{ echo "$hdr"; for k in $(seq 0 20); do echo "7,0.5,0.01,0.02,$((k / 10)).$((k % 10)),0.5,0.01,0.02"; done; } > outside.csv
run() { "$mpiexec" -n 2 "$gen4d" diagnose beam.toml "$@"; }
check missing-column 2 "missing.csv.*column 'Z'" -- run --recording missing.csv --out o1
check unmeasured-name 2 "unmeasured.*'w'" -- run --recording missing.csv --unmeasured w --out o1
{ echo "$hdr"; for k in $(seq 0 20); do echo "1,0.08,0.01,0.02,$((k / 10)).$((k % 10)),0.08,0.01,0.02"; done; } > still.csv
check lowpass-nyquist 2 "lowpass.*Nyquist" -- run --recording still.csv --lowpass 1e6 --out o1
check nan 2 "nan.csv:3" -- run --recording nan.csv --out o2
check time-backwards 2 "backwards.csv:3" -- run --recording backwards.csv --out o3
check outside-body 2 "outside.csv.*marker '7'.*not inside the body" -- run --recording outside.csv --out o4
check too-few-samples 2 "at least 7 samples" -- run --recording short.csv --out o5
check unknown-effect 2 "unknown effect 'friction'" -- run --recording short.csv --out o6 --effects friction
check bad-holdout 2 "holdout" -- run --recording short.csv --out o7 --holdout 0.9
check empty-effects 2 "--effects ',,' names no effect" -- run --recording short.csv --out o9 --effects ,,
check all-not-alone 2 "'all' names every effect, so it stands alone" -- run --recording short.csv --out o10 --effects all,damping
# 'all' passes the effect names' check (the recording then fails on its length, after it).
check all-effects 2 "at least 7 samples" -- run --recording short.csv --out o11 --effects all --hold-poisson
check missing-recording 2 "recording" -- run --out o8
for d in o1 o2 o3 o4 o5 o6 o7 o8 o9 o10 o11; do
  if [ -e "$d/report.json" ]; then echo "FAIL: $d/report.json written for bad input"; fail=1; fi
done
exit $fail

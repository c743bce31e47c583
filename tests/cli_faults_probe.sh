#!/usr/bin/env bash
# The MPI error handler and the watchdog (src/parallel/Watchdog.hpp) in a 2-rank probe
# (tests/faults_probe.cpp): an invalid MPI call and a hung rank each end the job within
# 30 s with a message naming the rank; steady progress never trips the watchdog.
set -u
mpiexec="$2"; dir="$3"; probe="$4"
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
# shellcheck source=tests/cli_faults_common.sh
source "$here/cli_faults_common.sh"
rm -rf "$dir"; mkdir -p "$dir"

# probe MODE EXPECTED_CODE REGEX: runs the probe (at most 60 s), checks its exit code (0 or
# "nonzero"), a line matching REGEX and at most 30 s.
probe() {
  local mode=$1 expected=$2 regex=$3 log="$dir/$1.log" start code took
  start=$(now)
  timeout 60 "$mpiexec" -n 2 "$probe" "$mode" > "$log" 2>&1
  code=$?
  took=$(elapsed "$start")
  echo "$mode: exit $code after $took s: $(grep -m1 -E "$regex" "$log")"
  if [[ $expected == 0 ]]; then
    [[ $code -eq 0 ]] || { echo "FAIL $mode: exit $code"; cat "$log"; exit 1; }
  else
    [[ $code -ne 0 && $code -ne 124 ]] || { echo "FAIL $mode: exit $code"; cat "$log"; exit 1; }
  fi
  awk -v t="$took" 'BEGIN { exit !(t <= 30) }' || { echo "FAIL $mode: $took s"; exit 1; }
  grep -qE "$regex" "$log" || { echo "FAIL $mode: no line matching '$regex'"; cat "$log"; exit 1; }
}

probe mpi-error nonzero "^\[rank 1\] error: MPI: .*(rank|RANK).*; aborting the job"
probe hang nonzero "^\[rank 0\] error: watchdog: rank 0 made no progress for 2 s \(waiting in the probe's barrier\)"
probe stuck nonzero "^\[rank 1\] error: watchdog: rank 1 made no progress for 2 s \(in the probe's endless step\)"
probe progress 0 "probe progress: finished"
echo "1 passed, 0 failed"

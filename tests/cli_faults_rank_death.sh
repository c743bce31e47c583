#!/usr/bin/env bash
# A rank that dies mid-step (kill -9, SIGABRT as from abort()) or hangs (SIGSTOP) in a
# 2-rank run: the job ends within 30 s, non-zero, with a message naming the rank. A dead rank
# is reported by mpiexec; a hung one by the watchdog of the rank left waiting for it
# (--watchdog 5).
set -u
gen4d="$1"; mpiexec="$2"; dir="$3"
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
# shellcheck source=tests/cli_faults_common.sh
source "$here/cli_faults_common.sh"
board="$here/../inputs/jelly_board.toml"
rm -rf "$dir"; mkdir -p "$dir"
# A run far longer than the test: it ends only through the fault.
sets=(--set simulation.end_time=1000 --set output.frame_interval=0.5 --set output.progress_interval=0.05
      --set output.surface=\"none\" --set output.checkpoint_every=0 --set domain.voxel_size=0.04)
limit=30

# fault NAME SIGNAL REGEX [ARGS...]: sends SIGNAL to rank 1 once steps run, then expects the
# job to end within $limit s, non-zero, its output matching REGEX.
fault() {
  local name=$1 signal=$2 regex=$3 log="$dir/$1.log"
  shift 3
  "$mpiexec" -n 2 "$gen4d" run "$board" --out "$dir/$name" "${sets[@]}" "$@" > "$log" 2>&1 &
  local launcher=$!
  local victim
  victim=$(rank_pid "$launcher" 1)
  local other
  other=$(rank_pid "$launcher" 0)
  if [[ -z $victim ]] || ! wait_for_log "$log" "step +[1-9][0-9]*/"; then
    echo "FAIL $name: the run did not start"; kill -9 "$launcher"; cat "$log"; exit 1
  fi
  kill "-$signal" "$victim"
  local start
  start=$(now)
  # The job's end, bounded: past the limit, the test cleans up and fails.
  local waited=0
  while kill -0 "$launcher" 2> /dev/null && [[ $waited -lt $((limit * 10 + 50)) ]]; do
    sleep 0.1; waited=$((waited + 1))
  done
  local took
  took=$(elapsed "$start")
  if kill -0 "$launcher" 2> /dev/null; then
    echo "FAIL $name: the job still runs $took s after SIGSTOP/kill"
    kill -9 "$victim" "$other" "$launcher" 2> /dev/null; wait "$launcher"; cat "$log"; exit 1
  fi
  wait "$launcher"
  local code=$?
  echo "$name: SIG$signal to rank 1: the job ended after $took s, exit $code: $(grep -m1 -E "$regex" "$log")"
  # A stopped process ends only once it is killed: none may be left behind (5 s to exit).
  for p in $victim $other; do
    for _ in $(seq 1 50); do
      [[ $(awk '{ print $3 }' "/proc/$p/stat" 2> /dev/null) =~ ^[^Z]$ ]] || break
      sleep 0.1
    done
    if [[ $(awk '{ print $3 }' "/proc/$p/stat" 2> /dev/null) =~ ^[^Z]$ ]]; then
      echo "FAIL $name: process $p outlived the job"; kill -9 "$p"; exit 1
    fi
  done
  [[ $code -ne 0 ]] || { echo "FAIL $name: exit 0"; cat "$log"; exit 1; }
  awk -v t="$took" -v l="$limit" 'BEGIN { exit !(t <= l) }' ||
    { echo "FAIL $name: $took s > $limit s"; cat "$log"; exit 1; }
  grep -qE "$regex" "$log" || { echo "FAIL $name: no message matching '$regex'"; cat "$log"; exit 1; }
}

fault kill KILL "rank 1 .*(exited on signal 9|Killed)"
fault abort ABRT "rank 1 .*(exited on signal 6|Aborted)"
fault hang STOP "rank 0\] error: watchdog: rank 0 made no progress for 5 s" --watchdog 5
echo "1 passed, 0 failed"

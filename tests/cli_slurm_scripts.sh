#!/usr/bin/env bash
# The batch scripts without a scheduler: shellcheck over every script in jobs/ (and the
# cli_slurm_* tests), and a dry run of jobs/pbs/gen4d.pbs with stand-ins for mpirun and gen4d that print
# their command lines (no PBS server was available to run it on): a fresh run, an explicit
# restart, RESTART=auto picking the newest complete checkpoint, and the rank count from
# $PBS_NODEFILE. Exit 77 (skipped) when shellcheck is not installed.
set -u
dir="$3"
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
rm -rf "$dir"
mkdir -p "$dir"
fail=0
failed() {
  echo "FAIL $*"
  fail=1
}
command -v shellcheck > /dev/null || {
  echo "SKIP shellcheck not installed (Debian package shellcheck)"
  exit 77
}

# 1. shellcheck: scripts follow the files they source (-x, relative to the script).
mapfile -t scripts < <(cd "$root" && {
  find jobs -type f \( -name '*.sh' -o -name '*.sbatch' -o -name '*.pbs' \) ! -path jobs/env.sh
  find tests -name 'cli_slurm_*.sh'
} | sort)
sc=0
(cd "$root" && shellcheck -x -P SCRIPTDIR "${scripts[@]}") > "$dir/shellcheck.txt" 2>&1 || sc=1
(cd "$root" && shellcheck --shell=bash jobs/env.sh) >> "$dir/shellcheck.txt" 2>&1 || sc=1
if [[ $sc -eq 0 ]]; then
  echo "shellcheck: ${#scripts[@]} scripts and jobs/env.sh clean"
else
  cat "$dir/shellcheck.txt"
  failed "shellcheck"
fi

# 2. PBS dry run: mpirun prints its arguments; gen4d is never started.
stubs="$dir/stubs"
mkdir -p "$stubs"
printf '#!/bin/sh\necho "mpirun $*"\n' > "$stubs/mpirun"
printf '#!/bin/sh\necho "gen4d must not run in a dry run" >&2\nexit 99\n' > "$stubs/gen4d"
chmod +x "$stubs/mpirun" "$stubs/gen4d"
work="$dir/work"
mkdir -p "$work/run1"
# pbs NAME EXPECTED [VAR=value ...]: runs the script as PBS would, compares the printed command.
pbs() {
  local name="$1" want="$2" got
  shift 2
  got="$(cd "$work" && env -u PBS_NODEFILE -u RESTART -u DECK -u NP PATH="$stubs:$PATH" \
    GEN4D_ROOT="$root" GEN4D="$stubs/gen4d" PBS_O_WORKDIR="$work" PBS_JOBID=42.server "$@" \
    bash "$root/jobs/pbs/gen4d.pbs" 2>&1)" || {
    failed "$name: the script exited non-zero: $got"
    return
  }
  if [[ $got == "$want" ]]; then
    echo "ok   $name: $got"
  else
    failed "$name: printed '$got', expected '$want'"
  fi
}
pbs "fresh run" "mpirun -np 2 $stubs/gen4d run inputs/jelly_board.toml --out run1 --overwrite --set simulation.end_time=0.5" \
  DECK=inputs/jelly_board.toml OUT=run1 GEN4D_ARGS="--set simulation.end_time=0.5"
pbs "default OUT" "mpirun -np 2 $stubs/gen4d run inputs/jelly_board.toml --out gen4d-42.server --overwrite" \
  DECK=inputs/jelly_board.toml
printf 'node1\nnode1\nnode2\nnode2\n' > "$work/nodes"
pbs "ranks from PBS_NODEFILE" "mpirun -np 4 $stubs/gen4d run inputs/jelly_board.toml --out run1 --overwrite" \
  DECK=inputs/jelly_board.toml OUT=run1 PBS_NODEFILE="$work/nodes"
pbs "explicit restart" "mpirun -np 2 $stubs/gen4d restart run1/checkpoint_00000150.h5 --out run1" \
  RESTART=run1/checkpoint_00000150.h5 OUT=run1
pbs "RESTART=auto without a checkpoint" "mpirun -np 2 $stubs/gen4d run inputs/jelly_board.toml --out run1 --overwrite" \
  RESTART=auto DECK=inputs/jelly_board.toml OUT=run1
# A half-written checkpoint (hidden .tmp) is newer but must not be picked.
touch "$work/run1/checkpoint_00000050.h5" "$work/run1/checkpoint_00000150.h5" \
  "$work/run1/.checkpoint_00000200.h5.tmp"
pbs "RESTART=auto" "mpirun -np 2 $stubs/gen4d restart run1/checkpoint_00000150.h5 --out run1" \
  RESTART=auto DECK=inputs/jelly_board.toml OUT=run1

[[ $fail -eq 0 ]] || exit 1
echo "1 passed, 0 failed"

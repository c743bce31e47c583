# shellcheck shell=bash
# Helpers of the cli_faults_*.sh tests (sourced).

# rank_pid LAUNCHER_PID RANK: the pid of rank RANK among the processes mpiexec started (its
# children, which carry OMPI_COMM_WORLD_RANK); waits up to 30 s for it (while the launcher
# runs), prints nothing if none.
rank_pid() {
  local launcher=$1 rank=$2 child
  for _ in $(seq 1 300); do
    kill -0 "$launcher" 2> /dev/null || return 0
    for child in $(pgrep -P "$launcher"); do
      if tr '\0' '\n' < "/proc/$child/environ" 2>/dev/null | grep -qx "OMPI_COMM_WORLD_RANK=$rank"; then
        echo "$child"
        return 0
      fi
    done
    sleep 0.1
  done
}

# wait_for_file GLOB [SECONDS]: waits until a file matches GLOB (default 120 s); 1 if none did.
wait_for_file() {
  local pattern=$1 limit=${2:-120}
  for _ in $(seq 1 $((limit * 10))); do
    compgen -G "$pattern" > /dev/null && return 0
    sleep 0.1
  done
  return 1
}

# wait_for_log FILE REGEX [SECONDS]: waits until a line of FILE matches REGEX (default 120 s).
wait_for_log() {
  local file=$1 regex=$2 limit=${3:-120}
  for _ in $(seq 1 $((limit * 10))); do
    grep -qE "$regex" "$file" 2> /dev/null && return 0
    sleep 0.1
  done
  return 1
}

# now: seconds since the epoch, with decimals.
now() { date +%s.%N; }

# elapsed START: seconds since START (from now), one decimal.
elapsed() { awk -v a="$1" -v b="$(now)" 'BEGIN { printf "%.1f", b - a }'; }

# h5_check FILE...: every file opens with h5py and every dataset in it reads; prints
# "FILE: N frames" for frames files.
h5_check() {
  /usr/bin/python3 - "$@" <<'PY'
import sys, h5py
for path in sys.argv[1:]:
    with h5py.File(path, "r") as f:
        def visit(name, obj):
            if isinstance(obj, h5py.Dataset):
                obj[...]
        f.visititems(visit)
        if "frames" in f:
            print(f"{path}: {len(f['frames'])} frames")
        else:
            print(f"{path}: step {f.attrs['step']}")
PY
}

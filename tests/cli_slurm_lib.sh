# shellcheck shell=bash
# Helpers of the cli_slurm_*.sh tests (sourced): a one-node Slurm cluster of their own in the
# scratch folder, always stopped on exit, and job polling without accounting (scontrol).
# Sets root (the source tree), cluster, and exports SLURM_CONF. Exit 77 (skipped) when Slurm
# is not installed.

slurm_fail() {
  echo "FAIL $*"
  exit 1
}

# slurm_start DIR: a fresh cluster in DIR/cluster, stopped when the test exits (any way).
slurm_start() {
  root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
  PATH="$PATH:/usr/sbin:/sbin"
  if ! command -v slurmctld > /dev/null; then
    echo "SKIP slurmctld not installed (Debian packages slurm-wlm and munge)"
    exit 77
  fi
  cluster="$1/cluster"
  trap 'bash "$root/jobs/slurm/local-cluster.sh" stop "$cluster"' EXIT
  bash "$root/jobs/slurm/local-cluster.sh" start "$cluster" || slurm_fail "cluster did not start"
  export SLURM_CONF="$cluster/slurm.conf"
}

# slurm_field JOBID NAME: a field of `scontrol show job` (JobState, ExitCode, Restarts, ...).
slurm_field() {
  scontrol show job -o "$1" 2> /dev/null | tr ' ' '\n' | sed -n "s/^$2=//p" | head -n 1
}

# slurm_wait JOBID SECONDS: until the job has ended (no requeue pending); prints its state.
slurm_wait() {
  local state="" t0=$SECONDS
  while ((SECONDS - t0 < $2)); do
    state="$(slurm_field "$1" JobState)"
    case "$state" in
      COMPLETED | FAILED | CANCELLED | TIMEOUT | NODE_FAIL | OUT_OF_MEMORY | BOOT_FAIL | DEADLINE)
        echo "$state"
        return 0
        ;;
    esac
    sleep 1
  done
  echo "still ${state:-unknown} after $2 s"
  return 1
}

# slurm_submit ARGS...: sbatch --parsable from the scratch folder; prints the job id.
slurm_submit() {
  local id
  id="$(sbatch --parsable "$@")" || slurm_fail "sbatch $*"
  echo "${id%%;*}"
}

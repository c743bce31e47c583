#!/usr/bin/env bash
# Installs gen4d's build and run dependencies from Debian packages.
# Idempotent: packages already present are skipped, so a second run is a no-op.
# Usage: cmake/install-deps.sh [--with-torch|--no-torch]
set -euo pipefail

want_torch=1
for a in "$@"; do
  case "$a" in
    --no-torch) want_torch=0 ;;
    --with-torch) want_torch=1 ;;
    *) echo "install-deps: unknown option '$a'" >&2; exit 2 ;;
  esac
done

pkgs=(
  build-essential cmake pkg-config git
  openmpi-bin libopenmpi-dev
  petsc-dev
  libhdf5-openmpi-dev
  libopenvdb-dev libboost-iostreams-dev libtbb-dev libblosc-dev
  libeigen3-dev
  libgtest-dev libgmock-dev
  libtomlplusplus-dev libcli11-dev
  libspdlog-dev libfmt-dev
  libpng-dev zlib1g-dev
  clang-format
  python3-matplotlib python3-h5py python3-numpy
  calculix-ccx
  ffmpeg
  slurm-wlm munge                         # a one-node Slurm cluster for the batch-job tests
  clang libclang-rt-dev shellcheck        # libFuzzer, ASan/UBSan, the job-script linter
)
if [ "$want_torch" = 1 ]; then pkgs+=(libtorch-dev); fi

missing=()
for p in "${pkgs[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#pkgs[@]} packages present"
  exit 0
fi

echo "install-deps: installing ${#missing[@]} missing package(s): ${missing[*]}"
SUDO=""
if [ "$(id -u)" != 0 ]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
echo "install-deps: done"

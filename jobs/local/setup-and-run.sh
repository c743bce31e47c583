#!/usr/bin/env bash
# One command on a fresh Debian 12 machine: install what is missing, build, and run the
# main job (the embedded default scene) on 2 MPI ranks. Extra arguments go to `gen4d run`.
#   jobs/local/setup-and-run.sh [--out DIR] [--set key=value ...]
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/../env.sh"
"$GEN4D_ROOT/cmake/install-deps.sh"
gen4d_build
out="gen4d-out"
args=("$@")
for ((i = 0; i < ${#args[@]}; i++)); do
  if [[ "${args[$i]}" == "--out" || "${args[$i]}" == "-o" ]]; then out="${args[$((i + 1))]}"; fi
done
mpirun -np 2 "$GEN4D_BUILD/drivers/gen4d" run --out "$out" --overwrite "$@"
echo "Rendered frames in $out/png (video $out/render.mp4 where ffmpeg is installed);" \
  "particles in $out/particles.xdmf for ParaView"

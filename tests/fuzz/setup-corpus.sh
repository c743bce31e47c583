#!/usr/bin/env bash
# Fills BUILD/fuzz/corpus/<target>/ with the seeds of each fuzz target: the small seeds of
# tests/fuzz/corpus, the repository's decks, configs and splats, binary seeds written by
# fuzz_make_seeds, and, where the sibling data folder ../shared exists, pieces of its meshes,
# splats and recordings. Usage: setup-corpus.sh BUILD_DIR
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(cd "$here/../.." && pwd)"
build="$(cd "${1:?usage: setup-corpus.sh BUILD_DIR}" && pwd)"
corpus="$build/fuzz/corpus"
shared="$root/../shared/data"
targets=(fuzz_deck fuzz_mesh fuzz_vdb fuzz_ply fuzz_physgaussian_json fuzz_recording
         fuzz_checkpoint)
for t in "${targets[@]}"; do
  mkdir -p "$corpus/$t"
  if [[ -d "$here/corpus/$t" ]]; then cp "$here/corpus/$t"/* "$corpus/$t/"; fi
done

cp "$root"/inputs/*.toml "$corpus/fuzz_deck/"
cp "$root"/inputs/physgaussian/*.json "$root"/tests/data/physgaussian/*.json \
   "$corpus/fuzz_physgaussian_json/"

# A 3DGS PLY cut to its header and the first 3 vertices (binary little-endian float32).
trim_ply() {
  python3 - "$1" "$2" <<'PY'
import sys
data = open(sys.argv[1], "rb").read(1 << 20)
end = data.index(b"end_header\n") + len(b"end_header\n")
header = data[:end].decode("ascii").split("\n")
props = sum(1 for line in header if line.startswith("property float"))
keep = 3
header = [f"element vertex {keep}" if l.startswith("element vertex") else l for l in header]
body = data[end:end + keep * 4 * props]
open(sys.argv[2], "wb").write("\n".join(header).encode("ascii") + body)
PY
}
trim_ply "$root/inputs/splats/donut.ply" "$corpus/fuzz_ply/donut_sh0_3.ply"

# A seed writer, not a test: OpenMPI's exit-time allocations are no finding here.
# shellcheck source=SCRIPTDIR/../../jobs/env.sh
(source "$root/jobs/env.sh" && ASAN_OPTIONS=detect_leaks=0 "$build/tests/fuzz/fuzz_make_seeds" "$corpus")

if [[ -d "$shared" ]]; then
  ply="$shared/splats/donut/point_cloud.ply"
  if [[ -f "$ply" ]]; then trim_ply "$ply" "$corpus/fuzz_ply/point_cloud_3.ply"; fi
  # The first 60 vertices of a mesh and the faces among them ("0": the target's OBJ byte).
  for obj in "$shared"/meshes/suzanne.obj "$shared"/meshes/cow.obj; do
    if [[ -f "$obj" ]]; then
      { printf '0'
        awk '/^v /{ if (++n <= 60) print; next }
             /^f /{ ok = 1; for (i = 2; i <= NF; ++i) { split($i, a, "/"); if (a[1] > 60) ok = 0 }
                    if (ok) print }' "$obj"
      } > "$corpus/fuzz_mesh/$(basename "$obj" .obj)_60.obj"
    fi
  done
  for csv in "$shared"/recordings/*/*.csv; do
    if [[ -f "$csv" ]]; then
      { printf '0'; head -n 40 "$csv"; } > "$corpus/fuzz_recording/$(basename "$(dirname "$csv")").csv"
    fi
  done
fi
for t in "${targets[@]}"; do
  echo "corpus $t: $(find "$corpus/$t" -type f | wc -l) files"
done

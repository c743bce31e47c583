#!/usr/bin/env bash
# Low-resolution twins of the shipped PhysGaussian configs (inputs/physgaussian/*.json): each runs
# unchanged through `gen4d run --physgaussian` at 2 ranks, cut down only by --set (the most
# opaque Gaussians, a few substeps, 64 x 48 images). Checks per config: exit 0, the deck maps
# the config's distinctive keys, two non-black images in PhysGaussian's layout, and particles that
# moved between the first and the last --output-ply file.
set -u
gen4d="$1"; mpiexec="$2"; dir="$3"
src="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
rm -rf "$dir"; mkdir -p "$dir"
fail() { echo "FAIL $*"; exit 1; }
model="$src/inputs/physgaussian/donut_model"
# Nonzero colour bytes of a PNG (the bytes after each row's filter byte; 0 for a black image).
lit_bytes() {
  python3 - "$1" <<'PY'
import struct, sys, zlib
data = open(sys.argv[1], "rb").read()
pos, idat, width, height = 8, b"", 0, 0
while pos < len(data):
    n, kind = struct.unpack(">I4s", data[pos:pos + 8])
    if kind == b"IHDR": width, height = struct.unpack(">II", data[pos + 8:pos + 16])
    if kind == b"IDAT": idat += data[pos + 8:pos + 8 + n]
    pos += 12 + n
raw = zlib.decompress(idat)
row = len(raw) // height
print(width, height, sum(1 for r in range(height) for b in raw[r * row + 1:(r + 1) * row] if b))
PY
}
# config -> a line its converted deck must hold
declare -A expect=(
  [jelly_squeeze]='motion = "moving"'
  [metal_twist]='type = "enforce_particle_velocity_rotation"'
  [sand_pour]='type = "release_particles_sequentially"'
  [foam_slide]='rpic_damping = 0.2'
  [plasticine_press]='reset_duration = '
  [snow_smash]='model = "snow"'
  [jelly_two_stiffness]='[[material]]'
)
count=0
for cfg in "$src"/inputs/physgaussian/*.json; do
  name="$(basename "$cfg" .json)"
  [[ -n "${expect[$name]+x}" ]] || fail "$name: no twin expectation (add one)"
  out="$dir/$name"
  "$mpiexec" -n 2 "$gen4d" run --physgaussian "$cfg" --model-path "$model" --output-path "$out" \
    --set geometry.0.opacity_threshold=0.9 --set simulation.end_time=0.004 \
    --set output.frame_interval=0.002 --set render.width=64 --set render.height=48 \
    --output-ply > "$dir/$name.log" 2>&1 || { tail -20 "$dir/$name.log"; fail "$name: run"; }
  grep -qF "${expect[$name]}" "$out/physgaussian/deck.toml" || fail "$name: deck lacks ${expect[$name]}"
  for png in 0000 0001; do
    read -r w h lit < <(lit_bytes "$out/$png.png") || fail "$name: no $png.png"
    [[ "$w" == 64 && "$h" == 48 ]] || fail "$name: $png.png is ${w}x$h"
    (( lit > 100 )) || fail "$name: $png.png is black ($lit lit bytes)"
  done
  [[ ! -e "$out/0002.png" ]] || fail "$name: an image too many"
  plys=("$out"/simulation_ply/sim_*.ply)
  (( ${#plys[@]} == 3 )) || fail "$name: ${#plys[@]} PLY files, expected 3"
  cmp -s "${plys[0]}" "${plys[2]}" && fail "$name: nothing moved"
  count=$((count + 1))
  echo "ok $name: $(grep -o 'mpm: [0-9]* particles' "$dir/$name.log" | head -1)"
done
(( count >= 6 )) || fail "only $count configs"
echo "PASS: $count PhysGaussian configs"

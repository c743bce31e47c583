#!/usr/bin/env bash
# PhysGaussian's scenes through the gen4d command: a model folder laid out as 3DGS trains it
# (point_cloud/iteration_N/point_cloud.ply, the largest N taken), the test configs converted to
# decks, a short `run --physgaussian` at 2 ranks, and bad configs or folders as exit 2 with
# nothing written.
set -u
gen4d="$1"; mpiexec="$2"; dir="$3"
src="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
rm -rf "$dir"; mkdir -p "$dir/model/point_cloud/iteration_7000" "$dir/model/point_cloud/iteration_30000"
fail() { echo "FAIL $*"; exit 1; }
cp "$src/inputs/splats/donut.ply" "$dir/model/point_cloud/iteration_30000/point_cloud.ply"
printf 'not a ply\n' > "$dir/model/point_cloud/iteration_7000/point_cloud.ply"  # older: ignored
for cfg in jelly_cuboid sand_collider; do
  "$gen4d" convert-physgaussian "$src/tests/data/physgaussian/$cfg.json" --model-path "$dir/model" \
    -o "$dir/$cfg" > "$dir/$cfg.log" 2>&1 || { cat "$dir/$cfg.log"; fail "convert $cfg"; }
  [[ -s "$dir/$cfg/deck.toml" && -s "$dir/$cfg/object.ply" ]] || fail "$cfg: no deck or PLY"
  grep -q "iteration_30000" "$dir/$cfg/deck.toml" || fail "$cfg: not the latest iteration"
done
"$mpiexec" -n 2 "$gen4d" run --physgaussian "$src/tests/data/physgaussian/sand_collider.json" \
  --model-path "$dir/model" --output-path "$dir/run" --set simulation.end_time=0.002 \
  --set output.frame_interval=0.001 --set render.width=64 --set render.height=48 \
  > "$dir/run.log" 2>&1 || { cat "$dir/run.log"; fail "run --physgaussian"; }
[[ -s "$dir/run/particles.h5" && -s "$dir/run/png/frame_000002.png" ]] || fail "run outputs"

expect2() {  # expect2 NAME NEEDLE ARGS...: exit 2, NEEDLE in the message, nothing written
  local name="$1" needle="$2"; shift 2
  local err; err=$("$gen4d" "$@" 2>&1 >/dev/null); local code=$?
  [[ $code -eq 2 && "$err" == *"$needle"* && ! -e "$dir/bad" ]] ||
    fail "$name: exit $code, message: $err"
}
printf '{\n  "material": "jelly",\n  "n_grid": "many"\n}\n' > "$dir/badtype.json"
printf '{\n  "material": "jelly",\n  "colour": 1\n}\n' > "$dir/unknown.json"
printf '{\n  "material": "jelly",\n' > "$dir/broken.json"
cfg="$src/tests/data/physgaussian/jelly_cuboid.json"
expect2 "wrong type" "badtype.json:3" convert-physgaussian "$dir/badtype.json" --model-path "$dir/model" -o "$dir/bad"
expect2 "unknown key" "colour" convert-physgaussian "$dir/unknown.json" --model-path "$dir/model" -o "$dir/bad"
expect2 "malformed" "broken.json" convert-physgaussian "$dir/broken.json" --model-path "$dir/model" -o "$dir/bad"
# metal_rotation.json's sim_area is a plane's: nothing of the donut lies in it.
expect2 "empty selection" "metal_rotation.json: no Gaussian is left" convert-physgaussian \
  "$src/tests/data/physgaussian/metal_rotation.json" --model-path "$dir/model" -o "$dir/bad"
expect2 "no model" "point_cloud" convert-physgaussian "$cfg" --model-path "$dir/nothing" -o "$dir/bad"
expect2 "no model path" "--model-path" run --physgaussian "$cfg" --output-path "$dir/bad"
echo "1 passed, 0 failed"

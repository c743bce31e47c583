#!/usr/bin/env bash
# PhysGaussian's scenes through the gen4d command: a model folder laid out as 3DGS trains it
# (point_cloud/iteration_N/point_cloud.ply, the largest N taken, and cameras.json), the test
# configs converted to decks, a short `run --physgaussian --output-ply --mp4` at 2 ranks with
# gs_simulation.py's output layout (images, simulation_ply/, output.mp4), sim_area's scenery and
# a cameras.json view, the converted deck rerun at 1 rank (the same image), and bad configs,
# folders or scenery as exit 2 with nothing written.
set -u
gen4d="$1"; mpiexec="$2"; dir="$3"
src="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
rm -rf "$dir"; mkdir -p "$dir/model/point_cloud/iteration_7000" "$dir/model/point_cloud/iteration_30000"
fail() { echo "FAIL $*"; exit 1; }
cp "$src/inputs/splats/donut.ply" "$dir/model/point_cloud/iteration_30000/point_cloud.ply"
printf 'not a ply\n' > "$dir/model/point_cloud/iteration_7000/point_cloud.ply"  # older: ignored
# Two small views of the donut from -y, looking along +y and slightly down.
cat > "$dir/model/cameras.json" <<'EOF'
[{"id": 0, "img_name": "a", "width": 64, "height": 48, "position": [0.0, -0.5, 0.25],
  "rotation": [[1, 0, 0], [0, -0.391918358845308, 0.92], [0, -0.92, -0.391918358845308]],
  "fy": 60, "fx": 60},
 {"id": 1, "img_name": "b", "width": 80, "height": 60, "position": [0.0, -0.45, 0.25],
  "rotation": [[1, 0, 0], [0, -0.391918358845308, 0.92], [0, -0.92, -0.391918358845308]],
  "fy": 70, "fx": 72}]
EOF
for cfg in jelly_cuboid sand_collider; do
  "$gen4d" convert-physgaussian "$src/tests/data/physgaussian/$cfg.json" --model-path "$dir/model" \
    -o "$dir/$cfg" > "$dir/$cfg.log" 2>&1 || { cat "$dir/$cfg.log"; fail "convert $cfg"; }
  [[ -s "$dir/$cfg/deck.toml" && -s "$dir/$cfg/object.ply" ]] || fail "$cfg: no deck or PLY"
  grep -q "iteration_30000" "$dir/$cfg/deck.toml" || fail "$cfg: not the latest iteration"
done
# sand_collider made cheap (a 50-cell grid, 1e-4 s substeps), simulating the donut's x > 0 half
# (the other half is scenery) and seen from cameras.json's second view.
sed -e 's/"n_grid": 200/"n_grid": 50/' -e 's/"substep_dt": 2e-5/"substep_dt": 1e-4/' \
  -e 's/"default_camera_index": -1/"default_camera_index": 1/' \
  -e 's/"opacity_threshold": 0.02,/&\n    "sim_area": [0.0, 1.0, -1.0, 1.0, -1.0, 1.0],/' \
  "$src/tests/data/physgaussian/sand_collider.json" > "$dir/half.json"
"$mpiexec" -n 2 "$gen4d" run --physgaussian "$dir/half.json" --model-path "$dir/model" \
  --output-path "$dir/run" --set simulation.end_time=0.002 --set output.frame_interval=0.001 \
  --output-ply --mp4 > "$dir/run.log" 2>&1 || { cat "$dir/run.log"; fail "run --physgaussian"; }
run="$dir/run"; conv="$run/physgaussian"
[[ -s "$run/particles.h5" && -s "$conv/scenery.ply" && -s "$conv/sim_cameras.json" ]] ||
  fail "run outputs"
grep -qx 'scenery = "scenery.ply"' "$conv/deck.toml" || fail "deck: no scenery"
grep -qx 'camera = "sim_cameras.json:1"' "$conv/deck.toml" || fail "deck: not cameras.json's view 1"
# gs_simulation.py's images: 0000.png is the state after one frame; none of the rest state.
[[ -s "$run/0000.png" && -s "$run/0001.png" && ! -e "$run/0002.png" && ! -e "$run/png" ]] ||
  fail "images: $(ls "$run")"
size=$(od -An -tu1 -j16 -N8 "$run/0000.png" | awk '{print $3 * 256 + $4 "x" $7 * 256 + $8}')
[[ "$size" == "80x60" ]] || fail "image size $size, cameras.json's view 1 is 80x60"
# --output-ply: simulation_ply/sim_<frame, 10 digits>.ply for frames 0..2, float x y z of every
# particle.
n=$(sed -n 's/^mpm: \([0-9]*\) particles.*/\1/p' "$dir/run.log")
[[ -n "$n" && $(ls "$run/simulation_ply" | wc -l) -eq 3 ]] ||
  fail "simulation_ply: $(ls "$run/simulation_ply")"
want=$(printf 'ply\nformat binary_little_endian 1.0\nelement vertex %s\nproperty float x\nproperty float y\nproperty float z\nend_header' "$n")
for f in 0 1 2; do
  ply="$run/simulation_ply/sim_000000000$f.ply"
  header=$(head -c 200 "$ply" | sed -n '1,/^end_header$/p')
  [[ "$header" == "$want" ]] || fail "$ply: header $header"
  [[ $(stat -c %s "$ply") -eq $(( ${#want} + 1 + 12 * n )) ]] || fail "$ply: not $n points"
done
cmp -s "$run/simulation_ply/sim_0000000000.ply" "$run/simulation_ply/sim_0000000002.ply" &&
  fail "the particles did not move"
if command -v ffmpeg > /dev/null; then
  [[ -s "$run/output.mp4" ]] || fail "no output.mp4"
  if command -v ffprobe > /dev/null; then  # int(1 / frame_dt) = 25 frames per second, 2 frames
    probe=$(ffprobe -v error -count_frames -select_streams v:0 \
      -show_entries stream=r_frame_rate,nb_read_frames -of csv=p=0 "$run/output.mp4")
    [[ "$probe" == "25/1,2" ]] || fail "output.mp4: rate and frames $probe"
  fi
fi
# The converted deck run by itself at 1 rank draws the same first image (any rank count); without
# its scenery the image differs.
sed '/^scenery = /d' "$conv/deck.toml" > "$conv/no_scenery.toml"
for deck in deck no_scenery; do
  "$gen4d" run "$conv/$deck.toml" --out "$dir/$deck" --set simulation.end_time=0.001 \
    --set output.frame_interval=0.001 > "$dir/$deck.log" 2>&1 ||
    { cat "$dir/$deck.log"; fail "run $deck"; }
done
cmp -s "$dir/deck/0000.png" "$run/0000.png" || fail "1 and 2 ranks draw different images"
cmp -s "$dir/no_scenery/0000.png" "$run/0000.png" && fail "the scenery is not drawn"

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
expect2 "output-ply without physgaussian" "--output-ply" run "$conv/deck.toml" --output-ply \
  --out "$dir/bad"
sed 's/"default_camera_index": 1/"default_camera_index": 2/' "$dir/half.json" > "$dir/index.json"
expect2 "camera index" "default_camera_index" convert-physgaussian "$dir/index.json" \
  --model-path "$dir/model" -o "$dir/bad"
expect2 "missing scenery" "render.scenery" run "$conv/deck.toml" --out "$dir/bad" \
  --set 'render.scenery="missing.ply"'
expect2 "broken scenery" "render.scenery: $dir/badtype.json" run "$conv/deck.toml" --out "$dir/bad" \
  --set 'render.scenery="../../badtype.json"'
echo "1 passed, 0 failed"

#!/usr/bin/env bash
# The main job end to end, shortened: the embedded default scene (the trained donut as MPM
# jelly) at 1, 2 and 4 ranks renders identical PNG frames and writes identical deformed splats
# (3DGS PLY); a restart from a 2-rank checkpoint at 1 rank renders the same last frame; bad
# splat input is exit 2 naming the file, with nothing written.
set -u
gen4d="$1"; mpiexec="$2"; dir="$3"
rm -rf "$dir"; mkdir -p "$dir"
donut="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)/inputs/splats/donut.ply"
source "$(dirname "${BASH_SOURCE[0]}")/cli_common.sh"
{
  jelly_deck 2e-3 0.04 0.02 2e4 "$(printf 'type = "splats"\nfile = "%s"' "$donut")" fixed_corotated \
    "gravity = [0.0, 0.0, -9.81]"
  printf '[output]\nframe_interval = 0.02\n'
} > "$dir/noview.toml"
fail() { echo "FAIL $*"; exit 1; }
sets=(--set simulation.end_time=0.06 --set output.frame_interval=0.03
      --set output.progress_interval=100 --set render.width=96 --set render.height=72
      --set output.particles=ply --set render.video=none --set domain.voxel_size=0.016)
for np in 1 2 4; do
  "$mpiexec" -n $np "$gen4d" run --out "$dir/np$np" "${sets[@]}" > "$dir/np$np.log" 2>&1 ||
    { cat "$dir/np$np.log"; fail "run at $np ranks"; }
done
frames=$(ls "$dir/np1/png" | wc -l)
[[ $frames -eq 3 ]] || fail "expected 3 rendered frames, got $frames: $(ls "$dir/np1/png")"
for np in 2 4; do
  for f in "$dir"/np1/png/*.png; do
    cmp -s "$f" "$dir/np$np/png/$(basename "$f")" || fail "$(basename "$f") differs at $np ranks"
  done
  for f in "$dir"/np1/splats/*.ply; do
    cmp -s "$f" "$dir/np$np/splats/$(basename "$f")" || fail "$(basename "$f") differs at $np ranks"
  done
done
nply=$(ls "$dir/np1/splats" | wc -l)
[[ $nply -eq 3 ]] || fail "expected 3 splat PLYs, got $nply"
# The deformed splats are a valid 3DGS PLY: gen4d render reads them back.
"$gen4d" render "$dir/np1/splats/$(ls "$dir/np1/splats" | tail -1)" --out "$dir/last.png" \
  --width 64 --height 48 > "$dir/render.log" 2>&1 || { cat "$dir/render.log"; fail "render"; }
[[ -s "$dir/last.png" ]] || fail "no last.png"

# --mp4 on a splat deck without [render]: the auto camera frames it, and ffmpeg makes the video.
"$mpiexec" -n 2 "$gen4d" run "$dir/noview.toml" --out "$dir/mp4" --mp4 > "$dir/mp4.log" 2>&1 ||
  { cat "$dir/mp4.log"; fail "--mp4 run"; }
[[ $(ls "$dir/mp4/png" | wc -l) -eq 3 ]] || fail "--mp4 run: $(ls "$dir/mp4/png")"
if command -v ffmpeg > /dev/null; then
  [[ -s "$dir/mp4/render.mp4" ]] || fail "no render.mp4"
else
  grep -q "ffmpeg is not on PATH" "$dir/mp4.log" || fail "no ffmpeg note"
fi

# Restart at 1 rank from the 2-rank run's first checkpoint: the same last image.
"$mpiexec" -n 2 "$gen4d" run --out "$dir/cut" "${sets[@]}" --set output.checkpoint_every=20 \
  > "$dir/cut.log" 2>&1 || { cat "$dir/cut.log"; fail "run with checkpoints"; }
ck=$(ls "$dir/cut"/checkpoint_*.h5 | head -1)
rm -rf "$dir/cut/png" "$dir/cut/splats"
"$gen4d" restart "$ck" > "$dir/restart.log" 2>&1 || { cat "$dir/restart.log"; fail "restart"; }
last=$(ls "$dir/np1/png" | tail -1)
cmp -s "$dir/np1/png/$last" "$dir/cut/png/$last" || fail "restarted $last differs"

# Bad splat files: exit 2, the file named, no output folder.
printf 'ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\nend_header\n' \
  > "$dir/bad.ply"
jelly_deck 1e-3 0.01 0.02 1e4 'type = "splats"
file = "bad.ply"' fixed_corotated > "$dir/bad.toml"
err=$("$gen4d" run "$dir/bad.toml" --out "$dir/bad" 2>&1 >/dev/null); code=$?
[[ $code -eq 2 && "$err" == *"bad.ply"* && ! -e "$dir/bad" ]] ||
  fail "bad splat file: exit $code, $err"
echo "1 passed, 0 failed"

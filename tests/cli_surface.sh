#!/usr/bin/env bash
# Surface sequence end to end: the jelly board at 2 ranks writes surface/surface_*.ply next to
# frames.h5, `gen4d preview` renders them (and still renders voxels from frames.h5), --mp4
# without ffmpeg is a note, and bad surface input is exit 2 with nothing written.
set -u
gen4d="$1"; mpiexec="$2"; dir="$3"
board="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)/inputs/jelly_board.toml"  # an ElastoGen scene
rm -rf "$dir"; mkdir -p "$dir"
fail() { echo "FAIL $*"; exit 1; }
sets=(--set simulation.end_time=0.04 --set output.frame_interval=0.02
      --set output.progress_interval=100 --set output.surface=ply)
"$mpiexec" -n 2 "$gen4d" run "$board" --out "$dir/run" "${sets[@]}" > "$dir/run.log" 2>&1 ||
  { cat "$dir/run.log"; fail "run"; }
for f in 0 1 2; do
  [[ -s "$dir/run/surface/surface_00000$f.ply" ]] || fail "no surface file for frame $f"
done
[[ $(ls -A "$dir/run/surface" | wc -l) -eq 3 ]] || fail "unexpected files: $(ls -A "$dir/run/surface")"
grep -q "surface: voxel boundary with" "$dir/run.log" || fail "no surface line in the log"
head -c 40 "$dir/run/surface/surface_000002.ply" | grep -q "binary_little_endian" || fail "header"

"$gen4d" preview "$dir/run" --out "$dir/png" --frames all --width 96 --height 72 \
  > "$dir/preview.log" 2>&1 || { cat "$dir/preview.log"; fail "preview"; }
for f in 0 1 2; do [[ -s "$dir/png/surface_00000$f.png" ]] || fail "no surface_00000$f.png"; done
"$gen4d" preview "$dir/run/frames.h5" --mode voxels --out "$dir/png" --frames -1 --width 96 \
  --height 72 > /dev/null 2>&1 || fail "voxel preview"
[[ -s "$dir/png/frame_000002.png" ]] || fail "no frame_000002.png"
"$gen4d" preview "$dir/run" --out "$dir/mp4" --mp4 --width 32 --height 32 > "$dir/mp4.log" 2>&1 ||
  { cat "$dir/mp4.log"; fail "--mp4"; }
if command -v ffmpeg > /dev/null; then
  [[ -s "$dir/mp4/preview.mp4" ]] || fail "no preview.mp4"
else
  grep -q "ffmpeg is not on PATH" "$dir/mp4.log" || fail "no ffmpeg note"
fi
[[ -s "$dir/mp4/surface_000002.png" ]] || fail "--mp4 did not render every frame"

err=$("$gen4d" run "$board" --out "$dir/bad" --set output.surface=stl 2>&1 >/dev/null); code=$?
[[ $code -eq 2 && "$err" == *"output.surface"* && ! -e "$dir/bad" ]] ||
  fail "bad output.surface: exit $code, $err"
err=$("$gen4d" run "$board" --out "$dir/bad" --set output.surface_source=mesh 2>&1 >/dev/null); code=$?
[[ $code -eq 2 && "$err" == *"surface_source"* && ! -e "$dir/bad" ]] ||
  fail "surface_source = mesh on a box: exit $code, $err"
mkdir -p "$dir/nosurface" && cp "$dir/run/frames.h5" "$dir/nosurface/"
err=$("$gen4d" preview "$dir/nosurface" --mode surface --out "$dir/nosurface/png" 2>&1 >/dev/null)
code=$?
[[ $code -eq 2 && "$err" == *"nosurface/surface"* ]] || fail "surface mode without files: $code $err"
echo "1 passed, 0 failed"

#!/usr/bin/env bash
# gen4d render end to end: the donut from a cameras.json view at 1 and 2 ranks (identical PNGs),
# an orbit view, and bad inputs (exit 2, one error line naming the file or option, no output).
set -u
gen4d="$1"; mpiexec="$2"; dir="$3"; ply="$4"
rm -rf "$dir"; mkdir -p "$dir/out"
fails=0
fail() { echo "FAIL $*"; fails=$((fails + 1)); }
# Width and height of a PNG from its IHDR chunk.
png_size() { od -An -tu1 -j16 -N8 "$1" | awk '{print $1*16777216+$2*65536+$3*256+$4 "x" $5*16777216+$6*65536+$7*256+$8}'; }
is_png() { [[ -f "$1" && "$(od -An -tx1 -N8 "$1" | tr -d ' \n')" == "89504e470d0a1a0a" ]]; }

# Two views of the donut (about 0.2 wide around the origin, z up): from -y and from above.
cat > "$dir/cameras.json" <<'JSON'
[
  {"id": 0, "img_name": "top", "width": 320, "height": 240, "position": [0, 0, 0.6],
   "rotation": [[1, 0, 0], [0, -1, 0], [0, 0, -1]], "fy": 300, "fx": 300},
  {"id": 1, "img_name": "side", "width": 640, "height": 480, "position": [0, -0.5, 0.04],
   "rotation": [[1, 0, 0], [0, 0, 1], [0, -1, 0]], "fy": 600, "fx": 600}
]
JSON
"$gen4d" render "$ply" --camera "$dir/cameras.json:1" --out "$dir/side1.png" --bg 1,1,1 \
  || fail "render at 1 rank"
"$mpiexec" -n 2 "$gen4d" render "$ply" --camera "$dir/cameras.json:1" --out "$dir/side2.png" \
  --bg 1,1,1 || fail "render at 2 ranks"
is_png "$dir/side1.png" || fail "side1.png is no PNG"
[[ "$(png_size "$dir/side1.png")" == "640x480" ]] || fail "side1.png is $(png_size "$dir/side1.png")"
cmp -s "$dir/side1.png" "$dir/side2.png" || fail "1 and 2 ranks differ"
"$gen4d" render "$ply" --camera "$dir/cameras.json" --out "$dir/top.png" || fail "index 0"
[[ "$(png_size "$dir/top.png")" == "320x240" ]] || fail "top.png is $(png_size "$dir/top.png")"
# A white background changes the image; the donut covers a good part of the side view, so the
# PNG of the white-background render is far from an empty image's few hundred bytes.
"$gen4d" render "$ply" --camera "$dir/cameras.json:1" --out "$dir/side_black.png" || fail "black"
cmp -s "$dir/side1.png" "$dir/side_black.png" && fail "the background is ignored"
(( $(stat -c %s "$dir/side1.png") > 20000 )) || fail "side1.png is nearly empty"
# Default orbit framing and explicit orbit options.
"$gen4d" render "$ply" --out "$dir/orbit.png" --width 200 --height 150 || fail "default orbit"
"$mpiexec" -n 2 "$gen4d" render "$ply" --out "$dir/orbit2.png" --width 200 --height 150 \
  --azimuth 45 --elevation 20 || fail "orbit at 2 ranks"
cmp -s "$dir/orbit.png" "$dir/orbit2.png" || fail "orbit at 1 and 2 ranks differ"
"$gen4d" render "$ply" --out "$dir/orbit3.png" --orbit-center 0,0,0.04 --radius 0.6 \
  --azimuth 200 --elevation 60 --fov 40 --width 120 --height 90 || fail "orbit options"
[[ "$(png_size "$dir/orbit3.png")" == "120x90" ]] || fail "orbit3.png size"

expect_fail() {  # name, expected message fragment, command...
  local name="$1" frag="$2"; shift 2
  local err; err=$("$@" 2>&1 >/dev/null); local code=$?
  local lines; lines=$(printf "%s\n" "$err" | grep -c "error")
  if [[ $code -ne 2 || "$err" != *"$frag"* || $lines -ne 1 ]]; then
    fail "$name: exit $code, stderr: $err"
  else
    echo "ok   $name: $err"
  fi
}
out="$dir/out/image.png"
head -c 200 "$ply" > "$dir/truncated.ply"
echo "not a ply" > "$dir/garbage.ply"
sed 's/"fx": 600/"fz": 600/' "$dir/cameras.json" > "$dir/nofx.json"
sed 's/"width": 640,/"width": 640,,/' "$dir/cameras.json" > "$dir/broken.json"
expect_fail "missing ply" "nothere.ply" "$gen4d" render "$dir/nothere.ply" --camera "$dir/cameras.json" --out "$out"
expect_fail "truncated ply" "truncated.ply" "$gen4d" render "$dir/truncated.ply" --camera "$dir/cameras.json" --out "$out"
expect_fail "garbage ply" "garbage.ply" "$gen4d" render "$dir/garbage.ply" --out "$out"
expect_fail "missing key" "nofx.json" "$gen4d" render "$ply" --camera "$dir/nofx.json:1" --out "$out"
expect_fail "missing key names it" '"fx"' "$gen4d" render "$ply" --camera "$dir/nofx.json:1" --out "$out"
expect_fail "malformed json" "broken.json:4" "$gen4d" render "$ply" --camera "$dir/broken.json" --out "$out"
expect_fail "index out of range" "out of range" "$gen4d" render "$ply" --camera "$dir/cameras.json:2" --out "$out"
expect_fail "missing camera file" "nocams.json" "$gen4d" render "$ply" --camera "$dir/nocams.json" --out "$out"
expect_fail "bad bg" "--bg" "$gen4d" render "$ply" --bg 1,2 --out "$out"
expect_fail "bg out of range" "--bg" "$gen4d" render "$ply" --bg 1,2,0.5 --out "$out"
expect_fail "camera and orbit" "command line" "$gen4d" render "$ply" --camera "$dir/cameras.json" --azimuth 3 --out "$out"
expect_fail "np2 bad camera" "nofx.json" "$mpiexec" -n 2 "$gen4d" render "$ply" --camera "$dir/nofx.json:1" --out "$out"
[[ -z "$(ls -A "$dir/out")" ]] || fail "bad inputs wrote files: $(ls -A "$dir/out")"
if [[ $fails -ne 0 ]]; then echo "$fails failure(s)"; exit 1; fi
echo "all render CLI checks passed"

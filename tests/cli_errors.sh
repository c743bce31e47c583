#!/usr/bin/env bash
# Every malformed input must give exit code 2, one error line naming the culprit, and leave
# an existing output directory exactly as it was.
set -u
gen4d="$1"; mpiexec="$2"; dir="$3"
rm -rf "$dir"; mkdir -p "$dir/out"
echo "precious" > "$dir/out/frames.h5"
fails=0; passes=0
source "$(dirname "${BASH_SOURCE[0]}")/cli_common.sh"
good=$(jelly_deck 0.01 0.02 0.05 1e5 "$(box "[0, 0, 0]" "[0.2, 0.1, 0.1]")")
expect_fail() {  # name, expected message fragment, command...
  local name="$1" frag="$2"; shift 2
  local err; err=$("$@" 2>&1 >/dev/null); local code=$?
  local lines; lines=$(printf "%s\n" "$err" | grep -c "error")
  if [[ $code -ne 2 || "$err" != *"$frag"* || $lines -ne 1 ]]; then
    echo "FAIL $name: exit $code, stderr: $err"; fails=$((fails + 1))
  else
    echo "ok   $name: $err"; passes=$((passes + 1))
  fi
}
deck() { printf "%s\n" "$2" > "$dir/$1"; echo "$dir/$1"; }
expect_fail "negative modulus" "youngs_modulus" "$gen4d" run "$(deck neg.toml "${good/1e5/-1e5}")" --out "$dir/out"
expect_fail "poisson 0.5" "poisson_ratio" "$gen4d" run "$(deck nu.toml "${good/0.3/0.5}")" --out "$dir/out"
expect_fail "zero dt" "dt" "$gen4d" run "$(deck dt.toml "${good/dt = 0.01/dt = 0}")" --out "$dir/out"
expect_fail "unknown key" "densty" "$gen4d" run "$(deck typo.toml "${good/density/densty}")" --out "$dir/out"
expect_fail "wrong type" "voxel_size" "$gen4d" run "$(deck type.toml "${good/0.05/\"big\"}")" --out "$dir/out"
expect_fail "syntax" "syntax" "$gen4d" run "$(deck syntax.toml "${good/\[material\]/[material}")" --out "$dir/out"
expect_fail "missing mesh" "nothere.obj" "$gen4d" run "$(deck mesh.toml "$(printf "%s" "$good" | sed 's|type = "box"|type = "mesh"\nfile = "nothere.obj"|; /^lo = /d; /^hi = /d')")" --out "$dir/out"
printf 'v 0 0 0\nv 1 0 x\nf 1 2 3\n' > "$dir/bad.obj"
expect_fail "malformed obj" "bad.obj:2" "$gen4d" run "$(deck badobj.toml "$(printf "%s" "$good" | sed 's|type = "box"|type = "mesh"\nfile = "bad.obj"|; /^lo = /d; /^hi = /d')")" --out "$dir/out"
echo "not a vdb" > "$dir/x.vdb"
expect_fail "bad vdb" "x.vdb" "$gen4d" run "$(deck vdb.toml "$(printf "%s" "$good" | sed 's|type = "box"|type = "vdb"\nfile = "x.vdb"|; /^lo = /d; /^hi = /d')")" --out "$dir/out"
expect_fail "bad --set" "material.youngs_modulus" "$gen4d" run "$(deck ok.toml "$good")" --out "$dir/out" --set material.youngs_modulus=abc
expect_fail "existing results" "--overwrite" "$gen4d" run "$(deck ok2.toml "$good")" --out "$dir/out"
echo "garbage" > "$dir/ck.h5"
expect_fail "foreign checkpoint" "ck.h5" "$gen4d" restart "$dir/ck.h5" --out "$dir/out"
head -c 300 "$dir/ok.toml" > "$dir/trunc.h5"
expect_fail "truncated checkpoint" "trunc.h5" "$gen4d" restart "$dir/trunc.h5" --out "$dir/out"
expect_fail "bad option" "command line" "$gen4d" run --bogus
expect_fail "np2 bad deck" "youngs_modulus" "$mpiexec" -n 2 "$gen4d" run "$dir/neg.toml" --out "$dir/out"
if [[ "$(cat "$dir/out/frames.h5")" != "precious" || $(ls "$dir/out" | wc -l) -ne 1 ]]; then
  echo "FAIL output directory was modified: $(ls "$dir/out")"; fails=$((fails + 1))
fi
# A good deck runs, exits 0 and writes frames, xdmf and a checkpoint.
"$gen4d" run "$dir/ok.toml" --out "$dir/good" >/dev/null 2>&1 || { echo "FAIL good deck"; fails=$((fails + 1)); }
for f in frames.h5 frames.xdmf checkpoint_00000002.h5; do
  [[ -f "$dir/good/$f" ]] || { echo "FAIL missing $f"; fails=$((fails + 1)); }
done
"$gen4d" info | grep -q "PETSc" || { echo "FAIL info"; fails=$((fails + 1)); }
echo "$passes passed, $fails failed"
[[ $fails -eq 0 ]]

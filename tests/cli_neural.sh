#!/usr/bin/env bash
# gen4d train-material / make-material / train-generator: bad arguments give exit code 2 and
# one error line naming the option or file, and leave no output file; short good runs work.
set -u
gen4d="$1"; dir="$2"; generator="$3"
rm -rf "$dir"; mkdir -p "$dir"
fails=0; passes=0
expect_fail() {  # name, expected message fragment, output that must not appear, command...
  local name="$1" frag="$2" out="$3"; shift 3
  local err; err=$("$@" 2>&1 >/dev/null); local code=$?
  local lines; lines=$(printf "%s\n" "$err" | grep -c "error")
  if [[ $code -ne 2 || "$err" != *"$frag"* || $lines -ne 1 || -e "$out" ]]; then
    echo "FAIL $name: exit $code, stderr: $err"; fails=$((fails + 1))
  else
    echo "ok   $name: $err"; passes=$((passes + 1))
  fi
}
expect_ok() {  # name, output file, command...
  local name="$1" out="$2"; shift 2
  if "$@" >"$dir/$name.log" 2>&1 && [[ -s "$out" ]]; then
    echo "ok   $name"; passes=$((passes + 1))
  else
    echo "FAIL $name: $(tail -3 "$dir/$name.log")"; fails=$((fails + 1))
  fi
}
o="$dir/mtl.h5"
expect_fail "unknown law" "--law" "$o" "$gen4d" train-material --law rubber --nu 0.3 -o "$o"
expect_fail "nu 0.5" "--nu" "$o" "$gen4d" train-material --law stvk --nu 0.5 -o "$o"
expect_fail "negative nu" "--nu" "$o" "$gen4d" make-material --law stvk --nu -0.1 -o "$o"
expect_fail "negative E" "--E" "$o" "$gen4d" make-material --law stvk --nu 0.3 --E -5 -o "$o"
expect_fail "missing -o" "--out" "$o" "$gen4d" train-material --law stvk --nu 0.3
expect_fail "bad hidden" "--hidden" "$o" "$gen4d" train-material --law stvk --nu 0.3 --hidden 24,x -o "$o"
expect_fail "no such dir" "nodir" "$dir/nodir/m.h5" "$gen4d" train-material --law stvk --nu 0.3 -o "$dir/nodir/m.h5"
expect_fail "missing generator" "nothere.h5" "$o" "$gen4d" make-material --law stvk --nu 0.3 --generator "$dir/nothere.h5" -o "$o"
echo "not hdf5" > "$dir/corrupt.h5"
expect_fail "corrupt generator" "corrupt.h5" "$o" "$gen4d" make-material --law stvk --nu 0.3 --generator "$dir/corrupt.h5" -o "$o"
expect_fail "corrupt dataset" "corrupt.h5" "$dir/g.h5" "$gen4d" train-generator --dataset "$dir/corrupt.h5" --out "$dir/g.h5"
expect_ok "train-material" "$o" "$gen4d" train-material --law corotated --nu 0.2 --hidden 8 --steps 100 --lbfgs-steps 10 -o "$o"
if [[ -f "$generator" ]]; then
  expect_ok "make-material" "$dir/gen.h5" "$gen4d" make-material --law neo_hookean --E 1e5 --nu 0.37 --finetune-steps 10 --generator "$generator" -o "$dir/gen.h5"
fi
echo "$passes passed, $fails failed"
[[ $fails -eq 0 ]]

#!/usr/bin/env bash
# A full disk during a frame write and during a checkpoint write of a 2-rank run: the run
# stops with exit 1 and one error naming the file and the cause, the frames written before
# stay readable, and no partial checkpoint is left under any name.
# The disk is a small tmpfs mounted for the test (root); without mount rights, a file size
# limit (ulimit -f) stands in for it; with neither the test is skipped (exit 77).
set -u
gen4d="$1"; mpiexec="$2"; dir="$3"
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
# shellcheck source=tests/cli_faults_common.sh
source "$here/cli_faults_common.sh"
board="$here/../inputs/jelly_board.toml"
if mountpoint -q "$dir/disk" 2> /dev/null; then umount "$dir/disk"; fi
rm -rf "$dir"; mkdir -p "$dir/disk"
mounted=0
cleanup() { if [[ $mounted -eq 1 ]]; then umount "$dir/disk"; fi; }
trap cleanup EXIT
common=(--set output.surface=\"none\" --set output.checkpoint_keep=100)
# Case "frame": a frame every step, no periodic checkpoint; case "checkpoint": frames only at the
# start and the end, a checkpoint every 2 steps.
frame_sets=(--set simulation.end_time=0.06 --set output.frame_interval=0.01 --set output.checkpoint_every=0)
ckpt_sets=(--set simulation.end_time=0.04 --set output.frame_interval=1 --set output.checkpoint_every=2)

# The sizes of the files on an ordinary disk.
"$mpiexec" -n 2 "$gen4d" run "$board" --out "$dir/ref_frame" "${common[@]}" "${frame_sets[@]}" \
  > "$dir/ref_frame.log" 2>&1 || { echo "FAIL reference run"; cat "$dir/ref_frame.log"; exit 1; }
"$mpiexec" -n 2 "$gen4d" run "$board" --out "$dir/ref_ckpt" "${common[@]}" "${ckpt_sets[@]}" \
  > "$dir/ref_ckpt.log" 2>&1 || { echo "FAIL reference run"; cat "$dir/ref_ckpt.log"; exit 1; }
frames_size=$(stat -c %s "$dir/ref_frame/frames.h5")                 # 7 frames
ckpt_size=$(stat -c %s "$dir/ref_ckpt/checkpoint_00000002.h5")
first_size=$(stat -c %s "$dir/ref_ckpt/frames.h5")                   # 2 frames
echo "reference sizes: frames.h5 of 7 frames $frames_size B, of 2 frames $first_size B, checkpoint $ckpt_size B"

# run_full CASE BYTES SETS...: the run of CASE with BYTES of disk; its exit code.
run_full() {
  local name=$1 bytes=$2
  shift 2
  local out="$dir/disk/$name"
  if [[ $mounted -eq 1 ]]; then
    umount "$dir/disk"; mounted=0
  fi
  if mount -t tmpfs -o "size=$bytes" gen4d-test-disk "$dir/disk" 2> "$dir/mount.log"; then
    mounted=1; how="a tmpfs of $bytes bytes"
    "$mpiexec" -n 2 "$gen4d" run "$board" --out "$out" "${common[@]}" "$@" > "$dir/$name.log" 2>&1
  elif (ulimit -f $((bytes / 1024))) 2> /dev/null; then
    # The limit for the ranks alone (mpiexec's own shared-memory files are larger), and no
    # shared-memory transport, whose segment files would pass it.
    how="ulimit -f $((bytes / 1024)) (mount: $(cat "$dir/mount.log"))"
    OMPI_MCA_btl=self,tcp "$mpiexec" -n 2 bash -c "ulimit -f $((bytes / 1024)); exec \"\$0\" \"\$@\"" \
      "$gen4d" run "$board" --out "$out" "${common[@]}" "$@" > "$dir/$name.log" 2>&1
  else
    echo "SKIP neither a tmpfs mount nor ulimit -f is available"; exit 77
  fi
}

# expect_failure CASE FILE: exit 1 and one error line naming FILE and the lack of space.
expect_failure() {
  local name=$1 file=$2 code=$3 log="$dir/$1.log"
  echo "$name: $how: exit $code; $(grep -m1 'gen4d: error' "$log")"
  [[ $code -eq 1 ]] || { echo "FAIL $name: exit $code, expected 1"; cat "$log"; exit 1; }
  grep -E "error.*$file.*(no space left on device|file size limit)" "$log" > /dev/null ||
    { echo "FAIL $name: no error naming $file and the cause"; cat "$log"; exit 1; }
}

# A frame write runs out of space: room for about half the frames.
run_full frame $(( (frames_size / 2 + 4095) / 4096 * 4096 )) "${frame_sets[@]}"
expect_failure frame "frames.h5" $?
kept=$(h5_check "$dir/disk/frame/frames.h5") || { echo "FAIL frames.h5 unreadable after the failure"; exit 1; }
echo "$kept"
[[ $(awk '{ print $2 }' <<< "$kept") -ge 2 ]] || { echo "FAIL the run stopped before it had written frames"; exit 1; }
if compgen -G "$dir/disk/frame/checkpoint_*" > /dev/null || compgen -G "$dir/disk/frame/.checkpoint_*" > /dev/null; then
  echo "FAIL checkpoint files left: $(ls -a "$dir/disk/frame")"; exit 1
fi

# A checkpoint write runs out of space: room for the first frame and half a checkpoint. A file
# size limit holds each file alone, and the frames file is larger than a checkpoint: that case
# needs the small disk.
if [[ $mounted -eq 0 ]]; then
  echo "checkpoint case not run: no tmpfs mount (ulimit -f cannot stop a checkpoint here)"
  echo "1 passed, 0 failed"; exit 0
fi
run_full checkpoint $(( (first_size / 2 + ckpt_size / 2 + 4095) / 4096 * 4096 + 4096 )) "${ckpt_sets[@]}"
expect_failure checkpoint "checkpoint_00000002.h5" $?
h5_check "$dir/disk/checkpoint/frames.h5" || { echo "FAIL frames.h5 unreadable after the failure"; exit 1; }
if compgen -G "$dir/disk/checkpoint/checkpoint_*" > /dev/null || compgen -G "$dir/disk/checkpoint/.checkpoint_*" > /dev/null; then
  echo "FAIL checkpoint files left: $(ls -a "$dir/disk/checkpoint")"; exit 1
fi
echo "1 passed, 0 failed"

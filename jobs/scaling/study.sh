#!/usr/bin/env bash
# Scaling study as a user runs it: strong and weak scaling of ElastoGen (`gen4d run` of a
# generated box deck), MPM (bench_mpm) and the renderer (bench_render) at 1, 2 and 4 ranks
# (ranks above the node's cores are marked oversubscribed), MPI latency / bandwidth /
# allreduce (bench_mpi), and the parallel HDF5 checkpoint write of `gen4d run` against dd
# in the same folder. Then jobs/scaling/model.py collects everything into scaling.csv,
# fits the performance model, projects it to 1,024 ranks and draws the plots.
#
#   jobs/scaling/study.sh [--out DIR] [--size full|tiny] [--ranks "1 2 4"]
#                         [--codes "elastogen mpm render"] [--no-checkpoint] [--no-model]
#
# Every rank runs one thread (OMP_NUM_THREADS=1), so the rank count is the core count used.
# Binaries: $GEN4D_BUILD/drivers/{gen4d,bench_mpm,bench_render,bench_mpi} (GEN4D_BUILD
# defaults to the build folder beside jobs/); each can be overridden by the environment
# variables GEN4D, BENCH_MPM, BENCH_RENDER, BENCH_MPI; MPIEXEC picks the launcher.
# Full size takes about 6-8 minutes on a quiet 2-core machine; tiny (the test) under a minute.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
# shellcheck source=/dev/null
source "$here/../env.sh"

out="scaling-out"
size="full"
ranks="1 2 4"
codes="elastogen mpm render"
checkpoint=1
model=1
die() { echo "study.sh: $*" >&2; exit 2; }
while [[ $# -gt 0 ]]; do
  case "$1" in
    --out) [[ $# -ge 2 ]] || die "--out needs a folder"; out="$2"; shift 2 ;;
    --size) [[ $# -ge 2 ]] || die "--size needs full or tiny"; size="$2"; shift 2 ;;
    --ranks) [[ $# -ge 2 ]] || die "--ranks needs a list"; ranks="$2"; shift 2 ;;
    --codes) [[ $# -ge 2 ]] || die "--codes needs a list"; codes="$2"; shift 2 ;;
    --no-checkpoint) checkpoint=0; shift ;;
    --no-model) model=0; shift ;;
    -h|--help) sed -n '2,17p' "${BASH_SOURCE[0]}"; exit 0 ;;
    *) die "unknown argument '$1' (see --help)" ;;
  esac
done
for r in $ranks; do
  [[ "$r" =~ ^[1-9][0-9]*$ ]] || die "--ranks: '$r' is not a positive integer"
done
for c in $codes; do
  case "$c" in elastogen|mpm|render) ;; *) die "--codes: unknown code '$c' (elastogen, mpm, render)" ;; esac
done

# Problem sizes. ElastoGen: voxels of a cube (strong) and per rank of a bar of cubes along x
# (weak); MPM: particles; renderer: synthetic SH-3 splats at 1920x1080. Weak sizes are per rank.
case "$size" in
  full)
    eg_strong=40 eg_weak=26 eg_steps=6 eg_outer=3 eg_sweeps=40 eg_modes=6
    mpm_strong=400000 mpm_weak=200000 mpm_substeps=10
    render_strong=200000 render_weak=100000 render_frames=2
    ck_cells=112 ck_steps=3
    mpi_max=16777216 mpi_repeats=5 mpi_trips=10000 mpi_calls=2000 ;;
  tiny)
    eg_strong=8 eg_weak=6 eg_steps=2 eg_outer=2 eg_sweeps=8 eg_modes=6
    mpm_strong=4000 mpm_weak=2000 mpm_substeps=2
    render_strong=2000 render_weak=1000 render_frames=1
    ck_cells=10 ck_steps=6
    mpi_max=65536 mpi_repeats=1 mpi_trips=200 mpi_calls=100 ;;
  *) die "--size: '$size' is not full or tiny" ;;
esac

GEN4D="${GEN4D:-$GEN4D_BUILD/drivers/gen4d}"
BENCH_MPM="${BENCH_MPM:-$GEN4D_BUILD/drivers/bench_mpm}"
BENCH_RENDER="${BENCH_RENDER:-$GEN4D_BUILD/drivers/bench_render}"
BENCH_MPI="${BENCH_MPI:-$GEN4D_BUILD/drivers/bench_mpi}"
MPIEXEC="${MPIEXEC:-mpirun}"
need=("$BENCH_MPI")
[[ " $codes " == *" elastogen "* || $checkpoint == 1 ]] && need+=("$GEN4D")
[[ " $codes " == *" mpm "* ]] && need+=("$BENCH_MPM")
[[ " $codes " == *" render "* ]] && need+=("$BENCH_RENDER")
for b in "${need[@]}"; do
  [[ -x "$b" ]] || die "$b: not built (cmake --build \"\$GEN4D_BUILD\" --target $(basename "$b"))"
done
command -v "$MPIEXEC" > /dev/null || die "$MPIEXEC: no MPI launcher (set MPIEXEC)"

# The node's cores (nproc alone would answer OMP_NUM_THREADS).
cores=$(env -u OMP_NUM_THREADS -u OMP_THREAD_LIMIT nproc)
export OMP_NUM_THREADS=1 OMP_WAIT_POLICY=passive
mkdir -p "$out/raw" "$out/bin"
out="$(cd "$out" && pwd)"
# Private copies: a rebuild of the build folder during the study cannot swap a binary mid-way.
for v in GEN4D BENCH_MPM BENCH_RENDER BENCH_MPI; do
  if [[ -x "${!v}" ]]; then
    cp "${!v}" "$out/bin/"
    printf -v "$v" "%s" "$out/bin/$(basename "${!v}")"
  fi
done
runs="$out/runs.tsv"
printf "code\tkind\tranks\toversubscribed\tsize\tunit\tsteps\tload1\tload5\tfile\n" > "$runs"

load() { cut -d' ' -f"$1" /proc/loadavg; }

# run CODE KIND NP SIZE UNIT STEPS FILE COMMAND...: one measured case, its output in FILE.
run() {
  local code=$1 kind=$2 np=$3 sz=$4 unit=$5 steps=$6 file=$7
  shift 7
  local l1 l5 over=0
  l1=$(load 1) l5=$(load 2)
  ((np > cores)) && over=1
  printf "  %-9s %-6s np %-2s %s %s%s (load %s)\n" "$code" "$kind" "$np" "$sz" "$unit" \
    "$([[ $over == 1 ]] && echo ", oversubscribed")" "$l1"
  # JSON on stdout stays apart from warnings on stderr; a log keeps both.
  local err="$out/raw/$file"
  [[ $file == *.json ]] && err="$out/raw/$file.err"
  if ! "$MPIEXEC" -np "$np" "$@" > "$out/raw/$file" 2>> "$err"; then
    tail -n 20 "$err" >&2
    echo "study.sh: $code $kind at $np ranks failed (full output: $out/raw/$file)" >&2
    exit 1
  fi
  printf "%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\n" "$code" "$kind" "$np" "$over" "$sz" "$unit" \
    "$steps" "$l1" "$l5" "$file" >> "$runs"
}

# eg_deck FILE NX NY NZ STEPS OUTER SWEEPS MODES CHECKPOINT_EVERY: a clamped box of NX x NY x NZ
# voxels sagging under gravity, with a fixed amount of work per step (OUTER loops of SWEEPS
# Jacobi sweeps: the tolerances are out of reach and no extra loops are allowed).
eg_deck() {
  local h=0.02
  cat > "$1" <<EOF
[simulation]
name = "scaling-box"
dt = 0.01
end_time = $(awk -v s="$5" 'BEGIN{printf "%.4f", s * 0.01}')
gravity = [0.0, 0.0, -9.81]

[domain]
voxel_size = $h
padding = 1

[[geometry]]
type = "box"
lo = [0.0, 0.0, 0.0]
hi = [$(awk -v a="$2" -v b="$3" -v c="$4" -v h="$h" 'BEGIN{printf "%.6f, %.6f, %.6f", a*h, b*h, c*h}')]

[material]
model = "fixed_corotated"
target = "arap"
youngs_modulus = 2.0e5
poisson_ratio = 0.35
density = 1000.0

[solver]
relaxation = "jacobi"
subspace_modes = $8
max_outer = $6
outer_tolerance = 1e-300
max_sweeps = $7
inner_tolerance = 1e-300
max_extra_outer = 0
anderson_depth = 0

[[fixed]]
lo = [-1.0, -1.0, -1.0]
hi = [$(awk -v h="$h" 'BEGIN{printf "%.6f", 0.5 * h}'), 100.0, 100.0]

[output]
frame_interval = 1000.0
checkpoint_every = $9
progress_interval = 1e9
EOF
}

echo "scaling study: size $size, ranks $ranks, $cores cores (ranks above that oversubscribed)"
echo "  output: $out"
uptime > "$out/uptime_start.txt"
printf "key\tvalue\nsize\t%s\neg_outer\t%s\neg_sweeps\t%s\neg_modes\t%s\ncores\t%s\n" \
  "$size" "$eg_outer" "$eg_sweeps" "$eg_modes" "$cores" > "$out/params.tsv"

# 1. MPI transport (shared memory on one node) at every rank count >= 2.
for np in $ranks; do
  ((np >= 2)) || continue
  run mpi pingpong "$np" "$mpi_max" bytes 1 "mpi_np$np.json" \
    "$BENCH_MPI" --max-bytes "$mpi_max" --repeats "$mpi_repeats" --max-round-trips "$mpi_trips" \
    --collective-calls "$mpi_calls"
done

# 2. The codes, strong then weak.
for code in $codes; do
  for kind in strong weak; do
    for np in $ranks; do
      tag="${code}_${kind}_np$np"
      case "$code" in
        elastogen)
          if [[ $kind == strong ]]; then nx=$eg_strong ny=$eg_strong nz=$eg_strong
          else nx=$((eg_weak * np)) ny=$eg_weak nz=$eg_weak; fi
          deck="$out/raw/$tag.toml"
          eg_deck "$deck" "$nx" "$ny" "$nz" "$eg_steps" "$eg_outer" "$eg_sweeps" "$eg_modes" 0
          run elastogen "$kind" "$np" $((nx * ny * nz)) voxels "$eg_steps" "$tag.log" \
            "$GEN4D" run "$deck" --out "$out/raw/$tag.out" --overwrite
          rm -rf "$out/raw/$tag.out" ;;
        mpm)
          n=$mpm_strong
          [[ $kind == weak ]] && n=$((mpm_weak * np))
          run mpm "$kind" "$np" "$n" particles "$mpm_substeps" "$tag.json" \
            "$BENCH_MPM" --particles "$n" --substeps "$mpm_substeps" --stream-n 1000000 ;;
        render)
          n=$render_strong
          [[ $kind == weak ]] && n=$((render_weak * np))
          run render "$kind" "$np" "$n" splats "$render_frames" "$tag.json" \
            "$BENCH_RENDER" --donut none --splats "$n" --frames "$((2 * render_frames))" ;;
      esac
    done
  done
done

# 3. Communication counts of a real run, to check the ones the model takes from the code: a
#    PMPI interposer (mpi_count.c) counts collectives and point-to-point messages and bytes at
#    2 ranks; two runs differing only in their step count give the counts per step.
mpicc_bin="${MPICC:-mpicc}"
if command -v "$mpicc_bin" > /dev/null; then
  "$mpicc_bin" -shared -fPIC -O2 -o "$out/raw/libmpi_count.so" "$here/mpi_count.c"
  printf "code\tsteps\trank\tallgather\tallreduce\talltoall\talltoallv\tother\tp2p_messages\tp2p_bytes\tcells\n" \
    > "$out/counts.tsv"
  for code in $codes; do
    [[ $code == render ]] && continue  # one exchange and one gather a frame: nothing to count
    for steps in 2 4; do
      tag="count_${code}_$steps"
      rm -f "$out/raw/$tag".*
      if [[ $code == elastogen ]]; then
        n=$eg_weak
        eg_deck "$out/raw/$tag.toml" $((2 * n)) "$n" "$n" "$steps" "$eg_outer" "$eg_sweeps" \
          "$eg_modes" 0
        cmd=("$GEN4D" run "$out/raw/$tag.toml" --out "$out/raw/$tag.out" --overwrite)
        cells="$((2 * n))x${n}x$n"
      else
        n=$((2 * mpm_weak))
        cmd=("$BENCH_MPM" --particles "$n" --substeps "$steps" --stream-n 1000000)
        cells=$n
      fi
      "$MPIEXEC" -np 2 -x LD_PRELOAD="$out/raw/libmpi_count.so" -x MPI_COUNT_FILE="$out/raw/$tag" \
        "${cmd[@]}" > "$out/raw/$tag.log" 2>&1 ||
        { tail -n 20 "$out/raw/$tag.log" >&2; echo "study.sh: $tag failed" >&2; exit 1; }
      rm -rf "$out/raw/$tag.out"
      for r in 0 1; do
        [[ -s "$out/raw/$tag.$r" ]] || { echo "study.sh: $out/raw/$tag.$r: no counts" >&2; exit 1; }
        read -r _ ag ar aa av ot pm pb < "$out/raw/$tag.$r"
        printf "%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\n" "$code" "$steps" "$r" "$ag" "$ar" \
          "$aa" "$av" "$ot" "$pm" "$pb" "$cells" >> "$out/counts.tsv"
      done
    done
    echo "  counted   $code communication per step (2 ranks)"
  done
else
  echo "  (no $mpicc_bin: communication counts not measured)"
fi

# 4. Checkpoint bandwidth: the same deck run with a checkpoint after every step and with only
#    the final one; the difference of their "io" phases is the extra checkpoints' write time.
#    Then dd writes a file of the checkpoint's size into the same folder, once through the page
#    cache and once with fdatasync.
if [[ $checkpoint == 1 ]]; then
  ck="$out/checkpoint"
  mkdir -p "$ck"
  printf "ranks\tcheckpoints\tfile\tbytes\tload1\tlog_every_step\tlog_final_only\n" > "$out/checkpoint_runs.tsv"
  for np in $ranks; do
    ((np <= cores)) || continue  # bandwidth of oversubscribed writers says nothing
    deck="$out/raw/checkpoint_np$np.toml"
    l1=$(load 1)
    for every in 1 0; do
      eg_deck "$deck" "$ck_cells" "$ck_cells" "$ck_cells" "$ck_steps" 1 2 0 "$every"
      run checkpoint "every$every" "$np" $((ck_cells ** 3)) voxels "$ck_steps" \
        "checkpoint_np${np}_every$every.log" "$GEN4D" run "$deck" --out "$ck/np$np" --overwrite
    done
    file=$(find "$ck/np$np" -name 'checkpoint_*.h5' | sort | tail -n 1)
    [[ -n "$file" ]] || { echo "study.sh: no checkpoint file in $ck/np$np" >&2; exit 1; }
    printf "%s\t%s\t%s\t%s\t%s\t%s\t%s\n" "$np" "$((ck_steps - 1))" "$(basename "$file")" \
      "$(stat -c %s "$file")" "$l1" "checkpoint_np${np}_every1.log" \
      "checkpoint_np${np}_every0.log" >> "$out/checkpoint_runs.tsv"
    bytes=$(stat -c %s "$file")
  done
  [[ -n "${bytes:-}" ]] || die "--ranks: the checkpoint part needs a rank count <= $cores cores (or --no-checkpoint)"
  mib=$(( (bytes + 1048575) / 1048576 ))
  printf "mode\tbytes\tseconds\tload1\n" > "$out/dd.tsv"
  for mode in page_cache fdatasync; do
    flags=()
    [[ $mode == fdatasync ]] && flags=(conv=fdatasync)
    l1=$(load 1)
    rm -f "$ck/dd.bin"
    t0=$(date +%s.%N)
    dd if=/dev/zero of="$ck/dd.bin" bs=1M count="$mib" "${flags[@]}" 2> /dev/null
    t1=$(date +%s.%N)
    printf "%s\t%s\t%s\t%s\n" "$mode" "$((mib * 1048576))" \
      "$(awk -v a="$t0" -v b="$t1" 'BEGIN{printf "%.4f", b - a}')" "$l1" >> "$out/dd.tsv"
    echo "  dd        $mode $mib MiB (load $l1)"
  done
  rm -rf "$ck"
fi
uptime > "$out/uptime_end.txt"
rm -rf "${out:?}/bin"

if [[ $model == 1 ]]; then
  python_bin="${PYTHON:-/usr/bin/python3}"
  "$python_bin" "$here/model.py" "$out"
fi

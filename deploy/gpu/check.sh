#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# The one-call device check: unpacks the bundle deploy/gpu/bundle.sh made,
# prints the GPU, runs the gpu-labelled tests, erg-bench --backend cuda on
# scenes A and B at 1024², 2048² and 8192² and on 2 tiles sharing the GPU,
# and prints one table (README, "Device check on a GPU machine").
#
#   deploy/gpu/check.sh [BUNDLE.tar.xz | BUNDLE_DIR]
#   deploy/gpu/check.sh --cpu-self-test [BUNDLE.tar.xz | BUNDLE_DIR]
#
# Default bundle: the folder this script lies in when it is the bundle's own
# copy, else build-gpubundle/erg-gpu.tar.xz of the repository. The output goes
# to stdout and, when $OUT is set, also to $OUT/erg-gpu-check.txt.
# ERG_CHECK_BUDGET_S (default 330) bounds the whole check: each part gets its
# own timeout and never more than what is left, so the check ends in under
# 6 minutes whatever hangs.
#
# --cpu-self-test proves the bundle on a machine without a GPU: under env -i,
# with nothing from this machine on any library path, it runs erg-bench
# --backend cpu on a small scene, lists the gpu tests (--gtest_list_tests),
# runs erg-worker on a tiny job alone and on 2 MPI ranks, and checks with the
# loader's own trace (LD_DEBUG=libs) that every library any bundled program
# loaded came from the bundle.
set -uo pipefail

here=$(cd "$(dirname "$0")" && pwd)
mode=gpu
if [ "${1:-}" = "--cpu-self-test" ]; then
  mode=cpu
  shift
fi
bundle=${1:-}
if [ -z "$bundle" ]; then
  if [ -x "$here/run/erg-bench" ]; then bundle=$here; else bundle=$here/../../build-gpubundle/erg-gpu.tar.xz; fi
fi

# The self-test starts again under env -i: no variable of this session
# (LD_LIBRARY_PATH, PATH to other tools) reaches the bundle.
if [ "$mode" = cpu ] && [ -z "${ERG_CHECK_CLEAN:-}" ]; then
  exec env -i ERG_CHECK_CLEAN=1 PATH=/usr/bin:/bin HOME=/tmp ${OUT:+OUT=$OUT} \
    ${ERG_CHECK_BUDGET_S:+ERG_CHECK_BUDGET_S=$ERG_CHECK_BUDGET_S} \
    bash "$0" --cpu-self-test "$bundle"
fi

budget=${ERG_CHECK_BUDGET_S:-330}
start=$(date +%s)
work=$(mktemp -d "${TMPDIR:-/tmp}/erg-gpu-check.XXXXXX")
if [ -n "${OUT:-}" ]; then
  mkdir -p "$OUT"
  log=$OUT/erg-gpu-check.txt
  : >"$log"
  exec > >(tee -a "$log") 2>&1
fi
say() { printf '%s\n' "$*"; }
# ldconfig lies in /sbin, which a non-root PATH may lack.
ldcache() { { command -v ldconfig >/dev/null && ldconfig -p || /sbin/ldconfig -p; } 2>/dev/null; }
left() { echo $((budget - ($(date +%s) - start))); }
# part SECONDS CMD...: runs CMD with at most SECONDS (and what is left of the
# budget); prints how it ended.
part() {
  local t=$1 rest
  shift
  rest=$(left)
  [ "$rest" -lt "$t" ] && t=$rest
  if [ "$t" -le 5 ]; then
    say "  [skipped: the check's ${budget} s are spent]"
    return 124
  fi
  timeout -k 5 "$t" "$@"
  local rc=$?
  [ "$rc" = 124 ] && say "  [timed out after ${t} s]"
  return "$rc"
}

say "== erg device check ($mode), $(date -u +%Y-%m-%dT%H:%M:%SZ) on $(uname -n)"
# ---- unpack ----------------------------------------------------------------
if [ -d "$bundle" ]; then
  B=$(cd "$bundle" && pwd)
else
  [ -f "$bundle" ] || { say "check.sh: no bundle at $bundle (deploy/gpu/bundle.sh makes it)"; exit 2; }
  # xz, or Python's lzma where the image has no xz.
  if command -v xz >/dev/null; then
    tar -C "$work" -xJf "$bundle" || exit 2
  else
    python3 -c 'import sys, tarfile; tarfile.open(sys.argv[1]).extractall(sys.argv[2])' "$bundle" "$work" || exit 2
  fi
  B=$work/erg-gpu
fi
say "bundle: $B ($(sed -n 2p "$B/MANIFEST"))"
export ERG_WORKER_BIN=$B/run/erg-worker ERG_MPIEXEC=$B/run/mpirun

# ---- the device's own driver (device/) ---------------------------------------
rm -rf "$B/device" && mkdir -p "$B/device"
if [ "$mode" = gpu ]; then
  cudadir=
  for d in $(ldcache | awk '/libcuda\.so\.1 /{print $NF}' | xargs -r -n1 dirname) \
    /usr/lib/x86_64-linux-gnu /usr/lib64 /usr/local/nvidia/lib64 /usr/local/nvidia/lib \
    /lib/x86_64-linux-gnu /usr/lib/wsl/lib /usr/local/cuda/compat; do
    if [ -e "$d/libcuda.so.1" ]; then cudadir=$d; break; fi
  done
  if [ -n "$cudadir" ]; then
    # The driver and the libraries it dlopens (PTX JIT and the like).
    for f in "$cudadir"/libcuda.so* "$cudadir"/libnvidia-*.so*; do
      [ -e "$f" ] && ln -sf "$f" "$B/device/"
    done
    say "driver: $cudadir/libcuda.so.1 -> $(readlink -f "$cudadir/libcuda.so.1")"
  else
    say "driver: libcuda.so.1 NOT FOUND (looked in ldconfig -p and the usual folders)"
  fi
fi
# Any other library the bundle's programs ask the GPU machine for (bundle.sh
# lists them in device.needs besides the driver; erg itself needs none since
# the wind's smoothing has no FFT).
for n in $(grep -v '^libcuda\.so\.1$' "$B/device.needs"); do
  found=
  for d in ${CUDA_HOME:+$CUDA_HOME/lib64} /usr/local/cuda/lib64 /usr/local/cuda/targets/x86_64-linux/lib \
      /usr/local/cuda-*/lib64 /usr/local/cuda-*/targets/x86_64-linux/lib \
      $(ldcache | awk -v n="$n" '$1 == n {print $NF}' | xargs -r -n1 dirname); do
    [ -e "$d/$n" ] && { found=$d/$n; break; }
  done
  if [ -n "$found" ]; then
    ln -sf "$found" "$B/device/"
    say "$n: $found -> $(readlink -f "$found")"
  else
    say "$n: NOT FOUND (CUDA toolkit lib64, ldconfig -p)"
  fi
done

# ---- the GPU -----------------------------------------------------------------
if [ "$mode" = gpu ]; then
  say ""
  say "== GPU"
  if command -v nvidia-smi >/dev/null; then
    part 30 nvidia-smi --query-gpu=name,driver_version,memory.total,clocks.max.sm,clocks.max.mem,power.limit --format=csv
  else
    say "  (no nvidia-smi)"
  fi
  part 60 "$B/run/erg-bench" --device-info | tee "$work/device.txt"
  bw=$(sed -n 's/.*copy (256 MiB, read + write): \([0-9.]*\) GB\/s.*/\1/p' "$work/device.txt")
else
  bw=
fi

rows=()
fail=0
# bench LABEL TIMEOUT ARGS...: one erg-bench run; its JSON line goes to rows.
bench() {
  local label=$1 t=$2
  shift 2
  say "-- $label: $*"
  part "$t" "$@" --json >"$work/bench.out" 2>&1
  local rc=$?
  local line
  line=$(grep '^{"scene"' "$work/bench.out" | tail -1)
  if [ "$rc" != 0 ] || [ -z "$line" ]; then
    tail -20 "$work/bench.out"
    rows+=("$label|FAILED (exit $rc)")
    fail=1
  else
    say "$line"
    rows+=("$label|$line")
  fi
}

# The table: one row per run. ms/step and the per-stage ms are erg-bench's;
# MB/step is its bytes-moved model (erg_bench.cpp, byte_model: every field
# each stage reads or writes, once per pass); GB/s is the device's
# device-to-device copy (erg-bench --device-info), or the CPU triad in the
# self-test; roofline = MB/step / GB/s, and "x" how far above it erg is.
table() {
  say ""
  say "== table (${1})"
  printf '%-22s %10s %9s %9s %8s %9s %6s  %s\n' run ms/step Mcell/s MB/step GB/s roof_ms x "per-stage ms"
  local r label line
  for r in "${rows[@]}"; do
    label=${r%%|*}
    line=${r#*|}
    case "$line" in
      FAILED*) printf '%-22s %s\n' "$label" "$line"; continue ;;
    esac
    num() { printf '%s' "$line" | sed -n "s/.*\"$1\":\([-0-9.eE+]*\).*/\1/p"; }
    local ms cu bytes own stages g
    ms=$(num ms_per_step)
    cu=$(num cell_updates_per_s)
    bytes=$(num bytes_per_step_model)
    own=$(num memory_bandwidth_gbs)
    g=${bw:-$own}
    stages=$(printf '%s' "$line" | sed -n 's/.*"stage_ms":{\([^}]*\)}.*/\1/p' | tr -d '"' | tr ',' ' ' | sed 's/:/=/g')
    awk -v l="$label" -v ms="$ms" -v cu="$cu" -v b="$bytes" -v g="$g" -v st="$stages" 'BEGIN {
      roof = g > 0 ? b / (g * 1e9) * 1e3 : 0
      x = roof > 0 ? ms / roof : 0
      printf "%-22s %10.3f %9.1f %9.1f %8.1f %9.3f %6.2f  %s\n", l, ms, cu / 1e6, b / 1e6, g, roof, x, st }'
  done
}

if [ "$mode" = gpu ]; then
  # ---- the gpu tests ---------------------------------------------------------
  say ""
  say "== gpu tests"
  for t in $(sed -n 's/^gpu tests: //p' "$B/MANIFEST"); do
    say "-- $t"
    if part 150 "$B/run/$t"; then say "  $t: PASSED"; else say "  $t: FAILED"; fail=1; fi
  done
  # ---- benchmarks --------------------------------------------------------------
  say ""
  say "== erg-bench --backend cuda"
  for scene in A B; do
    for size in 1024 2048 8192; do
      case $size in
        1024) steps=30 warm=5 t=40 ;;
        2048) steps=20 warm=5 t=50 ;;
        8192) steps=5 warm=2 t=90 ;;
      esac
      bench "$scene ${size}²" "$t" "$B/run/erg-bench" --backend cuda --scene $scene --size $size \
        --steps $steps --warmup $warm
    done
  done
  # Two tiles on the one GPU: mpirun starts the ranks itself (ERG_BENCH_CHILD:
  # erg-bench's own --ranks would start mpirun again by /proc/self/exe, which
  # through the bundle's loader is the loader).
  export ERG_BENCH_CHILD=1
  bench "A 2048² 2 tiles" 60 "$B/run/mpirun" -n 2 --bind-to none -x ERG_BENCH_CHILD \
    "$B/run/erg-bench" --backend cuda --scene A --size 2048 --steps 20 --warmup 5 --ranks 2
  unset ERG_BENCH_CHILD
  table "CUDA; GB/s: device-to-device copy"
else
  # ---- CPU self-test -------------------------------------------------------------
  trace=$work/ld-trace
  mkdir -p "$trace"
  # The loader's trace of every bundled program, one file per process.
  export ERG_BUNDLE_LD_TRACE=$trace/p
  say ""
  say "== erg-bench --backend cpu"
  bench "A 512² cpu" 120 "$B/run/erg-bench" --backend cpu --scene A --size 512 --steps 3 --warmup 1 --threads 2
  say ""
  say "== gpu tests, listed"
  for t in $(sed -n 's/^gpu tests: //p' "$B/MANIFEST"); do
    part 30 "$B/run/$t" --gtest_list_tests || { say "  $t --gtest_list_tests FAILED"; fail=1; }
  done
  say ""
  say "== erg-worker on a tiny job, alone and on 2 ranks"
  cat >"$work/tiny.json" <<'EOF'
{"name": "bundle-self-test", "domain": {"nx": 256, "ny": 128, "cell_size_m": 1.0},
 "layers": {"sand": {"patches": {"coverage": 0.4, "radius_m": 8, "height": 2, "falloff_m": 3}}},
 "wind": {"constant": {"speed_mps": 6, "direction_deg": 30}}, "seed": 3,
 "run": {"steps": 10, "snapshot_every": 10}}
EOF
  for ranks in 1 2; do
    if [ $ranks = 1 ]; then
      cmd=("$B/run/erg-worker" "$work/tiny.json" --backend cpu --threads 1 --quiet --out "$work/tiny1")
    else
      cmd=("$B/run/mpirun" -n 2 --oversubscribe --bind-to none "$B/run/erg-worker" "$work/tiny.json"
        --backend cpu --threads 1 --quiet --out "$work/tiny2")
    fi
    say "-- ${cmd[*]##*/}"
    if part 120 "${cmd[@]}" && [ -f "$work/tiny$ranks/snapshots/step_00000010.h5" ]; then
      say "  $ranks rank(s): PASSED ($(ls "$work/tiny$ranks/snapshots" | tr '\n' ' '))"
    else
      say "  $ranks rank(s): FAILED"
      fail=1
    fi
  done
  # Built without GDAL (bundle.sh): a GeoTIFF map is refused with the reason.
  printf 'II*\0' >"$work/dem.tif"
  sed 's/"layers": {/"layers": {"bedrock": {"map": {"path": "dem.tif"}}, /' "$work/tiny.json" >"$work/tif.json"
  say "-- erg-worker tif.json (a GeoTIFF map; the bundle has no GDAL)"
  part 60 "$B/run/erg-worker" "$work/tif.json" --backend cpu --quiet --out "$work/tif" >"$work/tif.out" 2>&1
  rc=$?
  sed 's/^/  /' "$work/tif.out"
  # Refused: an error exit, never a crash (a signal) or a success.
  if [ "$rc" -eq 0 ] || [ "$rc" -ge 124 ]; then
    say "  exit status $rc, not a refusal: FAILED"
    fail=1
  fi
  grep -q 'ERG_WITH_GDAL=OFF' "$work/tif.out" || { say "  no error naming ERG_WITH_GDAL: FAILED"; fail=1; }
  table "CPU self-test; GB/s: CPU triad"
  # ---- where every library came from ------------------------------------------
  # LD_DEBUG=libs: "calling init: PATH" for each object a process starts,
  # "initialize program: P" when its main program starts. A process that
  # is a bundled program (started as $B/run/NAME: the wrappers pass that as
  # argv[0]) must have loaded only bundled files.
  say ""
  say "== libraries loaded by the bundled programs (LD_DEBUG=libs)"
  awk -v B="$B/" '
    FNR == 1 { prog = ""; n = 0 }
    /calling init: / { p = $0; sub(/.*calling init: /, "", p); if (prog == "") { pend[n++] = p } else { see(prog, p) } }
    /initialize program: / { prog = $0; sub(/.*initialize program: /, "", prog);
                             for (i = 0; i < n; i++) see(prog, pend[i]); n = 0 }
    function see(prog, p) {
      if (index(prog, B "run/") != 1) return
      progs[prog] = 1
      if (index(p, B "device/") == 1) { dev[p] = 1 } else if (index(p, B) == 1) { ok[p] = 1 } else { bad[prog " <- " p] = 1 }
    }
    END {
      np = 0; for (p in progs) np++
      nb = 0; for (p in ok) nb++
      for (p in dev) printf "  from device/ (found above, not carried): %s\n", p
      printf "  %d bundled program(s) traced, %d distinct files loaded from the bundle; none from elsewhere: ", np, nb
      nbad = 0; for (k in bad) nbad++
      if (nbad == 0) { print "yes" } else { print "NO"; for (k in bad) print "  FROM THIS MACHINE: " k; exit 1 }
    }' "$trace"/p* || fail=1
  [ -n "$(ls "$trace")" ] || { say "  no trace written"; fail=1; }
fi

say ""
say "== done in $(($(date +%s) - start)) s: $([ $fail = 0 ] && echo PASSED || echo FAILED)"
rm -rf "$work"
exit $fail

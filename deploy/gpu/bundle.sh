#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Builds the GPU device-check bundle: erg-worker, erg-bench and the gpu-labelled
# test binaries (tests/gpu) for sm_90 (SASS + PTX), with every shared library
# they load except the one that must come from the GPU machine (the driver,
# libcuda.so.1: deploy/gpu/check.sh finds it there), in
# one .tar.xz of at most 48 MiB that check.sh runs on a machine with none of
# erg's Debian libraries (README, "Device check on a GPU machine").
#
#   deploy/gpu/bundle.sh [OUT.tar.xz]      (default build-gpubundle/erg-gpu.tar.xz)
#
# ERG_BUNDLE_BUILD: the build folder (default build-gpubundle, git-ignored);
# ERG_BUNDLE_JOBS: compiler jobs (default 2).
#
# Choices, and why:
# - The build: its own folder; ERG_NATIVE=OFF (the GPU machine's CPU is not
#   this one: -march=native code could stop on an illegal instruction there);
#   CMAKE_CUDA_ARCHITECTURES=90 (H100/H200 SASS plus compute_90 PTX, which
#   newer GPUs JIT); CMAKE_CUDA_RUNTIME_LIBRARY=Static (cudart is linked in,
#   worker/CMakeLists.txt, so no libcudart travels); ERG_WITH_GDAL=OFF (GDAL
#   serves GeoTIFF maps and exports alone and pulls in ~100 libraries; the
#   bundle's programs run generated scenes); CMAKE_SKIP_RPATH (no RUNPATH
#   to this machine's /usr/local/cuda).
# - The C library and the dynamic loader travel too, and every program runs
#   as `lib/ld-linux-x86-64.so.2 --inhibit-cache --library-path lib:device
#   bin/PROGRAM` (the wrappers in run/). The libraries were built against
#   Debian 12's glibc 2.36 and need its symbol versions; the GPU machine's
#   glibc is unknown. Started by the machine's loader with our libc on
#   LD_LIBRARY_PATH, loader and libc would be of different releases (they
#   must match exactly), and LD_LIBRARY_PATH would also reach the machine's
#   own programs (nvidia-smi, sh) with our libc. The bundled loader with
#   --library-path affects only the process it starts; --inhibit-cache keeps
#   the machine's /etc/ld.so.cache out, so each library comes from lib/ or
#   from device/ (the symlinks to the driver check.sh makes). The
#   driver is only dlopen'ed (by the static cudart) and needs nothing of
#   glibc newer than 2.36's.
# - Open MPI dlopens its components from its install folders: they travel
#   under ompi/ and pmix/, and run/env.sh points Open MPI there (OPAL_*
#   variables, PMIX_*); OPAL_BINDIR is run/, so an MPI singleton starts the
#   bundle's orted through its wrapper. Shared memory (btl self,vader; pml
#   ob1) is all one GPU machine needs.
set -euo pipefail

SRC=$(cd "$(dirname "$0")/../.." && pwd)
BUILD=${ERG_BUNDLE_BUILD:-$SRC/build-gpubundle}
OUT_TAR=${1:-$BUILD/erg-gpu.tar.xz}
JOBS=${ERG_BUNDLE_JOBS:-2}
LIMIT_MIB=48

mkdir -p "$BUILD"
cmake -S "$SRC" -B "$BUILD" -G Ninja -DCMAKE_BUILD_TYPE=Release -DERG_WERROR=ON \
  -DERG_NATIVE=OFF -DERG_WITH_GDAL=OFF -DERG_BUILD_TESTS=ON \
  -DCMAKE_CUDA_ARCHITECTURES=90 -DCMAKE_CUDA_RUNTIME_LIBRARY=Static -DCMAKE_SKIP_RPATH=ON >"$BUILD/bundle-configure.log" ||
  { cat "$BUILD/bundle-configure.log"; exit 1; }
if ! grep -q '^CMAKE_CUDA_COMPILER:[A-Z]*=.*nvcc' "$BUILD/CMakeCache.txt"; then
  echo "bundle.sh: no nvcc found; the bundle needs the CUDA backend" >&2
  exit 1
fi
# The gpu-labelled test binaries: every executable tests/gpu defines.
GPU_TESTS=$(sed -n 's/^ *add_executable(\([A-Za-z0-9_]*\).*/\1/p' "$SRC/tests/gpu/CMakeLists.txt" | tr '\n' ' ')
PROGRAMS="erg-worker erg-bench"
# shellcheck disable=SC2086
cmake --build "$BUILD" -j"$JOBS" --target $PROGRAMS $GPU_TESTS

MPIEXEC=$(sed -n 's/^MPIEXEC_EXECUTABLE:FILEPATH=//p' "$BUILD/CMakeCache.txt")
ORTERUN=$(readlink -f "$MPIEXEC")
ORTED=$(dirname "$ORTERUN")/orted
# Debian 12's Open MPI 4.1 and PMIx 4.2 (libopenmpi-dev, deploy/bootstrap.sh).
OMPI_PKGLIB=${ERG_BUNDLE_OMPI_PKGLIB:-/usr/lib/x86_64-linux-gnu/openmpi/lib/openmpi3}
PMIX_ROOT=${ERG_BUNDLE_PMIX_ROOT:-/usr/lib/x86_64-linux-gnu/pmix2}

STAGE=$BUILD/stage/erg-gpu
rm -rf "$BUILD/stage"
mkdir -p "$STAGE"/{bin,lib,run,device,hwloc,ompi/lib,ompi/share,ompi/etc,pmix/lib,pmix/share}
for p in $PROGRAMS $GPU_TESTS; do cp "$BUILD/bin/$p" "$STAGE/bin/"; done
cp "$ORTERUN" "$STAGE/bin/orterun"
cp "$ORTED" "$STAGE/bin/orted"
cp -r "$OMPI_PKGLIB" "$STAGE/ompi/lib/openmpi3"
cp -r /usr/share/openmpi "$STAGE/ompi/share/openmpi"
cp /etc/openmpi/openmpi-mca-params.conf "$STAGE/ompi/etc/" 2>/dev/null || : >"$STAGE/ompi/etc/openmpi-mca-params.conf"
cp -r "$PMIX_ROOT/lib/pmix" "$STAGE/pmix/lib/pmix"
cp -r "$PMIX_ROOT/share/." "$STAGE/pmix/share/"

# Every library the programs and the Open MPI and PMIx components need, as
# ldd resolves it here, by the name they ask for. Not carried: the driver and
# the CUDA libraries a program may ask the GPU machine for (check.sh finds
# them there; erg needs none but the driver) and the kernel's vDSO.
skip='^(linux-vdso\.so\.1|libcuda\.so\.1|libcu(fft|blas|rand)\.so\.[0-9]+|libnvidia-.*)$'
: >"$BUILD/stage/needed"
for f in "$STAGE"/bin/* "$STAGE"/ompi/lib/openmpi3/*.so "$STAGE"/pmix/lib/pmix/*.so; do
  ldd "$f" >"$BUILD/stage/ldd.tmp" || { echo "bundle.sh: ldd $f failed" >&2; exit 1; }
  while read -r name arrow path _; do
    case "$arrow" in
      "=>")
        [[ $name =~ $skip ]] && continue
        if [ "$path" = "not" ]; then
          echo "bundle.sh: $f needs $name, which is not found here" >&2
          exit 1
        fi
        echo "$name $path" >>"$BUILD/stage/needed" ;;
      *)
        # The loader line: /lib64/ld-linux-x86-64.so.2 (0x...)
        case "$name" in /*ld-linux*) echo "ld-linux-x86-64.so.2 $name" >>"$BUILD/stage/needed" ;; esac ;;
    esac
  done <"$BUILD/stage/ldd.tmp"
done
sort -u "$BUILD/stage/needed" | while read -r name path; do
  cp -L "$path" "$STAGE/lib/$name"
done
rm -f "$BUILD/stage/ldd.tmp"
for f in "$STAGE"/bin/*; do
  if ldd "$f" | grep -q 'libcudart\.so'; then
    echo "bundle.sh: $f links the shared CUDA runtime (expected it static)" >&2
    exit 1
  fi
done

# The wrappers: each program through the bundle's loader (see above).
cat >"$STAGE/run/env.sh" <<'EOF'
# Sourced by the wrappers in run/ with B set to the bundle's folder: Open MPI,
# PMIx and hwloc find their components and help texts in the bundle.
# A preload of the machine's would be loaded against the bundle's libc.
unset LD_PRELOAD
export OPAL_PREFIX="$B/ompi" OPAL_EXEC_PREFIX="$B/ompi" OPAL_BINDIR="$B/run" OPAL_LIBDIR="$B/lib"
export OPAL_PKGLIBDIR="$B/ompi/lib/openmpi3" OPAL_DATAROOTDIR="$B/ompi/share"
export OPAL_DATADIR="$B/ompi/share" OPAL_PKGDATADIR="$B/ompi/share/openmpi"
export OPAL_SYSCONFDIR="$B/ompi/etc"
export PMIX_INSTALL_PREFIX="$B/pmix" PMIX_PREFIX="$B/pmix" PMIX_PKGLIBDIR="$B/pmix/lib/pmix"
export PMIX_MCA_mca_base_component_path="$B/pmix/lib/pmix"
export HWLOC_PLUGINS_PATH="$B/hwloc"
# One machine: shared memory between the ranks; ROMIO for MPI-IO (worker/main.cpp).
export OMPI_MCA_pml="${OMPI_MCA_pml:-ob1}" OMPI_MCA_btl="${OMPI_MCA_btl:-self,vader}"
export OMPI_MCA_osc="${OMPI_MCA_osc:-^ucx}" OMPI_MCA_io="${OMPI_MCA_io:-romio321}"
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
EOF
# ERG_BUNDLE_LD_TRACE (check.sh --cpu-self-test): the loader traces the
# libraries this program loads (LD_DEBUG=libs) into a file of its own; the
# name carries this shell's pid, so the trace of a shell that inherited the
# variable (same pid, before exec) never lands in the program's file.
for p in $PROGRAMS $GPU_TESTS orterun orted; do
  cat >"$STAGE/run/$p" <<EOF
#!/bin/sh
# bin/$p through the bundle's own loader and libraries (deploy/gpu/bundle.sh).
B=\$(CDPATH= cd -- "\$(dirname -- "\$0")/.." && pwd)
. "\$B/run/env.sh"
set -- "\$B/lib/ld-linux-x86-64.so.2" --inhibit-cache --library-path "\$B/lib:\$B/device" \\
  --argv0 "\$0" "\$B/bin/$p" "\$@"
if [ -n "\${ERG_BUNDLE_LD_TRACE:-}" ]; then
  LD_DEBUG=libs LD_DEBUG_OUTPUT="\$ERG_BUNDLE_LD_TRACE.$p.\$\$" exec "\$@"
fi
exec "\$@"
EOF
  chmod +x "$STAGE/run/$p"
done
ln -s orterun "$STAGE/run/mpirun"
cp "$SRC/deploy/gpu/check.sh" "$STAGE/check.sh"
# The libraries check.sh must find on the GPU machine, by the names asked for.
for f in "$STAGE"/bin/*; do ldd "$f"; done | awk '$1 ~ /^libcu(fft|blas|rand)/ {print $1}' | sort -u >"$STAGE/device.needs"
echo libcuda.so.1 >>"$STAGE/device.needs"
{
  echo "erg GPU bundle"
  echo "source: $(git -C "$SRC" describe --always --dirty 2>/dev/null || echo unknown)"
  echo "built: $(date -u +%Y-%m-%dT%H:%M:%SZ) on $(. /etc/os-release && echo "$PRETTY_NAME"), glibc $(ldd --version | head -1 | awk '{print $NF}')"
  echo "cuda: $(/usr/local/cuda/bin/nvcc --version | tail -1), sm_90 + compute_90 PTX, static cudart"
  echo "gpu tests: $GPU_TESTS"
  echo "libraries (lib/):"
  (cd "$STAGE/lib" && ls -1 | while read -r l; do printf '  %-40s %8d KiB\n' "$l" $(($(stat -c %s "$l") / 1024)); done)
} >"$STAGE/MANIFEST"

mkdir -p "$(dirname "$OUT_TAR")"
# xz, not zstd: xz (or Python's lzma, check.sh's fallback) is in nearly
# every image; zstd often is not.
tar --sort=name --owner=0 --group=0 --numeric-owner -C "$BUILD/stage" -cf - erg-gpu |
  xz -9 -T"$JOBS" >"$OUT_TAR"
size=$(stat -c %s "$OUT_TAR")
echo "bundle.sh: $OUT_TAR: $((size / 1024 / 1024)) MiB ($size bytes; $(du -sh "$STAGE" | cut -f1) unpacked), $(ls "$STAGE/lib" | wc -l) libraries"
if [ "$size" -gt $((LIMIT_MIB * 1024 * 1024)) ]; then
  echo "bundle.sh: larger than $LIMIT_MIB MiB" >&2
  exit 1
fi

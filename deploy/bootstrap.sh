#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Installs every Debian package erg needs to build, test and run.
# Idempotent and non-interactive: packages already present are skipped, so a
# second run is a no-op that only checks. Needs root (or passwordless sudo).
# The CUDA toolkit is not a Debian package here: it is expected at
# /usr/local/cuda (nvcc); without it erg builds the CPU backend only.
set -euo pipefail

packages=(
  # toolchain
  build-essential cmake ninja-build pkg-config git clang-format
  # MPI and parallel HDF5 (the worker, snapshots, checkpoints)
  openmpi-bin libopenmpi-dev libhdf5-openmpi-dev hdf5-tools
  # the job schema (protobuf JSON) and the service
  libprotobuf-dev protobuf-compiler libgrpc++-dev protobuf-compiler-grpc
  # previews and map files
  libpng-dev zlib1g-dev
  # GeoTIFF and OpenEXR map imports and exports (erg export)
  libgdal-dev gdal-bin libopenexr-dev
  # ergd: job store, HTTP dashboard and metrics, TLS, sha256
  libsqlite3-dev libcpp-httplib-dev prometheus-cpp-dev libssl-dev
  # the libFuzzer target of the spec parser (clang's fuzzer runtime)
  clang libclang-rt-14-dev
  # tests and benchmarks
  libgtest-dev libgmock-dev libbenchmark-dev
  # test helpers that read our outputs with tools erg did not write
  python3 python3-h5py python3-numpy
  # ... and read erg export's files: GDAL's Python bindings, PIL for 16-bit PNGs
  python3-gdal python3-pil
  # erg validate: measurements (connected components) and the report's plots
  python3-scipy python3-matplotlib
  # the Slurm launcher and its test cluster (slurmctld, slurmd, munge)
  slurmctld slurmd slurm-client munge
  # systemd-analyze verifies the installed ergd.service
  systemd
  # the Python gRPC client of the service tests, and the dashboard test
  python3-grpcio python3-protobuf chromium openssl
  # the dashboard test drives Chromium with Selenium
  chromium-driver python3-selenium
  # readers of the snapshots as netCDF-4/CF (xarray over h5netcdf, with dask for
  # open_mfdataset; ncdump), and
  # ParaView's pvbatch (under a virtual X server) for the XDMF test
  python3-xarray python3-h5netcdf python3-dask netcdf-bin paraview python3-paraview xvfb
  # the Python package (client/python): built offline with setuptools, and its
  # tests (pip in a venv over the system site packages)
  python3-venv python3-pip python3-setuptools python3-wheel
)

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "bootstrap: all ${#packages[@]} packages present"
  exit 0
fi

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
echo "bootstrap: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -q
$SUDO apt-get install -y -q --no-install-recommends "${missing[@]}"
echo "bootstrap: done"

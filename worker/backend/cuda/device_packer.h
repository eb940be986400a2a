// SPDX-License-Identifier: Apache-2.0
// The halo packer of a CUDA-aware MPI (dist/halo_packer.h): the fields'
// device copies (dist::Ghosts::device) packed into device buffers on a
// stream, which MPI reads and writes directly; unpacked and zeroed there
// too. Host code may include this (no device code): the CUDA backend uses
// it, and tests/gpu runs it against the host packer.
#pragma once

#include <cuda_runtime_api.h>

#include <memory>

#include "dist/halo_packer.h"

namespace erg::gpu {

// managed: the message buffers are managed memory (cudaMallocManaged), which
// an MPI that is not CUDA-aware can read and write too (for tests; the
// backend uses device memory).
std::unique_ptr<dist::HaloPacker> make_device_packer(cudaStream_t s, bool managed);

}  // namespace erg::gpu

// SPDX-License-Identifier: Apache-2.0
#include "backend/backend.h"

#include <iostream>
#include <stdexcept>

#include "backend/cpu/cpu_backend.h"

namespace erg {

#ifdef ERG_HAVE_CUDA
// backend/cuda/cuda_backend.cu
std::unique_ptr<Backend> make_cuda_backend(const Model& model, dist::Exchange& ex, int local_rank);
bool cuda_runtime_has_device();
CudaDeviceInfo cuda_runtime_device_info(int local_rank);
#endif

CudaDeviceInfo cuda_device_info(int local_rank) {
#ifdef ERG_HAVE_CUDA
  if (!cuda_runtime_has_device())
    throw std::runtime_error("no CUDA device is visible to this process");
  return cuda_runtime_device_info(local_rank);
#else
  (void)local_rank;
  throw std::runtime_error("this build has no CUDA backend (nvcc was not found)");
#endif
}

bool cuda_device_available() {
#ifdef ERG_HAVE_CUDA
  return cuda_runtime_has_device();
#else
  return false;
#endif
}

std::unique_ptr<Backend> make_backend(BackendKind kind, const Model& model, int threads,
                                      dist::Exchange& ex, int local_rank) {
  if (kind == BackendKind::kCuda || kind == BackendKind::kAuto) {
#ifdef ERG_HAVE_CUDA
    if (cuda_device_available()) return make_cuda_backend(model, ex, local_rank);
    if (kind == BackendKind::kCuda)
      throw std::invalid_argument("--backend cuda: no CUDA device is visible to this process");
    // Once per process, and from one rank per node.
    static bool told = false;
    if (!told && local_rank == 0) std::cerr << "erg: no CUDA device found, using the CPU backend\n";
    told = true;
#else
    if (kind == BackendKind::kCuda)
      throw std::invalid_argument(
          "--backend cuda: this build has no CUDA backend (nvcc was not found)");
    static bool told = false;
    if (!told && local_rank == 0) std::cerr << "erg: built without CUDA, using the CPU backend\n";
    told = true;
#endif
  }
  return std::make_unique<cpu::CpuBackend>(model, threads, ex);
}

}  // namespace erg

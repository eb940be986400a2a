// SPDX-License-Identifier: Apache-2.0
// Which GPU a rank computes on. The ranks of one node (local_rank: the rank
// within MPI_COMM_TYPE_SHARED, dist/tiling) take the node's devices in turn,
// so k ranks on a k-GPU node use one device each, and 2k ranks share each
// device by two. Where the launcher binds one device per task (Slurm's
// --gpus-per-task, or CUDA_VISIBLE_DEVICES set per rank), each process sees
// one device and takes it. A pure function, so that the rule is tested
// without a GPU.
#pragma once

#include <stdexcept>
#include <string>

namespace erg {

inline int device_for_rank(int local_rank, int devices) {
  if (devices <= 0)
    throw std::invalid_argument(
        "no CUDA device is visible to this process (devices = " + std::to_string(devices) + ")");
  if (local_rank < 0)
    throw std::invalid_argument("local rank " + std::to_string(local_rank) + " is negative");
  return local_rank % devices;
}

}  // namespace erg

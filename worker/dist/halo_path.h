// SPDX-License-Identifier: Apache-2.0
// How a tile's ghosts reach MPI, and what a device backend does when. Plain
// C++ (no CUDA, no MPI), so that the rules are unit-tested without a GPU
// (tests/dist/test_halo_path.cpp); the CUDA backend follows them.
//
// - kHost: the fields live in host memory (CPU backend): the exchange packs
//   them itself.
// - kDevice: one tile is the whole torus: the periodic wrap runs on the
//   device, nothing crosses to the host.
// - kHostStaged: several tiles, MPI reads host memory only: each field's
//   halo frame (dist/halo_frame.h) is packed on the device, copied to pinned
//   host memory, exchanged there and copied back (counted by
//   Exchange::count_host_staged).
// - kDeviceDirect: several tiles and a CUDA-aware MPI (compiled with
//   MPIX_CUDA_AWARE_SUPPORT and MPIX_Query_cuda_support() true at run time):
//   the exchange's messages are packed on the device and MPI reads and writes
//   device buffers (dist::HaloPacker); 0 bytes are staged.
#pragma once

#include <cstddef>
#include <span>
#include <vector>

#include "core/grid.h"
#include "dist/ghosts.h"
#include "dist/halo_frame.h"

namespace erg::dist {

enum class HaloPath { kHost, kDevice, kHostStaged, kDeviceDirect };

// The name in the worker's log, its done event and erg-bench --json.
inline const char* halo_path_name(HaloPath p) {
  switch (p) {
    case HaloPath::kHost:
      return "host";
    case HaloPath::kDevice:
      return "device";
    case HaloPath::kHostStaged:
      return "host-staged";
    case HaloPath::kDeviceDirect:
      return "cuda-aware-mpi";
  }
  return "?";
}

// What the MPI library says about device buffers. `built`: <mpi-ext.h>
// defines MPIX_CUDA_AWARE_SUPPORT to 1; `runtime`: MPIX_Query_cuda_support()
// returns 1 (Open MPI's two-step check); `allowed`: not switched off by
// ERG_CUDA_AWARE_MPI=0 (to compare both paths on one machine).
struct MpiCudaSupport {
  bool built = false;
  bool runtime = false;
  bool allowed = true;
};

// What this process's MPI library says (dist/mpi_exchange.cpp; after
// MPI_Init): <mpi-ext.h>'s MPIX_CUDA_AWARE_SUPPORT where the header has it,
// MPIX_Query_cuda_support() where the library has it, and the variable
// ERG_CUDA_AWARE_MPI (0: not allowed).
MpiCudaSupport mpi_cuda_support();

// The path of a backend whose fields are on the device (or not) on a
// decomposition of `tiles` tiles. Device buffers go to MPI only when the
// library was built for them AND says so at run time.
inline HaloPath choose_halo_path(bool device_fields, int tiles, const MpiCudaSupport& mpi) {
  if (!device_fields) return HaloPath::kHost;
  if (tiles <= 1) return HaloPath::kDevice;
  if (mpi.built && mpi.runtime && mpi.allowed) return HaloPath::kDeviceDirect;
  return HaloPath::kHostStaged;
}

// ---- the host-staged path: what happens when --------------------------------
// A device backend runs its kernels on a compute stream and the staging on
// a copy stream of its own. For one ghost operation:
// - download: after the kernels that wrote the fields (an event), pack every
//   field's frame on the copy stream and copy them all to pinned host memory
//   in one asynchronous copy;
// - exchange: wait for that copy (the copy stream only, not the compute
//   stream), unpack into the host fields and run Exchange::ghosts(exchange_op);
// - upload: pack the host frames into pinned memory, copy them to the device
//   and unpack on the copy stream; the compute stream waits for it (an
//   event), the host does not;
// - ghosts_only: the unpack writes only the ghost cells. A fill leaves the
//   owned cells as they are, so its upload may run alongside kernels that
//   work on the owned cells (and the values it writes are copies: the
//   results are the same bits whatever overlaps).
// A split fill (kBeginFill ... kFinishFill around work that reads no ghost
// and writes none of the fields) downloads at kBeginFill and returns at
// once: the copy overlaps that work's kernels. kFinishFill exchanges (the
// host, while those kernels still run) and uploads, overlapping them too;
// only the kernels launched after it wait.
struct StagingSteps {
  bool download = false;
  bool exchange = false;
  GhostOp exchange_op = GhostOp::kFill;
  bool upload = false;
  bool ghosts_only = false;
};

inline StagingSteps staging_steps(GhostOp op) {
  switch (op) {
    case GhostOp::kBeginFill:
      return {true, false, GhostOp::kFill, false, false};
    case GhostOp::kFinishFill:
      return {false, true, GhostOp::kFill, true, true};
    case GhostOp::kFill:
      return {true, true, GhostOp::kFill, true, true};
    case GhostOp::kSum:  // the owned cells within the width change: upload the whole frame
      return {true, true, GhostOp::kSum, true, false};
  }
  return {};
}

// The frames of several fields one after another in one buffer, so that one
// copy moves all of them; each starts at a multiple of kFrameAlign bytes
// (the alignment of cudaMalloc, so that every field's elements are aligned).
inline constexpr std::size_t kFrameAlign = 256;

struct FrameSlot {
  HaloFrame frame;
  std::size_t offset = 0;  // bytes from the start of the buffer
  std::size_t bytes = 0;   // frame.size() * the element size
};

struct FrameLayout {
  std::vector<FrameSlot> slots;  // in list order
  std::size_t bytes = 0;         // the buffer's size: the last slot's end, aligned
  std::size_t payload = 0;       // the frames' bytes alone (what is counted as staged)
};

// widths[i], elem_bytes[i]: field i's exchange width (clipped to the tile's
// halo, as the exchange clips it) and element size.
inline FrameLayout frame_layout(const TileGeom& g, std::span<const int> widths,
                                std::span<const std::size_t> elem_bytes) {
  FrameLayout l;
  for (std::size_t i = 0; i < widths.size(); ++i) {
    const int w = widths[i] < g.halo ? widths[i] : g.halo;
    FrameSlot s;
    s.frame = HaloFrame{g.nx, g.ny, w > 0 ? w : 0};
    s.bytes = s.frame.size() * elem_bytes[i];
    s.offset = l.bytes;
    l.bytes += (s.bytes + kFrameAlign - 1) / kFrameAlign * kFrameAlign;
    l.payload += s.bytes;
    l.slots.push_back(s);
  }
  return l;
}

// The bytes one operation moves between device and host: the frames down,
// back up, or both.
inline long long staged_bytes(const StagingSteps& s, const FrameLayout& l) {
  const long long one_way = static_cast<long long>(l.payload);
  return (s.download ? one_way : 0) + (s.upload ? one_way : 0);
}

}  // namespace erg::dist

// SPDX-License-Identifier: Apache-2.0
// The CUDA backend: the same stages, in the same order, over the same padded
// fields as the CPU backend (backend/cpu), one thread per cell. Every formula
// is a call into stages/ (shared with the CPU); the code here only allocates
// device memory, fills and folds halos and launches kernels. Scatters use 64-bit integer atomics
// (exact and order-independent); reductions are integer sums, so results do
// not depend on the launch configuration (docs/design.md, "Exactness").
//
// Included only by the .cu files of this folder (it has device code).
#pragma once

#include <cuda_runtime.h>

#include <cstddef>
#include <limits>
#include <memory>
#include <utility>
#include <vector>

#include "backend/backend.h"
#include "backend/cuda/device_packer.h"
#include "core/fields.h"
#include "core/grid.h"
#include "core/units.h"
#include "dist/halo_frame.h"
#include "dist/halo_packer.h"
#include "dist/halo_path.h"
#include "stages/shear_stress.h"
#include "stages/wind_warping.h"

namespace erg::gpu {

// ---- error checking ---------------------------------------------------------
// Every CUDA call is checked; a failure throws std::runtime_error naming the
// call and the runtime's message.
[[noreturn]] void fail(const char* what, const char* detail);
inline void check(cudaError_t e, const char* what) {
  if (e != cudaSuccess) fail(what, cudaGetErrorString(e));
}
// After a kernel launch: reports launch errors (and earlier asynchronous ones).
void check_launch(const char* kernel);

#define ERG_CUDA_CHECK(call) ::erg::gpu::check((call), #call)
// kernel<<<grid, block>>>(args...) followed by a launch check naming it.
#define ERG_LAUNCH(kernel, grid, block, ...)  \
  do {                                        \
    kernel<<<(grid), (block)>>>(__VA_ARGS__); \
    ::erg::gpu::check_launch(#kernel);        \
  } while (0)
// The same on `stream` (the halo copy stream; every stage runs on the
// default stream).
#define ERG_LAUNCH_ON(stream, kernel, grid, block, ...)    \
  do {                                                     \
    kernel<<<(grid), (block), 0, (stream)>>>(__VA_ARGS__); \
    ::erg::gpu::check_launch(#kernel);                     \
  } while (0)

// ---- device memory ----------------------------------------------------------
// An owned, zero-initialised device array.
template <class T>
class DeviceBuffer {
 public:
  DeviceBuffer() = default;
  ~DeviceBuffer() {
    if (p_) cudaFree(p_);  // no throw from a destructor
  }
  DeviceBuffer(const DeviceBuffer&) = delete;
  DeviceBuffer& operator=(const DeviceBuffer&) = delete;
  DeviceBuffer(DeviceBuffer&& o) noexcept { swap(o); }
  DeviceBuffer& operator=(DeviceBuffer&& o) noexcept {
    swap(o);
    return *this;
  }

  void reset(std::size_t n) {
    if (p_) ERG_CUDA_CHECK(cudaFree(p_));
    p_ = nullptr;
    n_ = 0;
    if (n == 0) return;
    ERG_CUDA_CHECK(cudaMalloc(reinterpret_cast<void**>(&p_), n * sizeof(T)));
    n_ = n;
    ERG_CUDA_CHECK(cudaMemset(p_, 0, n * sizeof(T)));
  }
  void swap(DeviceBuffer& o) noexcept {
    std::swap(p_, o.p_);
    std::swap(n_, o.n_);
  }
  T* get() { return p_; }
  const T* get() const { return p_; }
  std::size_t size() const { return n_; }
  std::size_t bytes() const { return n_ * sizeof(T); }

 private:
  T* p_ = nullptr;
  std::size_t n_ = 0;
};

// Page-locked host memory (cudaMallocHost), so that copies to and from the
// device run at full PCIe speed; grows, never shrinks.
class PinnedBuffer {
 public:
  PinnedBuffer() = default;
  ~PinnedBuffer() {
    if (p_) cudaFreeHost(p_);  // no throw from a destructor
  }
  PinnedBuffer(const PinnedBuffer&) = delete;
  PinnedBuffer& operator=(const PinnedBuffer&) = delete;
  void* at_least(std::size_t bytes) {
    if (bytes > n_) {
      if (p_) ERG_CUDA_CHECK(cudaFreeHost(p_));
      p_ = nullptr;
      n_ = 0;
      ERG_CUDA_CHECK(cudaMallocHost(&p_, bytes));
      n_ = bytes;
    }
    return p_;
  }

 private:
  void* p_ = nullptr;
  std::size_t n_ = 0;
};

// A stream that does not wait for the legacy default stream (where the
// stages run), and an event without timing; owned, destroyed without throwing.
class Stream {
 public:
  Stream() { ERG_CUDA_CHECK(cudaStreamCreateWithFlags(&s_, cudaStreamNonBlocking)); }
  ~Stream() {
    if (s_) cudaStreamDestroy(s_);
  }
  Stream(const Stream&) = delete;
  Stream& operator=(const Stream&) = delete;
  cudaStream_t get() const { return s_; }

 private:
  cudaStream_t s_ = nullptr;
};
class Event {
 public:
  Event() { ERG_CUDA_CHECK(cudaEventCreateWithFlags(&e_, cudaEventDisableTiming)); }
  ~Event() {
    if (e_) cudaEventDestroy(e_);
  }
  Event(const Event&) = delete;
  Event& operator=(const Event&) = delete;
  cudaEvent_t get() const { return e_; }

 private:
  cudaEvent_t e_ = nullptr;
};
// `waiter` runs nothing more until everything queued on `done` so far has
// run (through `e`); the host does not wait.
inline void stream_waits(cudaStream_t waiter, cudaStream_t done, const Event& e) {
  ERG_CUDA_CHECK(cudaEventRecord(e.get(), done));
  ERG_CUDA_CHECK(cudaStreamWaitEvent(waiter, e.get(), 0));
}
// The legacy default stream, where every stage's kernels run.
inline constexpr cudaStream_t kCompute = 0;

// ---- launch geometry --------------------------------------------------------
inline constexpr int kBlockX = 32, kBlockY = 8;  // 2-D blocks over owned cells
inline constexpr int kRowThreads = 256;          // one block per row (reductions)
inline constexpr int kThreads1D = 256;

struct Launch {
  dim3 grid, block;
};
// One thread per cell of the tile grown by `grow` cells on every side
// (ghost-zone expansion: reptation and avalanching run on the halo too).
inline Launch grown_cells(const TileGeom& g, int grow) {
  return {dim3(static_cast<unsigned>((g.nx + 2 * grow + kBlockX - 1) / kBlockX),
               static_cast<unsigned>((g.ny + 2 * grow + kBlockY - 1) / kBlockY)),
          dim3(kBlockX, kBlockY)};
}
__device__ __forceinline__ bool grown_cell(const TileGeom& g, int grow, int& x, int& y) {
  x = static_cast<int>(blockIdx.x * blockDim.x + threadIdx.x) - grow;
  y = static_cast<int>(blockIdx.y * blockDim.y + threadIdx.y) - grow;
  return x < g.nx + grow && y < g.ny + grow;
}
// One thread per owned cell.
inline Launch owned_cells(const TileGeom& g) {
  return {dim3(static_cast<unsigned>((g.nx + kBlockX - 1) / kBlockX),
               static_cast<unsigned>((g.ny + kBlockY - 1) / kBlockY)),
          dim3(kBlockX, kBlockY)};
}
// One thread per element of a flat array of n.
inline Launch flat(std::size_t n) {
  return {dim3(static_cast<unsigned>((n + kThreads1D - 1) / kThreads1D)), dim3(kThreads1D)};
}
// The owned cell of this thread; false for the threads past the tile edge.
__device__ __forceinline__ bool owned_cell(const TileGeom& g, int& x, int& y) {
  x = static_cast<int>(blockIdx.x * blockDim.x + threadIdx.x);
  y = static_cast<int>(blockIdx.y * blockDim.y + threadIdx.y);
  return x < g.nx && y < g.ny;
}
__device__ __forceinline__ std::size_t flat_index() {
  return static_cast<std::size_t>(blockIdx.x) * blockDim.x + threadIdx.x;
}

// Sum of one value per thread of a kRowThreads block (integers: exact in any
// order). The result is valid in thread 0.
__device__ __forceinline__ total_t block_sum(total_t v, total_t* shared) {
  shared[threadIdx.x] = v;
  __syncthreads();
  for (int s = kRowThreads / 2; s > 0; s >>= 1) {
    if (static_cast<int>(threadIdx.x) < s) shared[threadIdx.x] += shared[threadIdx.x + s];
    __syncthreads();
  }
  return shared[0];
}

// Neighbour offsets in storage, in the fixed neighbour order (core/grid.h).
struct Offsets {
  long long o[8];
};
inline Offsets neighbour_offsets(int pitch) {
  Offsets off{};
  for (int k = 0; k < 8; ++k)
    off.o[k] = static_cast<long long>(neighbour(k).dy) * pitch + neighbour(k).dx;
  return off;
}

// Cell centre of local cell (x, y) in global metres (as in the CPU backend).
ERG_HD double centre_x(const TileGeom& g, int x) {
  return (g.x0 + x + 0.5) * g.cell_m;
}
ERG_HD double centre_y(const TileGeom& g, int y) {
  return (g.y0 + y + 0.5) * g.cell_m;
}

// Bedrock avalanching has no supply limit (as in the CPU backend).
inline constexpr units_t kUnlimited = std::numeric_limits<units_t>::max() / 4;

// ---- periodic halos (cuda_backend.cu) ---------------------------------------
// Same results as dist::fill_periodic / dist::sum_periodic (dist/exchange.h): every
// ghost within min(width, halo) takes its owner's value; the fold adds every
// ghost into its owner (integer atomics) and zeroes the ghost.
template <class T>
void fill_halo_periodic(T* f, const TileGeom& g, int width);
void fold_halo_periodic(units_t* f, const TileGeom& g, int width);

// ---- the backend --------------------------------------------------------------
class CudaBackend final : public Backend {
 public:
  // `ex` (which must outlive the backend) fills ghosts and sums across tiles;
  // with several tiles, the packed halo frames go through pinned host memory,
  // or straight to MPI where it is CUDA-aware (dist/halo_path.h). The GPU
  // used is local_rank % devices (device_choice.h).
  CudaBackend(const Model& model, dist::Exchange& ex, int local_rank);
  ~CudaBackend() override;
  std::string name() const override { return "cuda"; }
  dist::HaloPath halo_path() const override { return path_; }
  void upload(const TileState& s) override;
  void download(TileState& s) override;
  void download_owned(fields::Id id, std::vector<float>& out) override;
  void upload_owned(fields::Id id, const std::vector<float>& in) override;
  void download_rows(fields::Id id, int y0, int y1, void* out) override;
  void upload_rows(fields::Id id, int y0, int y1, const void* in) override;
  void upload_done() override;

  void ghosts(GhostOp op, std::span<const FieldGhosts> fields) override;
  void obstacles_changed() override;  // updates any_obstacles_

  void heights() override;                                                         // wind.cu
  void wind(Vec2 a) override;                                                      // wind.cu
  void perturb_wind(const std::vector<wind_primitives::Batch>& batches) override;  // wind.cu
  void shadow() override;                                                          // shadow.cu
  void saltation_hop(std::int64_t step) override;                                  // saltation.cu
  void saltation_impact(std::int64_t step) override;                               // saltation.cu
  void reptation() override;                                                       // reptation.cu
  AvalancheResult avalanche_sand(const Refill& refill) override;                   // avalanching.cu
  void avalanche_bedrock(const Refill& refill) override;                           // avalanching.cu

  total_t apply_sand_brush(const events::Brush& b) override;
  total_t apply_bedrock_brush(const events::Brush& b) override;
  void set_vegetation(const events::Region& r) override;
  total_t set_obstacle(const obstacles::Shape& s, bool remove) override;
  Totals totals() override;
  void synchronize() override;

 private:
  void update_repose();  // tan_l from vegetation
  // `settled` (if given): the last iteration found no donor on this tile.
  AvalancheResult avalanche(bool bedrock, int iterations, const Refill& refill,
                            bool* settled = nullptr);  // avalanching.cu
  void coarse_gradients();                             // wind.cu: window_ -> grad_x_, grad_y_
  bool shear_field(Vec2 a);  // wind.cu: window_ -> shear_tau_; false when there is none
  // Per-row partial sums: copy the first `count` of row_sums_ to the host,
  // then add host_rows_[first, first + count) in a fixed order.
  void fetch_rows(int count);
  total_t sum_rows(int first, int count) const;
  // The three ways of ghosts() (dist/halo_path.h).
  void ghosts_periodic(GhostOp op, std::span<const FieldGhosts> fields);
  void ghosts_staged(GhostOp op, std::span<const FieldGhosts> fields);
  void ghosts_direct(GhostOp op, std::span<const FieldGhosts> fields);
  // The host field that stands for a device field in the exchange: the
  // staging copy of its frame (host-staged) or only its type and geometry
  // (CUDA-aware MPI, which reads the device copy, dist::Ghosts::device).
  dist::Ghosts host_ghosts(const FieldGhosts& f);
  // Frame buffers of at least `bytes` (after the copies that use them).
  void frame_capacity(std::size_t bytes);

  Model m_;
  TileGeom g_;
  dist::Exchange& ex_;
  dist::HaloPath path_;
  // Halo copies run on copy_, the stages on kCompute; produced_ orders the
  // copies after the kernels that wrote the fields, staged_ the kernels
  // after the copies back (dist::staging_steps says which overlap what).
  Stream copy_;
  Event produced_, staged_;
  fields::ByField<Field> stage_;              // host staging of ghosts (several tiles), per field
  DeviceBuffer<unsigned char> frame_dev_;     // the listed fields' packed halo frames
  PinnedBuffer frame_host_;                   // ... and their host copy
  std::unique_ptr<dist::HaloPacker> packer_;  // CUDA-aware MPI: packs on the device
  // One padded device buffer per registry entry (core/fields.h, TileGeom::at
  // layout), by id or by the name the stages use (d_.sand, d_.reptation, ...).
  fields::Named<DeviceBuffer> d_;
  DeviceBuffer<units_t>& units(fields::Id id) { return d_.units[id]; }
  DeviceBuffer<float>& reals(fields::Id id) { return d_.reals[id]; }
  bool any_obstacles_ = false;  // on this tile or its ghosts (saltation's slow path)
  // Since bedrock avalanching last found the bedrock settled (as on the CPU);
  // abrasion, found on the device, reaches it through abraded_.
  bool bedrock_changed_ = true;
  // reptation / avalanching work buffers
  DeviceBuffer<units_t> sand_next_;
  DeviceBuffer<float> h_a_, h_b_, frac_;
  DeviceBuffer<units_t> out_;
  DeviceBuffer<double> coarse_mine_;  // this tile's coarse cells
  DeviceBuffer<int> flag_;            // the yes/no of obstacles_changed's reduction
  DeviceBuffer<int> abraded_;         // set by saltation's impact when it abraded bedrock
  DeviceBuffer<int> moved_;           // two flags per avalanching iteration (avalanching.cu)
  // wind warping on the coarse grid (stages/wind_warping.h, TileWindow)
  wind_warping::TileWindow tw_{};
  std::vector<double> window_host_;            // Exchange::coarse_window's output
  DeviceBuffer<double> window_;                // the tile's coarse cells and halo
  DeviceBuffer<double> rows_, smooth_;         // the passes along y and along x
  DeviceBuffer<double> kx_[2], ky_[2];         // Gaussian taps per scale and axis
  DeviceBuffer<float> grad_x_[2], grad_y_[2];  // [tcny + 2][tcnx + 2], scale 0 large, 1 small
  // shear stress over relief (physical modes, stages/shear_stress.h)
  shear_stress::Kernel shear_kernel_;  // host taps of the current direction
  DeviceBuffer<double> shear_k_;       // ... on the device
  DeviceBuffer<int> shear_du_, shear_dv_;
  DeviceBuffer<double> shear_c_;   // the correction's taps for the direction
  DeviceBuffer<double> shear_cp_;  // ... and the lateral correction's
  DeviceBuffer<int> shear_cdu_, shear_cdv_;
  DeviceBuffer<double> shear_slope_, shear_slope_perp_;  // e . grad h, e_perp . grad h
  DeviceBuffer<float> shear_tau_, shear_tau_y_;  // tau1 / tau0, tau_y / tau0, [tcny + 2][tcnx + 2]
  // reductions and downloads
  DeviceBuffer<total_t> row_sums_;  // 3 ny
  std::vector<total_t> host_rows_;
};

}  // namespace erg::gpu

namespace erg {
// Entry points for backend/backend.cpp (cuda_backend.cu).
std::unique_ptr<Backend> make_cuda_backend(const Model& model, dist::Exchange& ex, int local_rank);
bool cuda_runtime_has_device();
}  // namespace erg

// SPDX-License-Identifier: Apache-2.0
// CUDA backend: construction, device selection, upload/download, periodic
// halos, timeline events and exact totals. The stages are in wind.cu,
// shadow.cu, saltation.cu, reptation.cu and avalanching.cu.
#include <algorithm>
#include <cstring>
#include <memory>
#include <stdexcept>
#include <string>
#include <type_traits>

#include "backend/cuda/cuda_backend.h"
#include "backend/device_choice.h"
#include "stages/events.h"
#include "stages/vegetation.h"

namespace erg {
namespace gpu {

// ---- errors -------------------------------------------------------------------

void fail(const char* what, const char* detail) {
  throw std::runtime_error(std::string("CUDA backend: ") + what + " failed: " + detail);
}

void check_launch(const char* kernel) {
  const cudaError_t e = cudaGetLastError();
  if (e != cudaSuccess) fail((std::string("launch of ") + kernel).c_str(), cudaGetErrorString(e));
}

// ---- periodic halos -------------------------------------------------------------

namespace {

__device__ __forceinline__ int wrap(int v, int n) {
  return ((v % n) + n) % n;
}

// Cells of the ghost ring of width w: the w ghost rows above and below (full
// padded width nx + 2w), then the 2w ghost columns of every owned row.
__host__ __device__ __forceinline__ std::size_t ring_size(const TileGeom& g, int w) {
  return 2 * static_cast<std::size_t>(w) * static_cast<std::size_t>(g.nx + 2 * w) +
         static_cast<std::size_t>(g.ny) * static_cast<std::size_t>(2 * w);
}
__device__ __forceinline__ void ring_cell(const TileGeom& g, int w, std::size_t i, int& x, int& y) {
  const std::size_t row = static_cast<std::size_t>(g.nx + 2 * w);
  const std::size_t strip = static_cast<std::size_t>(w) * row;
  if (i < strip) {
    y = -w + static_cast<int>(i / row);
    x = -w + static_cast<int>(i % row);
  } else if (i < 2 * strip) {
    i -= strip;
    y = g.ny + static_cast<int>(i / row);
    x = -w + static_cast<int>(i % row);
  } else {
    i -= 2 * strip;
    const std::size_t cols = static_cast<std::size_t>(2 * w);
    y = static_cast<int>(i / cols);
    const int c = static_cast<int>(i % cols);
    x = c < w ? c - w : g.nx + (c - w);
  }
}

// Every ghost reads its owner (an owned cell, never a ghost): no ordering needed.
template <class T>
__global__ void fill_halo_kernel(T* f, TileGeom g, int w) {
  const std::size_t i = flat_index();
  if (i >= ring_size(g, w)) return;
  int x, y;
  ring_cell(g, w, i, x, y);
  f[g.at(x, y)] = f[g.at(wrap(x, g.nx), wrap(y, g.ny))];
}

// Every ghost adds itself into its owner and is zeroed. Owners are owned
// cells, never ghosts; several ghosts may share an owner when the halo is wider
// than the tile: integer atomics, exact in any order.
__global__ void fold_halo_kernel(units_t* f, TileGeom g, int w) {
  const std::size_t i = flat_index();
  if (i >= ring_size(g, w)) return;
  int x, y;
  ring_cell(g, w, i, x, y);
  units_t& v = f[g.at(x, y)];
  if (v != 0) {
    atomicAdd(reinterpret_cast<unsigned long long*>(f + g.at(wrap(x, g.nx), wrap(y, g.ny))),
              static_cast<unsigned long long>(v));
    v = 0;
  }
}

}  // namespace

template <class T>
void fill_halo_periodic(T* f, const TileGeom& g, int width) {
  const int w = width < g.halo ? width : g.halo;
  if (w <= 0) return;
  const Launch l = flat(ring_size(g, w));
  ERG_LAUNCH(fill_halo_kernel<T>, l.grid, l.block, f, g, w);
}

void fold_halo_periodic(units_t* f, const TileGeom& g, int width) {
  const int w = width < g.halo ? width : g.halo;
  if (w <= 0) return;
  const Launch l = flat(ring_size(g, w));
  ERG_LAUNCH(fold_halo_kernel, l.grid, l.block, f, g, w);
}

template void fill_halo_periodic(units_t*, const TileGeom&, int);
template void fill_halo_periodic(float*, const TileGeom&, int);

// ---- kernels: events, repose, totals, downloads ------------------------------------

namespace {

__global__ void repose_kernel(TileGeom g, const float* vegetation, float* tan_l, float tan_bare,
                              float tan_vegetated) {
  int x, y;
  if (!owned_cell(g, x, y)) return;
  const std::size_t i = g.at(x, y);
  tan_l[i] = vegetation::repose_tan(vegetation[i], tan_bare, tan_vegetated);
}

// One block per row; the row's exact change goes to row_change[y].
__global__ void sand_brush_kernel(TileGeom g, events::Brush b, units_t* sand, const float* ob,
                                  total_t* row_change) {
  __shared__ total_t red[kRowThreads];
  const int y = static_cast<int>(blockIdx.x);
  units_t* s = sand + g.at(0, y);
  const float* o = ob + g.at(0, y);
  total_t change = 0;
  for (int x = static_cast<int>(threadIdx.x); x < g.nx; x += kRowThreads) {
    const units_t d = events::sand_brush_change(b, centre_x(g, x), centre_y(g, y), s[x], o[x]);
    s[x] += d;
    change += d;
  }
  change = block_sum(change, red);
  if (threadIdx.x == 0) row_change[y] = change;
}

__global__ void bedrock_brush_kernel(TileGeom g, events::Brush b, units_t* bedrock,
                                     total_t* row_change) {
  __shared__ total_t red[kRowThreads];
  const int y = static_cast<int>(blockIdx.x);
  units_t* r = bedrock + g.at(0, y);
  total_t change = 0;
  for (int x = static_cast<int>(threadIdx.x); x < g.nx; x += kRowThreads) {
    const units_t d = events::brush_units(b, centre_x(g, x), centre_y(g, y));
    r[x] += d;
    change += d;
  }
  change = block_sum(change, red);
  if (threadIdx.x == 0) row_change[y] = change;
}

__global__ void vegetation_kernel(TileGeom g, events::Region r, float* vegetation) {
  int x, y;
  if (!owned_cell(g, x, y)) return;
  if (events::in_region(r, centre_x(g, x), centre_y(g, y))) vegetation[g.at(x, y)] = r.value;
}

// One block per row: rows[y], rows[ny + y], rows[2 ny + y] = sand, airborne,
// bedrock of row y.
__global__ void totals_kernel(TileGeom g, const units_t* sand, const units_t* airborne,
                              const units_t* bedrock, total_t* rows) {
  __shared__ total_t rs[kRowThreads], ra[kRowThreads], rb[kRowThreads];
  const int y = static_cast<int>(blockIdx.x);
  const std::size_t row = g.at(0, y);
  total_t s = 0, a = 0, b = 0;
  for (int x = static_cast<int>(threadIdx.x); x < g.nx; x += kRowThreads) {
    s += sand[row + x];
    a += airborne[row + x];
    b += bedrock[row + x];
  }
  s = block_sum(s, rs);
  a = block_sum(a, ra);
  b = block_sum(b, rb);
  if (threadIdx.x == 0) {
    rows[y] = s;
    rows[g.ny + y] = a;
    rows[2 * g.ny + y] = b;
  }
}

}  // namespace

// ---- the backend ------------------------------------------------------------------

CudaBackend::CudaBackend(const Model& model, dist::Exchange& ex, int local_rank)
    : m_(model), g_(model.tile), ex_(ex) {
  int devices = 0;
  ERG_CUDA_CHECK(cudaGetDeviceCount(&devices));
  ERG_CUDA_CHECK(cudaSetDevice(device_for_rank(local_rank, devices)));

  const std::size_t n = g_.size();
  fields::each([&](fields::Id id, const fields::Info& f) {
    // (Every registry default is 0, what DeviceBuffer::reset leaves.)
    if (f.type == fields::Type::kUnits)
      units(id).reset(n);
    else
      reals(id).reset(n);
  });
  sand_next_.reset(n);
  flag_.reset(1);
  abraded_.reset(1);
  h_a_.reset(n);
  h_b_.reset(n);
  frac_.reset(n);
  out_.reset(n);
  coarse_mine_.reset(static_cast<std::size_t>(g_.nx / m_.coarse.cx) * (g_.ny / m_.coarse.cy));
  moved_.reset(
      2 * static_cast<std::size_t>(std::max({m_.avalanche_iterations, m_.bedrock_iterations, 1})));

  // Coarse grid of the wind warping: buffers and the Gaussian taps, made on
  // the host by the same function as the CPU's (wind_warping::gaussian_kernel).
  const CoarseGrid& c = m_.coarse;
  tw_ = {g_.nx / c.cx, g_.ny / c.cy, c.halo_x, c.halo_y};
  window_.reset(static_cast<std::size_t>(tw_.wx()) * tw_.wy());
  rows_.reset(static_cast<std::size_t>(tw_.tcny + 4) * tw_.wx());
  smooth_.reset(static_cast<std::size_t>(tw_.tcny + 4) * (tw_.tcnx + 4));
  const std::size_t gn = static_cast<std::size_t>(tw_.tcnx + 2) * (tw_.tcny + 2);
  for (int s = 0; s < 2; ++s) {
    grad_x_[s].reset(gn);
    grad_y_[s].reset(gn);
    for (int axis = 0; axis < 2; ++axis) {
      const int r = axis == 0 ? c.radius_x[s] : c.radius_y[s];
      std::vector<double> w(2 * static_cast<std::size_t>(r) + 1);
      wind_warping::gaussian_kernel(c.sigma_m[s], (axis == 0 ? c.cx : c.cy) * c.cell_m, r,
                                    w.data());
      DeviceBuffer<double>& d = axis == 0 ? kx_[s] : ky_[s];
      d.reset(w.size());
      ERG_CUDA_CHECK(
          cudaMemcpy(d.get(), w.data(), w.size() * sizeof(double), cudaMemcpyHostToDevice));
    }
  }

  row_sums_.reset(3 * static_cast<std::size_t>(g_.ny));
  host_rows_.assign(3 * static_cast<std::size_t>(g_.ny), 0);
}

namespace {
template <class T>
void copy_in(DeviceBuffer<T>& d, const Field<T>& h, const char* name) {
  if (h.size() != d.size())
    throw std::runtime_error(std::string("CUDA backend: upload: field ") + name +
                             " does not have the tile's padded size");
  ERG_CUDA_CHECK(cudaMemcpy(d.get(), h.data(), d.bytes(), cudaMemcpyHostToDevice));
}
template <class T>
void copy_out(const DeviceBuffer<T>& d, Field<T>& h, const TileGeom& g) {
  h.reset(g);
  ERG_CUDA_CHECK(cudaMemcpy(h.data(), d.get(), d.bytes(), cudaMemcpyDeviceToHost));
}
}  // namespace

void CudaBackend::upload(const TileState& s) {
  fields::each([&](fields::Id id, const fields::Info& f) {
    if (!f.state) return;
    if (f.type == fields::Type::kUnits)
      copy_in(units(id), s.units[id], f.name);
    else
      copy_in(reals(id), s.reals[id], f.name);
  });
  bedrock_changed_ = true;
  update_repose();
}

namespace {
// Sets *any when a cell, ghosts included (as on the CPU), holds an obstacle.
// Every writer writes the same 1, so the unordered stores race harmlessly.
__global__ void any_obstacle_kernel(const float* o, std::size_t n, int* any) {
  const std::size_t i = flat_index();
  if (i < n && obstacles::is_obstacle(o[i])) *any = 1;
}
}  // namespace

// A device-side reduction to one flag: 4 bytes cross PCIe, not the field.
void CudaBackend::obstacles_changed() {
  int any = 0;
  ERG_CUDA_CHECK(cudaMemset(flag_.get(), 0, sizeof(int)));
  const Launch l = flat(d_.obstacles.size());
  ERG_LAUNCH(any_obstacle_kernel, l.grid, l.block, d_.obstacles.get(), d_.obstacles.size(),
             flag_.get());
  ERG_CUDA_CHECK(cudaMemcpy(&any, flag_.get(), sizeof(int), cudaMemcpyDeviceToHost));
  any_obstacles_ = any != 0;
}

// Rare (timeline events): on the host, as the CPU backend does it.
total_t CudaBackend::set_obstacle(const obstacles::Shape& sh, bool remove) {
  Field<float> o;
  Field<units_t> s, a;
  copy_out(d_.obstacles, o, g_);
  copy_out(d_.sand, s, g_);
  copy_out(d_.airborne, a, g_);
  total_t change = 0;
  for (int y = 0; y < g_.ny; ++y)
    for (int x = 0; x < g_.nx; ++x) {
      change -= obstacles::edit_cell(sh, remove, centre_x(g_, x), centre_y(g_, y), o(x, y), s(x, y),
                                     a(x, y));
    }
  copy_in(d_.obstacles, o, "obstacles");
  copy_in(d_.sand, s, "sand");
  copy_in(d_.airborne, a, "airborne");
  std::vector<total_t> all{change};
  ex_.sum_exact(all);
  return all[0];
}

void CudaBackend::download(TileState& s) {
  s.geom = g_;
  fields::each([&](fields::Id id, const fields::Info& f) {
    if (!f.state) return;
    if (f.type == fields::Type::kUnits)
      copy_out(units(id), s.units[id], g_);
    else
      copy_out(reals(id), s.reals[id], g_);
  });
}

namespace {
// The owned cells of a padded device field, row-major.
template <class T>
std::vector<T> owned_of(const DeviceBuffer<T>& d, const TileGeom& g) {
  std::vector<T> out(static_cast<std::size_t>(g.nx) * g.ny);
  ERG_CUDA_CHECK(cudaMemcpy2D(out.data(), sizeof(T) * g.nx, d.get() + g.at(0, 0),
                              sizeof(T) * g.pitch, sizeof(T) * g.nx, g.ny, cudaMemcpyDeviceToHost));
  return out;
}
}  // namespace

void CudaBackend::download_owned(fields::Id id, std::vector<float>& out) {
  if (fields::info(id).type == fields::Type::kFloat) {
    out = owned_of(reals(id), g_);
    return;
  }
  const std::vector<units_t> u = owned_of(units(id), g_);
  out.resize(u.size());
  for (std::size_t i = 0; i < u.size(); ++i) out[i] = static_cast<float>(units_to_m_d(u[i]));
}

void CudaBackend::upload_owned(fields::Id id, const std::vector<float>& in) {
  check_owned_upload(id, in, g_);
  ERG_CUDA_CHECK(cudaMemcpy2D(reals(id).get() + g_.at(0, 0), sizeof(float) * g_.pitch, in.data(),
                              sizeof(float) * g_.nx, sizeof(float) * g_.nx, g_.ny,
                              cudaMemcpyHostToDevice));
}

void CudaBackend::update_repose() {
  const Launch l = owned_cells(g_);
  ERG_LAUNCH(repose_kernel, l.grid, l.block, g_, d_.vegetation.get(), d_.tan_l.get(), m_.tan_l_sand,
             m_.tan_l_vegetated);
}

void CudaBackend::fetch_rows(int count) {
  ERG_CUDA_CHECK(cudaMemcpy(host_rows_.data(), row_sums_.get(), sizeof(total_t) * count,
                            cudaMemcpyDeviceToHost));
}

total_t CudaBackend::sum_rows(int first, int count) const {
  total_t t = 0;
  for (int y = 0; y < count; ++y) t += host_rows_[static_cast<std::size_t>(first) + y];
  return t;
}

total_t CudaBackend::apply_sand_brush(const events::Brush& b) {
  ERG_LAUNCH(sand_brush_kernel, dim3(g_.ny), dim3(kRowThreads), g_, b, d_.sand.get(),
             d_.obstacles.get(), row_sums_.get());
  fetch_rows(g_.ny);
  std::vector<total_t> all{sum_rows(0, g_.ny)};
  ex_.sum_exact(all);
  return all[0];
}

total_t CudaBackend::apply_bedrock_brush(const events::Brush& b) {
  bedrock_changed_ = true;
  ERG_LAUNCH(bedrock_brush_kernel, dim3(g_.ny), dim3(kRowThreads), g_, b, d_.bedrock.get(),
             row_sums_.get());
  fetch_rows(g_.ny);
  std::vector<total_t> all{sum_rows(0, g_.ny)};
  ex_.sum_exact(all);
  return all[0];
}

void CudaBackend::set_vegetation(const events::Region& r) {
  const Launch l = owned_cells(g_);
  ERG_LAUNCH(vegetation_kernel, l.grid, l.block, g_, r, d_.vegetation.get());
  update_repose();
}

Totals CudaBackend::totals() {
  ERG_LAUNCH(totals_kernel, dim3(g_.ny), dim3(kRowThreads), g_, d_.sand.get(), d_.airborne.get(),
             d_.bedrock.get(), row_sums_.get());
  fetch_rows(3 * g_.ny);
  std::vector<total_t> all{sum_rows(0, g_.ny), sum_rows(g_.ny, g_.ny), sum_rows(2 * g_.ny, g_.ny)};
  ex_.sum_exact(all);
  return {all[0], all[1], all[2]};
}

namespace {
template <class T>
__global__ void pack_frame_kernel(const T* f, TileGeom g, dist::HaloFrame fr, T* out) {
  const std::size_t i = flat_index();
  if (i >= fr.size()) return;
  int x, y;
  fr.cell(i, x, y);
  out[i] = f[g.at(x, y)];
}

template <class T>
__global__ void unpack_frame_kernel(const T* in, TileGeom g, dist::HaloFrame fr, T* f) {
  const std::size_t i = flat_index();
  if (i >= fr.size()) return;
  int x, y;
  fr.cell(i, x, y);
  f[g.at(x, y)] = in[i];
}
}  // namespace

// The frame of width w (at most the halo) and its two staging buffers, sized
// for elements of `elem` bytes; the bytes are counted as staged (one way).
CudaBackend::FrameStaging CudaBackend::frame_staging(int w, std::size_t elem) {
  FrameStaging s{dist::HaloFrame{g_.nx, g_.ny, w < g_.halo ? w : g_.halo}, 0, nullptr, nullptr};
  s.bytes = s.frame.size() * elem;
  if (s.bytes == 0) return s;
  if (frame_dev_.size() < s.bytes) frame_dev_.reset(s.bytes);
  s.device = frame_dev_.get();
  s.host = frame_host_.at_least(s.bytes);
  ex_.count_host_staged(static_cast<long long>(s.bytes));
  return s;
}

template <class T>
void CudaBackend::frame_to_host(const DeviceBuffer<T>& d, Field<T>& h, int w) {
  const FrameStaging s = frame_staging(w, sizeof(T));
  if (s.bytes == 0) return;
  const Launch l = flat(s.frame.size());
  ERG_LAUNCH(pack_frame_kernel<T>, l.grid, l.block, d.get(), g_, s.frame,
             static_cast<T*>(s.device));
  ERG_CUDA_CHECK(cudaMemcpy(s.host, s.device, s.bytes, cudaMemcpyDeviceToHost));
  dist::unpack_frame(static_cast<const T*>(s.host), s.frame, h);
}

template <class T>
void CudaBackend::frame_to_device(const Field<T>& h, DeviceBuffer<T>& d, int w) {
  const FrameStaging s = frame_staging(w, sizeof(T));
  if (s.bytes == 0) return;
  dist::pack_frame(h, s.frame, static_cast<T*>(s.host));
  ERG_CUDA_CHECK(cudaMemcpy(s.device, s.host, s.bytes, cudaMemcpyHostToDevice));
  const Launch l = flat(s.frame.size());
  ERG_LAUNCH(unpack_frame_kernel<T>, l.grid, l.block, static_cast<const T*>(s.device), g_, s.frame,
             d.get());
}

// On one tile the periodic wrap runs on the device (a fill copies owners
// into ghosts, a sum folds ghosts into owners). With several tiles only each
// field's halo frame (the ghosts and the owned cells within the width of the
// edge, dist/halo_frame.h) crosses to its host staging field, where the
// exchange sends all of them in one message per neighbour, and back.
void CudaBackend::ghosts(GhostOp op, std::span<const FieldGhosts> fields) {
  const auto is_units = [](fields::Id id) { return fields::info(id).type == fields::Type::kUnits; };
  if (ex_.tiles() == 1) {
    if (op == GhostOp::kFinishFill) return;  // done at kBeginFill
    for (const FieldGhosts& f : fields) {
      if (op == GhostOp::kSum) {
        if (!is_units(f.id)) throw std::logic_error("CUDA backend: ghost sums are of units fields");
        fold_halo_periodic(units(f.id).get(), g_, f.width);
      } else if (is_units(f.id)) {
        fill_halo_periodic(units(f.id).get(), g_, f.width);
      } else {
        fill_halo_periodic(reals(f.id).get(), g_, f.width);
      }
    }
    return;
  }
  std::vector<dist::Ghosts> list;
  for (const FieldGhosts& f : fields) {
    if (is_units(f.id)) {
      Field<units_t>& host = stage_.units[f.id];
      if (host.size() != units(f.id).size()) host.reset(g_);
      if (op != GhostOp::kFinishFill) frame_to_host(units(f.id), host, f.width);
      list.push_back({&host, f.width});
    } else {
      Field<float>& host = stage_.reals[f.id];
      if (host.size() != reals(f.id).size()) host.reset(g_);
      if (op != GhostOp::kFinishFill) frame_to_host(reals(f.id), host, f.width);
      list.push_back({&host, f.width});
    }
  }
  ex_.ghosts(op, list);
  if (op == GhostOp::kBeginFill) return;  // uploaded at kFinishFill
  for (const FieldGhosts& f : fields) {
    if (is_units(f.id))
      frame_to_device(stage_.units[f.id], units(f.id), f.width);
    else
      frame_to_device(stage_.reals[f.id], reals(f.id), f.width);
  }
}

void CudaBackend::synchronize() {
  ERG_CUDA_CHECK(cudaDeviceSynchronize());
}

}  // namespace gpu

// ---- entry points for backend/backend.cpp ----------------------------------------

std::unique_ptr<Backend> make_cuda_backend(const Model& model, dist::Exchange& ex, int local_rank) {
  return std::make_unique<gpu::CudaBackend>(model, ex, local_rank);
}

bool cuda_runtime_has_device() {
  int count = 0;
  const cudaError_t e = cudaGetDeviceCount(&count);
  if (e != cudaSuccess) {
    (void)cudaGetLastError();  // leave no error behind for later calls
    return false;
  }
  return count > 0;
}

CudaDeviceInfo cuda_runtime_device_info(int local_rank) {
  int count = 0;
  ERG_CUDA_CHECK(cudaGetDeviceCount(&count));
  const int device = local_rank % count;
  ERG_CUDA_CHECK(cudaSetDevice(device));
  cudaDeviceProp p{};
  ERG_CUDA_CHECK(cudaGetDeviceProperties(&p, device));
  CudaDeviceInfo info;
  info.name = p.name;
  info.major = p.major;
  info.minor = p.minor;
  info.memory_bytes = static_cast<double>(p.totalGlobalMem);
  info.multiprocessors = p.multiProcessorCount;
  ERG_CUDA_CHECK(cudaRuntimeGetVersion(&info.runtime_version));
  ERG_CUDA_CHECK(cudaDriverGetVersion(&info.driver_version));
  // A copy far larger than the L2 (50 MiB on an H100/H200): the rate at
  // which a streaming kernel can read and write device memory.
  const std::size_t n = std::size_t{256} << 20;
  gpu::DeviceBuffer<unsigned char> a, b;
  a.reset(n);
  b.reset(n);
  cudaEvent_t start = nullptr, stop = nullptr;
  ERG_CUDA_CHECK(cudaEventCreate(&start));
  ERG_CUDA_CHECK(cudaEventCreate(&stop));
  ERG_CUDA_CHECK(cudaMemcpy(b.get(), a.get(), n, cudaMemcpyDeviceToDevice));  // warm-up
  float best_ms = 0;
  for (int rep = 0; rep < 10; ++rep) {
    ERG_CUDA_CHECK(cudaEventRecord(start));
    ERG_CUDA_CHECK(cudaMemcpy(b.get(), a.get(), n, cudaMemcpyDeviceToDevice));
    ERG_CUDA_CHECK(cudaEventRecord(stop));
    ERG_CUDA_CHECK(cudaEventSynchronize(stop));
    float ms = 0;
    ERG_CUDA_CHECK(cudaEventElapsedTime(&ms, start, stop));
    if (rep == 0 || ms < best_ms) best_ms = ms;
  }
  ERG_CUDA_CHECK(cudaEventDestroy(start));
  ERG_CUDA_CHECK(cudaEventDestroy(stop));
  info.copy_bytes_per_s = best_ms > 0 ? 2.0 * static_cast<double>(n) / (best_ms * 1e-3) : 0.0;
  return info;
}

}  // namespace erg

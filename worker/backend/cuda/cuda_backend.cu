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
#include <variant>
#include <vector>

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

// ---- the device packer of a CUDA-aware MPI ------------------------------------

namespace {

// One thread per cell of a rectangle of a padded field, row by row.
__device__ __forceinline__ bool rect_cell(const dist::Rect& r, int& x, int& y, std::size_t& i) {
  i = flat_index();
  const std::size_t w = static_cast<std::size_t>(r.x1 - r.x0);
  if (i >= w * static_cast<std::size_t>(r.y1 - r.y0)) return false;
  x = r.x0 + static_cast<int>(i % w);
  y = r.y0 + static_cast<int>(i / w);
  return true;
}
template <class T>
__global__ void rect_pack_kernel(const T* f, TileGeom g, dist::Rect r, T* out) {
  int x, y;
  std::size_t i;
  if (rect_cell(r, x, y, i)) out[i] = f[g.at(x, y)];
}
// Each cell once: a plain add is the host packer's add, bit for bit.
template <class T>
__global__ void rect_unpack_kernel(const T* in, TileGeom g, dist::Rect r, bool add, T* f) {
  int x, y;
  std::size_t i;
  if (!rect_cell(r, x, y, i)) return;
  T& c = f[g.at(x, y)];
  c = add ? c + in[i] : in[i];
}
template <class T>
__global__ void rect_zero_kernel(TileGeom g, dist::Rect r, T* f) {
  int x, y;
  std::size_t i;
  if (rect_cell(r, x, y, i)) f[g.at(x, y)] = T{};
}

std::size_t cells_of(const dist::Rect& r) {
  return static_cast<std::size_t>(r.x1 - r.x0) * static_cast<std::size_t>(r.y1 - r.y0);
}

// Packs the fields' device copies (dist::Ghosts::device) into device
// buffers that a CUDA-aware MPI reads and writes, on the backend's copy
// stream; the host fields of the list name only type and geometry.
class DevicePacker final : public dist::HaloPacker {
 public:
  DevicePacker(cudaStream_t s, bool managed) : s_(s), managed_(managed) {}
  ~DevicePacker() override {
    for (void* p : buf_)
      if (p) cudaFree(p);  // no throw from a destructor
  }
  DevicePacker(const DevicePacker&) = delete;
  DevicePacker& operator=(const DevicePacker&) = delete;
  char* buffer(int slot, std::size_t bytes) override {
    void*& p = buf_[slot];
    if (bytes_[slot] < bytes) {
      ERG_CUDA_CHECK(cudaStreamSynchronize(s_));
      if (p) ERG_CUDA_CHECK(cudaFree(p));
      p = nullptr;
      bytes_[slot] = 0;
      if (managed_)
        ERG_CUDA_CHECK(cudaMallocManaged(&p, bytes));
      else
        ERG_CUDA_CHECK(cudaMalloc(&p, bytes));
      bytes_[slot] = bytes;
    }
    return static_cast<char*>(p);
  }
  void pack(std::span<const dist::Ghosts> parts, const dist::RectOf& rect, char* dst) override {
    each(parts, rect, [&](auto* f, const TileGeom& g, const dist::Rect& r) {
      using T = std::remove_const_t<std::remove_pointer_t<decltype(f)>>;
      const Launch k = flat(cells_of(r));
      ERG_LAUNCH_ON(s_, rect_pack_kernel<T>, k.grid, k.block, f, g, r, reinterpret_cast<T*>(dst));
      dst += cells_of(r) * sizeof(T);
    });
  }
  void unpack(std::span<const dist::Ghosts> parts, const dist::RectOf& rect, const char* src,
              bool add) override {
    each(parts, rect, [&](auto* f, const TileGeom& g, const dist::Rect& r) {
      using T = std::remove_const_t<std::remove_pointer_t<decltype(f)>>;
      const Launch k = flat(cells_of(r));
      ERG_LAUNCH_ON(s_, rect_unpack_kernel<T>, k.grid, k.block, reinterpret_cast<const T*>(src), g,
                    r, add, f);
      src += cells_of(r) * sizeof(T);
    });
  }
  void zero(std::span<const dist::Ghosts> parts, const dist::RectOf& rect) override {
    each(parts, rect, [&](auto* f, const TileGeom& g, const dist::Rect& r) {
      using T = std::remove_const_t<std::remove_pointer_t<decltype(f)>>;
      const Launch k = flat(cells_of(r));
      ERG_LAUNCH_ON(s_, rect_zero_kernel<T>, k.grid, k.block, g, r, f);
    });
  }
  // MPI reads the send buffers only once their packing kernels are done.
  void ready() override { ERG_CUDA_CHECK(cudaStreamSynchronize(s_)); }

 private:
  // f(device storage, geometry, rectangle) for every field with a width > 0.
  template <class F>
  static void each(std::span<const dist::Ghosts> parts, const dist::RectOf& rect, F&& f) {
    for (const dist::Ghosts& p : parts) {
      if (p.width <= 0) continue;
      if (!p.device) throw std::logic_error("CUDA backend: a halo field without its device copy");
      std::visit(
          [&](auto* host) {
            using T = typename std::remove_reference_t<decltype(*host)>::value_type;
            const dist::Rect r = rect(p.width);
            if (cells_of(r) > 0) f(static_cast<T*>(p.device), host->geom(), r);
          },
          p.field);
    }
  }
  cudaStream_t s_;
  bool managed_;
  void* buf_[8] = {};
  std::size_t bytes_[8] = {};
};

}  // namespace

std::unique_ptr<dist::HaloPacker> make_device_packer(cudaStream_t s, bool managed) {
  return std::make_unique<DevicePacker>(s, managed);
}

namespace {
// Selects this rank's device, then the halo path: the first member that
// needs either, before the streams and events, which belong to the device
// current when they are made.
dist::HaloPath select_device_and_path(int local_rank, const dist::Exchange& ex) {
  int devices = 0;
  ERG_CUDA_CHECK(cudaGetDeviceCount(&devices));
  ERG_CUDA_CHECK(cudaSetDevice(device_for_rank(local_rank, devices)));
  return dist::choose_halo_path(true, ex.tiles(), ex.cuda_support());
}
}  // namespace

CudaBackend::CudaBackend(const Model& model, dist::Exchange& ex, int local_rank)
    : m_(model), g_(model.tile), ex_(ex), path_(select_device_and_path(local_rank, ex)) {
  if (path_ == dist::HaloPath::kDeviceDirect) {
    packer_ = make_device_packer(copy_.get(), false);
    ex_.set_packer(packer_.get());
  }

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

  if (m_.shear.on) {
    shear_slope_.reset(static_cast<std::size_t>(tw_.wx()) * tw_.wy());
    shear_slope_perp_.reset(static_cast<std::size_t>(tw_.wx()) * tw_.wy());
    shear_tau_.reset(gn);
    shear_tau_y_.reset(gn);
    const std::size_t taps =
        static_cast<std::size_t>(shear_stress::kernel_capacity(m_.shear.radius));
    shear_k_.reset(taps);
    shear_du_.reset(taps);
    shear_dv_.reset(taps);
  }

  row_sums_.reset(3 * static_cast<std::size_t>(g_.ny));
  host_rows_.assign(3 * static_cast<std::size_t>(g_.ny), 0);
}

CudaBackend::~CudaBackend() {
  if (!packer_) return;
  try {
    ex_.set_packer(nullptr);  // the exchange outlives this backend
  } catch (...) {
    // In flight (the run failed mid-exchange): the exchange is not used again.
  }
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

void CudaBackend::download_rows(fields::Id id, int y0, int y1, void* out) {
  check_rows(id, y0, y1, g_, false);
  if (y1 == y0) return;
  const std::size_t e = stored_bytes(id);
  const void* src = fields::info(id).type == fields::Type::kUnits
                        ? static_cast<const void*>(units(id).get() + g_.at(0, y0))
                        : static_cast<const void*>(reals(id).get() + g_.at(0, y0));
  ERG_CUDA_CHECK(cudaMemcpy2D(out, e * g_.nx, src, e * g_.pitch, e * g_.nx,
                              static_cast<std::size_t>(y1 - y0), cudaMemcpyDeviceToHost));
}

void CudaBackend::upload_rows(fields::Id id, int y0, int y1, const void* in) {
  check_rows(id, y0, y1, g_, true);
  if (y1 == y0) return;
  const std::size_t e = stored_bytes(id);
  void* dst = fields::info(id).type == fields::Type::kUnits
                  ? static_cast<void*>(units(id).get() + g_.at(0, y0))
                  : static_cast<void*>(reals(id).get() + g_.at(0, y0));
  ERG_CUDA_CHECK(cudaMemcpy2D(dst, e * g_.pitch, in, e * g_.nx, e * g_.nx,
                              static_cast<std::size_t>(y1 - y0), cudaMemcpyHostToDevice));
}

void CudaBackend::upload_done() {
  bedrock_changed_ = true;
  update_repose();
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

// ghosts_only (after a fill): the owned cells are left alone, so the copy
// back may run while kernels read them (dist::staging_steps).
template <class T>
__global__ void unpack_frame_kernel(const T* in, TileGeom g, dist::HaloFrame fr, bool ghosts_only,
                                    T* f) {
  const std::size_t i = flat_index();
  if (i >= fr.size()) return;
  int x, y;
  fr.cell(i, x, y);
  if (ghosts_only && fr.owned(x, y)) return;
  f[g.at(x, y)] = in[i];
}

bool is_units(fields::Id id) {
  return fields::info(id).type == fields::Type::kUnits;
}
}  // namespace

// Both grow together, so the pinned buffer is never smaller than the device one.
void CudaBackend::frame_capacity(std::size_t bytes) {
  if (frame_dev_.size() >= bytes) return;
  ERG_CUDA_CHECK(cudaStreamSynchronize(copy_.get()));  // nothing may still use the old ones
  frame_dev_.reset(bytes);
  frame_host_.at_least(bytes);
}

dist::Ghosts CudaBackend::host_ghosts(const FieldGhosts& f) {
  if (is_units(f.id)) {
    Field<units_t>& host = stage_.units[f.id];
    if (host.size() != units(f.id).size()) host.reset(g_);
    return {&host, f.width, units(f.id).get()};
  }
  Field<float>& host = stage_.reals[f.id];
  if (host.size() != reals(f.id).size()) host.reset(g_);
  return {&host, f.width, reals(f.id).get()};
}

// One tile: the periodic wrap on the device (a fill copies owners into
// ghosts, a sum folds ghosts into owners).
void CudaBackend::ghosts_periodic(GhostOp op, std::span<const FieldGhosts> fields) {
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
}

// Several tiles, MPI on host memory: the listed fields' halo frames (the
// ghosts and the owned cells within the width of the edge,
// dist/halo_frame.h), one after another in one buffer (dist::frame_layout),
// packed on copy_ and copied to pinned memory in one copy; unpacked into the
// host fields the exchange works on; and back. dist::staging_steps says
// which of these each operation does: a split fill downloads at kBeginFill
// and returns, so that the copy overlaps the wind warping's kernels, and at
// kFinishFill exchanges and queues the copy back, which the following
// kernels wait for on the device, not the host.
void CudaBackend::ghosts_staged(GhostOp op, std::span<const FieldGhosts> fields) {
  const dist::StagingSteps st = dist::staging_steps(op);
  std::vector<int> widths;
  std::vector<std::size_t> elems;
  for (const FieldGhosts& f : fields) {
    widths.push_back(f.width);
    elems.push_back(is_units(f.id) ? sizeof(units_t) : sizeof(float));
  }
  const dist::FrameLayout l = dist::frame_layout(g_, widths, elems);
  const cudaStream_t cs = copy_.get();
  // Calls f(field's device buffer, its slot) for every listed field with a frame.
  const auto each = [&](auto&& f) {
    for (std::size_t i = 0; i < fields.size(); ++i) {
      const dist::FrameSlot& slot = l.slots[i];
      if (slot.bytes == 0) continue;
      if (is_units(fields[i].id))
        f(units(fields[i].id), stage_.units[fields[i].id], slot);
      else
        f(reals(fields[i].id), stage_.reals[fields[i].id], slot);
    }
  };
  unsigned char* dev = nullptr;
  unsigned char* host = nullptr;
  if (l.bytes > 0) {
    if (st.download)
      frame_capacity(l.bytes);
    else if (frame_dev_.size() < l.bytes)
      throw std::logic_error("CUDA backend: a kFinishFill without its kBeginFill");
    dev = frame_dev_.get();
    host = static_cast<unsigned char*>(frame_host_.at_least(l.bytes));
  }
  std::vector<dist::Ghosts> list;
  for (const FieldGhosts& f : fields) list.push_back(host_ghosts(f));

  if (st.download && l.bytes > 0) {
    stream_waits(cs, kCompute, produced_);  // after the kernels that wrote the fields
    each([&](auto& d, auto&, const dist::FrameSlot& slot) {
      using T = std::remove_reference_t<decltype(*d.get())>;
      const Launch k = flat(slot.frame.size());
      ERG_LAUNCH_ON(cs, pack_frame_kernel<T>, k.grid, k.block, d.get(), g_, slot.frame,
                    reinterpret_cast<T*>(dev + slot.offset));
    });
    ERG_CUDA_CHECK(cudaMemcpyAsync(host, dev, l.bytes, cudaMemcpyDeviceToHost, cs));
    ex_.count_host_staged(dist::staged_bytes({true, false, GhostOp::kFill, false, false}, l));
  }
  if (!st.exchange) return;
  // The host reads the pinned frames once copy_ is done (the stages may
  // still run on kCompute).
  ERG_CUDA_CHECK(cudaStreamSynchronize(cs));
  each([&](auto&, auto& h, const dist::FrameSlot& slot) {
    using T = typename std::remove_reference_t<decltype(h)>::value_type;
    dist::unpack_frame(reinterpret_cast<const T*>(host + slot.offset), slot.frame, h);
  });
  ex_.ghosts(st.exchange_op, list);
  if (!st.upload || l.bytes == 0) return;
  each([&](auto&, auto& h, const dist::FrameSlot& slot) {
    using T = typename std::remove_reference_t<decltype(h)>::value_type;
    dist::pack_frame(h, slot.frame, reinterpret_cast<T*>(host + slot.offset));
  });
  ERG_CUDA_CHECK(cudaMemcpyAsync(dev, host, l.bytes, cudaMemcpyHostToDevice, cs));
  each([&](auto& d, auto&, const dist::FrameSlot& slot) {
    using T = std::remove_reference_t<decltype(*d.get())>;
    const Launch k = flat(slot.frame.size());
    ERG_LAUNCH_ON(cs, unpack_frame_kernel<T>, k.grid, k.block,
                  reinterpret_cast<const T*>(dev + slot.offset), g_, slot.frame, st.ghosts_only,
                  d.get());
  });
  stream_waits(kCompute, cs, staged_);  // the next stage's kernels wait on the device
  ex_.count_host_staged(dist::staged_bytes({false, false, GhostOp::kFill, true, false}, l));
}

// Several tiles, CUDA-aware MPI: the exchange packs and unpacks the device
// fields themselves through the device packer (on copy_) and hands MPI
// device buffers; nothing is staged. As on the staged path, the packing
// waits for the kernels that wrote the fields, and the kernels after the
// exchange wait for its unpacking on the device; between a kBeginFill and
// its kFinishFill the stages' kernels run alongside.
void CudaBackend::ghosts_direct(GhostOp op, std::span<const FieldGhosts> fields) {
  std::vector<dist::Ghosts> list;
  for (const FieldGhosts& f : fields) list.push_back(host_ghosts(f));
  if (op != GhostOp::kFinishFill) stream_waits(copy_.get(), kCompute, produced_);
  ex_.ghosts(op, list);
  if (op != GhostOp::kBeginFill) stream_waits(kCompute, copy_.get(), staged_);
}

void CudaBackend::ghosts(GhostOp op, std::span<const FieldGhosts> fields) {
  switch (path_) {
    case dist::HaloPath::kDeviceDirect:
      ghosts_direct(op, fields);
      return;
    case dist::HaloPath::kHostStaged:
      ghosts_staged(op, fields);
      return;
    default:
      ghosts_periodic(op, fields);
      return;
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

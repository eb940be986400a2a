// SPDX-License-Identifier: Apache-2.0
#include "dist/mpi_exchange.h"

#include <algorithm>
#include <cstdlib>
#include <stdexcept>
#include <string>

// Open MPI's extensions: MPIX_CUDA_AWARE_SUPPORT and MPIX_Query_cuda_support
// (its documented two-step check for CUDA-aware builds).
#if __has_include(<mpi-ext.h>)
#include <mpi-ext.h>
#endif

namespace erg::dist {

namespace {
void check(int rc, const char* what) {
  if (rc == MPI_SUCCESS) return;
  char text[MPI_MAX_ERROR_STRING];
  int n = 0;
  MPI_Error_string(rc, text, &n);
  throw std::runtime_error(std::string(what) + ": " + std::string(text, static_cast<size_t>(n)));
}
}  // namespace

MpiCudaSupport mpi_cuda_support() {
  MpiCudaSupport s;
#if defined(MPIX_CUDA_AWARE_SUPPORT) && MPIX_CUDA_AWARE_SUPPORT
  s.built = true;
#endif
#if defined(OMPI_HAVE_MPI_EXT_CUDA) && OMPI_HAVE_MPI_EXT_CUDA
  // Asked even when the headers say no, so that the log tells both.
  s.runtime = MPIX_Query_cuda_support() == 1;
#endif
  const char* v = std::getenv("ERG_CUDA_AWARE_MPI");
  s.allowed = !(v && std::string(v) == "0");
  return s;
}

void MpiExchange::ghosts(GhostOp op, std::span<const Ghosts> fields) {
  switch (op) {
    case GhostOp::kFill:
      halo_.fill(fields);
      break;
    case GhostOp::kBeginFill:
      halo_.begin_fill(fields);
      break;
    case GhostOp::kFinishFill:
      halo_.finish_fill(fields);
      break;
    case GhostOp::kSum:
      halo_.sum(fields);
      break;
  }
}

MpiExchange::MpiExchange(MPI_Comm cart, const Decomposition& d, const TileGeom& g, int cx, int cy)
    : cart_(cart), d_(d), cx_(cx), cy_(cy), halo_(cart, g), cuda_(mpi_cuda_support()) {
  check(MPI_Comm_size(cart_, &size_), "MPI_Comm_size");
  check(MPI_Comm_rank(cart_, &rank_), "MPI_Comm_rank");
  for (int i = 0; i < d_.px; ++i) {
    col0_.push_back(d_.x0(i) / cx_);
    ncol_.push_back(d_.nx(i) / cx_);
  }
  for (int j = 0; j < d_.py; ++j) {
    row0_.push_back(d_.y0(j) / cy_);
    nrow_.push_back(d_.ny(j) / cy_);
  }
  rank_of_.assign(static_cast<size_t>(d_.px) * d_.py, 0);
  ti_of_.resize(static_cast<size_t>(size_));
  tj_of_.resize(static_cast<size_t>(size_));
  for (int r = 0; r < size_; ++r) {
    int coords[2];
    check(MPI_Cart_coords(cart_, r, 2, coords), "MPI_Cart_coords");
    ti_of_[r] = coords[0];
    tj_of_[r] = coords[1];
    rank_of_[static_cast<size_t>(coords[1]) * d_.px + coords[0]] = r;
  }
}

namespace {
// The global coarse cells of [first, first + n) that a window of `width`
// cells starting at `origin` (unwrapped) covers on a torus of g cells,
// ascending and each once.
std::vector<int> covered(int origin, int width, int first, int n, int g) {
  std::vector<char> hit(static_cast<size_t>(n), 0);
  const int span = width < g ? width : g;  // a wider window sees every cell
  for (int t = 0; t < span; ++t) {
    const int x = ((origin + t) % g + g) % g;
    if (x >= first && x < first + n) hit[static_cast<size_t>(x - first)] = 1;
  }
  std::vector<int> out;
  for (int k = 0; k < n; ++k)
    if (hit[static_cast<size_t>(k)]) out.push_back(first + k);
  return out;
}
// Position of global cell x in an ascending list.
int position(const std::vector<int>& list, int x) {
  int lo = 0, hi = static_cast<int>(list.size());
  while (lo < hi) {
    const int mid = (lo + hi) / 2;
    if (list[static_cast<size_t>(mid)] < x)
      lo = mid + 1;
    else
      hi = mid;
  }
  return lo;
}
constexpr int kCoarseTag = 0x4552 + 16;  // apart from HaloExchanger's tags
}  // namespace

// Every rank knows the decomposition, so it works out alone both what it
// needs from whom and what whom needs from it: no negotiation.
void MpiExchange::make_plan(int hx, int hy) {
  Plan p;
  p.hx = hx;
  p.hy = hy;
  const int gcx = d_.gnx / cx_, gcy = d_.gny / cy_;
  const int me_i = ti_of_[rank_], me_j = tj_of_[rank_];
  const auto window_of = [&](int ti, int tj, int& ox, int& wx, int& oy, int& wy) {
    ox = col0_[ti] - hx;
    wx = ncol_[ti] + 2 * hx;
    oy = row0_[tj] - hy;
    wy = nrow_[tj] + 2 * hy;
  };
  int ox, wx, oy, wy;
  window_of(me_i, me_j, ox, wx, oy, wy);
  // Needed from every tile, in rank order (the order changes no value).
  std::vector<std::vector<int>> cols_of(static_cast<size_t>(d_.px)),
      rows_of(static_cast<size_t>(d_.py));
  for (int i = 0; i < d_.px; ++i) cols_of[i] = covered(ox, wx, col0_[i], ncol_[i], gcx);
  for (int j = 0; j < d_.py; ++j) rows_of[j] = covered(oy, wy, row0_[j], nrow_[j], gcy);
  p.from_of_tile.assign(static_cast<size_t>(d_.px) * d_.py, -1);
  for (int r = 0; r < size_; ++r) {
    const int i = ti_of_[r], j = tj_of_[r];
    if (cols_of[i].empty() || rows_of[j].empty()) continue;
    p.from_of_tile[static_cast<size_t>(j) * d_.px + i] = static_cast<int>(p.from.size());
    p.from.push_back({r, cols_of[i], rows_of[j], {}});
  }
  // Where every window column and row comes from.
  for (int t = 0; t < wx; ++t) {
    const int x = ((ox + t) % gcx + gcx) % gcx;
    const int i = std::min(x / (d_.chunk_x / cx_), d_.px - 1);
    p.col_tile.push_back(i);
    p.col_pos.push_back(position(cols_of[i], x));
  }
  for (int t = 0; t < wy; ++t) {
    const int y = ((oy + t) % gcy + gcy) % gcy;
    const int j = std::min(y / (d_.chunk_y / cy_), d_.py - 1);
    p.row_tile.push_back(j);
    p.row_pos.push_back(position(rows_of[j], y));
  }
  // What every rank's window needs of this tile.
  for (int r = 0; r < size_; ++r) {
    int rox, rwx, roy, rwy;
    window_of(ti_of_[r], tj_of_[r], rox, rwx, roy, rwy);
    Peer q{r,
           covered(rox, rwx, col0_[me_i], ncol_[me_i], gcx),
           covered(roy, rwy, row0_[me_j], nrow_[me_j], gcy),
           {}};
    if (!q.cols.empty() && !q.rows.empty()) p.to.push_back(std::move(q));
  }
  plan_ = std::move(p);
}

// 128-bit totals as two int64 halves (MPI has no 128-bit integer): the low
// 32 bits and the rest, each summed exactly, then recombined. Exact for any
// number of ranks below 2^31.
void MpiExchange::sum_exact(std::vector<total_t>& v) {
  const size_t n = v.size();
  std::vector<long long> parts(2 * n), sums(2 * n);
  for (size_t i = 0; i < n; ++i) {
    parts[2 * i] = static_cast<long long>(static_cast<unsigned long long>(v[i]) & 0xffffffffull);
    parts[2 * i + 1] = static_cast<long long>(v[i] >> 32);
  }
  check(MPI_Allreduce(parts.data(), sums.data(), static_cast<int>(2 * n), MPI_LONG_LONG, MPI_SUM,
                      cart_),
        "MPI_Allreduce (exact sums)");
  for (size_t i = 0; i < n; ++i)
    v[i] = static_cast<total_t>(sums[2 * i + 1]) * (static_cast<total_t>(1) << 32) + sums[2 * i];
}

bool MpiExchange::any(bool local) {
  int in = local ? 1 : 0, out = 0;
  check(MPI_Allreduce(&in, &out, 1, MPI_INT, MPI_LOR, cart_), "MPI_Allreduce (any)");
  return out != 0;
}

void MpiExchange::coarse_window(const std::vector<double>& mine, int tcnx, int tcny, int hx, int hy,
                                std::vector<double>& window) {
  const int me_i = ti_of_[rank_], me_j = tj_of_[rank_];
  if (tcnx != ncol_[me_i] || tcny != nrow_[me_j] ||
      mine.size() != static_cast<size_t>(tcnx) * tcny || hx < 0 || hy < 0)
    throw std::logic_error(
        "coarse_window: this tile's coarse cells do not match the decomposition");
  if (plan_.hx != hx || plan_.hy != hy) make_plan(hx, hy);
  Plan& p = plan_;
  const int x0 = col0_[me_i], y0 = row0_[me_j];
  std::vector<MPI_Request> requests;
  requests.reserve(p.from.size() + p.to.size());
  for (Peer& f : p.from) {
    f.buf.resize(f.cols.size() * f.rows.size());
    if (f.rank == rank_) continue;
    requests.emplace_back();
    check(MPI_Irecv(f.buf.data(), static_cast<int>(f.buf.size()), MPI_DOUBLE, f.rank, kCoarseTag,
                    cart_, &requests.back()),
          "MPI_Irecv (coarse window)");
  }
  for (Peer& t : p.to) {
    t.buf.clear();
    for (const int y : t.rows)
      for (const int x : t.cols)
        t.buf.push_back(mine[static_cast<size_t>(y - y0) * tcnx + (x - x0)]);
    if (t.rank == rank_) {
      p.from[static_cast<size_t>(p.from_of_tile[static_cast<size_t>(me_j) * d_.px + me_i])].buf =
          t.buf;
      continue;
    }
    requests.emplace_back();
    check(MPI_Isend(t.buf.data(), static_cast<int>(t.buf.size()), MPI_DOUBLE, t.rank, kCoarseTag,
                    cart_, &requests.back()),
          "MPI_Isend (coarse window)");
    coarse_messages_ += 1;
    coarse_bytes_ += static_cast<long long>(t.buf.size() * sizeof(double));
  }
  if (!requests.empty())
    check(MPI_Waitall(static_cast<int>(requests.size()), requests.data(), MPI_STATUSES_IGNORE),
          "MPI_Waitall (coarse window)");
  const int wx = tcnx + 2 * hx, wy = tcny + 2 * hy;
  window.resize(static_cast<size_t>(wx) * wy);
  for (int j = 0; j < wy; ++j) {
    const int tj = p.row_tile[static_cast<size_t>(j)], q = p.row_pos[static_cast<size_t>(j)];
    for (int i = 0; i < wx; ++i) {
      const int ti = p.col_tile[static_cast<size_t>(i)];
      const Peer& f =
          p.from[static_cast<size_t>(p.from_of_tile[static_cast<size_t>(tj) * d_.px + ti])];
      window[static_cast<size_t>(j) * wx + i] =
          f.buf[static_cast<size_t>(q) * f.cols.size() + static_cast<size_t>(p.col_pos[i])];
    }
  }
}

}  // namespace erg::dist

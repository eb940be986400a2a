// SPDX-License-Identifier: Apache-2.0
#include "dist/halo.h"

#include <algorithm>
#include <climits>
#include <cstddef>
#include <cstring>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <variant>

namespace erg::dist {

namespace {

// Directions, indexing send_/recv_ and the neighbour ranks.
enum Dir : int { kLeft = 0, kRight = 1, kDown = 2, kUp = 3 };
constexpr int kFlip[4] = {kRight, kLeft, kUp, kDown};
const char* const kDirName[4] = {"left", "right", "down", "up"};
// A message sent towards direction d carries tag kTag + d; the receiver,
// which sees the sender on the opposite side, receives from kFlip[d'] with
// the tag of the direction the sender sent in. The size exchange of the
// constructor uses its own tags.
constexpr int kTag = 0x4552;
constexpr int kSizeTag = kTag + 8;

void check(int rc, const char* call) {
  if (rc == MPI_SUCCESS) return;
  char text[MPI_MAX_ERROR_STRING];
  int len = 0;
  if (MPI_Error_string(rc, text, &len) != MPI_SUCCESS) len = 0;
  throw std::runtime_error(std::string("halo exchange: ") + call + " failed: " +
                           (len > 0 ? std::string(text, static_cast<std::size_t>(len))
                                    : "error code " + std::to_string(rc)));
}

template <class T>
std::size_t bytes_of(const Rect& r) {
  return static_cast<std::size_t>(r.x1 - r.x0) * static_cast<std::size_t>(r.y1 - r.y0) * sizeof(T);
}

// Calls f(field, width) for every field of the list with a width > 0.
template <class F>
void each(std::span<const Ghosts> parts, F&& f) {
  for (const Ghosts& g : parts)
    if (g.width > 0) std::visit([&](auto* field) { f(*field, g.width); }, g.field);
}

// The bytes of every field's rectangle rect(w), one after the other.
template <class RectOf>
std::size_t bytes_of_all(std::span<const Ghosts> parts, RectOf rect) {
  std::size_t n = 0;
  each(parts, [&](auto& f, int w) {
    n += bytes_of<typename std::decay_t<decltype(f)>::value_type>(rect(w));
  });
  return n;
}

template <class RectOf>
void pack(std::span<const Ghosts> parts, RectOf rect, std::vector<char>& buf) {
  buf.resize(bytes_of_all(parts, rect));
  char* p = buf.data();
  each(parts, [&](auto& f, int w) {
    using T = typename std::decay_t<decltype(f)>::value_type;
    const Rect r = rect(w);
    const std::size_t row = static_cast<std::size_t>(r.x1 - r.x0) * sizeof(T);
    for (int y = r.y0; y < r.y1; ++y, p += row) std::memcpy(p, &f(r.x0, y), row);
  });
}

template <class RectOf>
void unpack_copy(std::span<const Ghosts> parts, RectOf rect, const std::vector<char>& buf) {
  const char* p = buf.data();
  each(parts, [&](auto& f, int w) {
    using T = typename std::decay_t<decltype(f)>::value_type;
    const Rect r = rect(w);
    const std::size_t row = static_cast<std::size_t>(r.x1 - r.x0) * sizeof(T);
    for (int y = r.y0; y < r.y1; ++y, p += row) std::memcpy(&f(r.x0, y), p, row);
  });
}

template <class RectOf>
void unpack_add(std::span<const Ghosts> parts, RectOf rect, const std::vector<char>& buf) {
  const char* p = buf.data();
  each(parts, [&](auto& f, int w) {
    using T = typename std::decay_t<decltype(f)>::value_type;
    const Rect r = rect(w);
    const int n = r.x1 - r.x0;
    for (int y = r.y0; y < r.y1; ++y) {
      T* dst = &f(r.x0, y);
      for (int x = 0; x < n; ++x, p += sizeof(T)) {
        T v;
        std::memcpy(&v, p, sizeof(T));
        dst[x] += v;
      }
    }
  });
}

template <class RectOf>
void zero(std::span<const Ghosts> parts, RectOf rect) {
  each(parts, [&](auto& f, int w) {
    using T = typename std::decay_t<decltype(f)>::value_type;
    const Rect r = rect(w);
    for (int y = r.y0; y < r.y1; ++y) std::fill(&f(r.x0, y), &f(r.x0, y) + (r.x1 - r.x0), T{});
  });
}

int count_of(const std::vector<char>& buf) {
  if (buf.size() > static_cast<std::size_t>(INT_MAX))
    throw std::runtime_error("halo exchange: a message of " + std::to_string(buf.size()) +
                             " bytes is larger than MPI's int count");
  return static_cast<int>(buf.size());
}

// Posts the exchange along one axis (directions a and b = kFlip[a]):
// receives first, then sends. recv[d] must already have its final size.
void post(MPI_Comm comm, const int (&nb)[4], int a, int b, std::vector<char> (&send)[4],
          std::vector<char> (&recv)[4], MPI_Request* requests, int& pending,
          HaloExchanger::Stats& stats) {
  for (const int d : {a, b}) {
    check(MPI_Irecv(recv[d].data(), count_of(recv[d]), MPI_BYTE, nb[d], kTag + kFlip[d], comm,
                    &requests[pending]),
          "MPI_Irecv");
    ++pending;
  }
  for (const int d : {a, b}) {
    check(MPI_Isend(send[d].data(), count_of(send[d]), MPI_BYTE, nb[d], kTag + d, comm,
                    &requests[pending]),
          "MPI_Isend");
    ++pending;
    stats.messages += 1;
    stats.bytes += static_cast<long long>(send[d].size());
  }
}

void wait_all(MPI_Request* requests, int& pending) {
  const int n = pending;
  pending = 0;
  if (n > 0) check(MPI_Waitall(n, requests, MPI_STATUSES_IGNORE), "MPI_Waitall");
}

}  // namespace

HaloExchanger::HaloExchanger(MPI_Comm cart, const TileGeom& g) : cart_(cart), g_(g) {
  // Checks that every rank makes alike (same communicator) come first.
  int topo = MPI_UNDEFINED;
  check(MPI_Topo_test(cart, &topo), "MPI_Topo_test");
  if (topo != MPI_CART)
    throw std::invalid_argument("halo exchange: the communicator has no Cartesian topology");
  int ndims = 0;
  check(MPI_Cartdim_get(cart, &ndims), "MPI_Cartdim_get");
  if (ndims != 2)
    throw std::invalid_argument("halo exchange: the Cartesian communicator has " +
                                std::to_string(ndims) + " dimensions, not 2");
  int dims[2], periods[2], coords[2];
  check(MPI_Cart_get(cart, 2, dims, periods, coords), "MPI_Cart_get");
  if (!periods[0] || !periods[1])
    throw std::invalid_argument("halo exchange: the Cartesian communicator is not periodic");
  check(MPI_Cart_shift(cart, 0, 1, &left_, &right_), "MPI_Cart_shift");
  check(MPI_Cart_shift(cart, 1, 1, &down_, &up_), "MPI_Cart_shift");

  // Every neighbour's tile size: send ours towards d, receive from the
  // opposite side what that neighbour sent towards d (to us).
  const int nb[4] = {left_, right_, down_, up_};
  int mine[2] = {g.nx, g.ny};
  int theirs[4][2] = {};
  for (int d = 0; d < 4; ++d)
    check(MPI_Sendrecv(mine, 2, MPI_INT, nb[d], kSizeTag + d, theirs[kFlip[d]], 2, MPI_INT,
                       nb[kFlip[d]], kSizeTag + d, cart, MPI_STATUS_IGNORE),
          "MPI_Sendrecv");
  nx_left_ = theirs[kLeft][0];
  nx_right_ = theirs[kRight][0];
  ny_down_ = theirs[kDown][1];
  ny_up_ = theirs[kUp][1];

  std::string problem;
  if (g.nx <= 0 || g.ny <= 0 || g.halo < 0)
    problem = "tile of " + std::to_string(g.nx) + " x " + std::to_string(g.ny) +
              " cells with halo " + std::to_string(g.halo);
  else if (g.pitch < g.nx + 2 * g.halo)
    problem = "pitch " + std::to_string(g.pitch) + " is shorter than a padded row of " +
              std::to_string(g.nx + 2 * g.halo);
  else if (theirs[kLeft][1] != g.ny || theirs[kRight][1] != g.ny)
    problem = "the left/right neighbours' tiles are " + std::to_string(theirs[kLeft][1]) + " and " +
              std::to_string(theirs[kRight][1]) + " rows high, this one " + std::to_string(g.ny);
  else if (theirs[kDown][0] != g.nx || theirs[kUp][0] != g.nx)
    problem = "the down/up neighbours' tiles are " + std::to_string(theirs[kDown][0]) + " and " +
              std::to_string(theirs[kUp][0]) + " columns wide, this one " + std::to_string(g.nx);

  // Agree on validity and on the widest exchange any rank can serve, so
  // every rank throws alike.
  int local[4] = {problem.empty() ? 1 : 0, g.halo, g.nx, g.ny};
  int global[4] = {};
  check(MPI_Allreduce(local, global, 4, MPI_INT, MPI_MIN, cart), "MPI_Allreduce");
  if (!problem.empty())
    throw std::invalid_argument("halo exchange: inconsistent tile geometry: " + problem);
  if (!global[0])
    throw std::invalid_argument("halo exchange: another rank's tile geometry is inconsistent");
  max_width_ = std::min({global[1], global[2], global[3]});
}

namespace {

// The checks of every exchange: the field is this tile's, and w is one that
// every rank can serve (the same verdict on every rank, given the same w).
template <class T>
void check_call(const Field<T>& f, const TileGeom& g, int w, int max_width, int nx_left,
                int nx_right, int ny_down, int ny_up, const char* what) {
  const TileGeom& fg = f.geom();
  if (fg.nx != g.nx || fg.ny != g.ny || fg.halo != g.halo || fg.pitch != g.pitch)
    throw std::invalid_argument(std::string("halo exchange ") + what +
                                ": the field's geometry is not this tile's");
  if (w >= 0 && w <= max_width) return;
  std::string why;
  if (w < 0)
    why = "it is negative";
  else if (w > g.halo)
    why = "the tiles have " + std::to_string(g.halo) + " ghost cells";
  else if (w > std::min({g.nx, g.ny, nx_left, nx_right, ny_down, ny_up}))
    why = "this tile (" + std::to_string(g.nx) + " x " + std::to_string(g.ny) +
          ") or a neighbour (left/right " + std::to_string(nx_left) + "/" +
          std::to_string(nx_right) + " columns, down/up " + std::to_string(ny_down) + "/" +
          std::to_string(ny_up) + " rows) is narrower";
  else
    why = "another rank's ghost width or tile is smaller";
  throw std::invalid_argument(std::string("halo exchange ") + what + ": width " +
                              std::to_string(w) + " is out of range 0.." +
                              std::to_string(max_width) + ": " + why);
}

bool any_width(std::span<const Ghosts> parts) {
  for (const Ghosts& g : parts)
    if (g.width > 0) return true;
  return false;
}

}  // namespace

// The ghost and edge rectangles of width w (local cells): the x phase runs
// on owned rows, the y phase on the full padded width (carrying corners).
struct HaloExchanger::Rects {
  int nx, ny;
  Rect left_edge(int w) const { return {0, w, 0, ny}; }
  Rect right_edge(int w) const { return {nx - w, nx, 0, ny}; }
  Rect left_ghost(int w) const { return {-w, 0, 0, ny}; }
  Rect right_ghost(int w) const { return {nx, nx + w, 0, ny}; }
  Rect down_edge(int w) const { return {-w, nx + w, 0, w}; }
  Rect up_edge(int w) const { return {-w, nx + w, ny - w, ny}; }
  Rect down_ghost(int w) const { return {-w, nx + w, -w, 0}; }
  Rect up_ghost(int w) const { return {-w, nx + w, ny, ny + w}; }
};
void HaloExchanger::check_all(std::span<const Ghosts> parts, const char* what) const {
  for (const Ghosts& g : parts)
    std::visit(
        [&](auto* f) {
          check_call(*f, g_, g.width, max_width_, nx_left_, nx_right_, ny_down_, ny_up_, what);
        },
        g.field);
}

// One phase along the axis of directions a and b = kFlip[a]: every field's
// rectangle send_a (send_b) goes towards a (b), in one message each; what
// arrives from a (b) fills rectangles of the shape recv_a (recv_b).
void HaloExchanger::start_phase(std::span<const Ghosts> parts, int a, int b, RectOf send_a,
                                RectOf send_b, RectOf recv_a, RectOf recv_b) {
  const Rects R{g_.nx, g_.ny};
  const auto rect = [&R](RectOf r) { return [&R, r](int w) { return (R.*r)(w); }; };
  pack(parts, rect(send_a), send_[a]);
  pack(parts, rect(send_b), send_[b]);
  recv_[a].resize(bytes_of_all(parts, rect(recv_a)));
  recv_[b].resize(bytes_of_all(parts, rect(recv_b)));
  const int nb[4] = {left_, right_, down_, up_};
  post(cart_, nb, a, b, send_, recv_, requests_, pending_, stats_);
}

// Waits for the phase, then copies (or adds) what came from a and b into the
// rectangles into_a and into_b.
void HaloExchanger::finish_phase(std::span<const Ghosts> parts, int a, int b, RectOf into_a,
                                 RectOf into_b, bool add) {
  wait_all(requests_, pending_);
  const Rects R{g_.nx, g_.ny};
  for (const auto& [d, r] : {std::pair{a, into_a}, std::pair{b, into_b}}) {
    const auto rect = [&R, r = r](int w) { return (R.*r)(w); };
    if (add)
      unpack_add(parts, rect, recv_[d]);
    else
      unpack_copy(parts, rect, recv_[d]);
  }
}

void HaloExchanger::begin_fill(std::span<const Ghosts> parts) {
  if (pending_ != 0)
    throw std::logic_error("halo exchange begin_fill: an exchange is already in flight");
  check_all(parts, "begin_fill");
  if (!any_width(parts)) return;
  // x phase, owned rows: our first/last w columns go left/right.
  start_phase(parts, kLeft, kRight, &Rects::left_edge, &Rects::right_edge, &Rects::left_ghost,
              &Rects::right_ghost);
}

void HaloExchanger::finish_fill(std::span<const Ghosts> parts) {
  check_all(parts, "finish_fill");
  if (pending_ == 0) {
    if (!any_width(parts)) return;  // begin_fill with width 0 posted nothing
    throw std::logic_error("halo exchange finish_fill: no begin_fill is in flight");
  }
  const Rects R{g_.nx, g_.ny};
  if (recv_[kLeft].size() != bytes_of_all(parts, [&R](int w) { return R.left_ghost(w); }) ||
      recv_[kRight].size() != bytes_of_all(parts, [&R](int w) { return R.right_ghost(w); }))
    throw std::logic_error(
        "halo exchange finish_fill: widths or types differ from the matching begin_fill");
  finish_phase(parts, kLeft, kRight, &Rects::left_ghost, &Rects::right_ghost, false);
  // y phase, full padded width (carries the corners): our first/last w rows
  // go down/up.
  start_phase(parts, kDown, kUp, &Rects::down_edge, &Rects::up_edge, &Rects::down_ghost,
              &Rects::up_ghost);
  finish_phase(parts, kDown, kUp, &Rects::down_ghost, &Rects::up_ghost, false);
}

void HaloExchanger::fill(std::span<const Ghosts> parts) {
  begin_fill(parts);
  finish_fill(parts);
}

void HaloExchanger::sum(std::span<const Ghosts> parts) {
  if (pending_ != 0) throw std::logic_error("halo exchange sum: an exchange is already in flight");
  check_all(parts, "sum");
  if (!any_width(parts)) return;
  // y phase, full padded width: ghost rows go to their owners below/above,
  // which add them into their top/bottom w rows (ghost columns included, so
  // corner contributions travel on in the x phase). What arrives from below
  // is the down neighbour's up ghosts.
  start_phase(parts, kDown, kUp, &Rects::down_ghost, &Rects::up_ghost, &Rects::up_ghost,
              &Rects::down_ghost);
  finish_phase(parts, kDown, kUp, &Rects::down_edge, &Rects::up_edge, true);
  // x phase, owned rows: ghost columns go to their owners left/right.
  start_phase(parts, kLeft, kRight, &Rects::left_ghost, &Rects::right_ghost, &Rects::right_ghost,
              &Rects::left_ghost);
  finish_phase(parts, kLeft, kRight, &Rects::left_edge, &Rects::right_edge, true);
  const Rects R{g_.nx, g_.ny};
  for (const RectOf r :
       {&Rects::down_ghost, &Rects::up_ghost, &Rects::left_ghost, &Rects::right_ghost})
    zero(parts, [&R, r](int w) { return (R.*r)(w); });
}

}  // namespace erg::dist

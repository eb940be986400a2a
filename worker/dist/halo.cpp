// SPDX-License-Identifier: Apache-2.0
#include "dist/halo.h"

#include <algorithm>
#include <climits>
#include <cstddef>
#include <cstring>
#include <stdexcept>
#include <string>
#include <tuple>
#include <type_traits>
#include <utility>
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
std::size_t bytes_of_all(std::span<const Ghosts> parts, const RectOf& rect) {
  std::size_t n = 0;
  each(parts, [&](auto& f, int w) {
    n += bytes_of<typename std::decay_t<decltype(f)>::value_type>(rect(w));
  });
  return n;
}

// The packer of host fields: row copies in host memory.
class HostPacker final : public HostBufferPacker {
 public:
  void pack(std::span<const Ghosts> parts, const RectOf& rect, char* p) override {
    each(parts, [&](auto& f, int w) {
      using T = typename std::decay_t<decltype(f)>::value_type;
      const Rect r = rect(w);
      const std::size_t row = static_cast<std::size_t>(r.x1 - r.x0) * sizeof(T);
      for (int y = r.y0; y < r.y1; ++y, p += row) std::memcpy(p, &f(r.x0, y), row);
    });
  }
  void unpack(std::span<const Ghosts> parts, const RectOf& rect, const char* p, bool add) override {
    each(parts, [&](auto& f, int w) {
      using T = typename std::decay_t<decltype(f)>::value_type;
      const Rect r = rect(w);
      const int n = r.x1 - r.x0;
      const std::size_t row = static_cast<std::size_t>(n) * sizeof(T);
      for (int y = r.y0; y < r.y1; ++y) {
        T* dst = &f(r.x0, y);
        if (!add) {
          copy_changed(dst, p, row);  // ghosts of a zero layer stay unwritten
          p += row;
          continue;
        }
        for (int x = 0; x < n; ++x, p += sizeof(T)) {
          T v;
          std::memcpy(&v, p, sizeof(T));
          dst[x] += v;
        }
      }
    });
  }
  void zero(std::span<const Ghosts> parts, const RectOf& rect) override {
    each(parts, [&](auto& f, int w) {
      using T = typename std::decay_t<decltype(f)>::value_type;
      const Rect r = rect(w);
      for (int y = r.y0; y < r.y1; ++y) std::fill(&f(r.x0, y), &f(r.x0, y) + (r.x1 - r.x0), T{});
    });
  }
};

int count_of(std::size_t bytes) {
  if (bytes > static_cast<std::size_t>(INT_MAX))
    throw std::runtime_error("halo exchange: a message of " + std::to_string(bytes) +
                             " bytes is larger than MPI's int count");
  return static_cast<int>(bytes);
}

// Posts the exchange along one axis (directions a and b = kFlip[a]):
// receives first, then sends (buffers and their sizes per direction).
void post(MPI_Comm comm, const int (&nb)[4], int a, int b, char* const (&send)[4],
          const std::size_t (&send_bytes)[4], char* const (&recv)[4],
          const std::size_t (&recv_bytes)[4], MPI_Request* requests, int& pending,
          HaloExchanger::Stats& stats) {
  for (const int d : {a, b}) {
    check(MPI_Irecv(recv[d], count_of(recv_bytes[d]), MPI_BYTE, nb[d], kTag + kFlip[d], comm,
                    &requests[pending]),
          "MPI_Irecv");
    ++pending;
  }
  for (const int d : {a, b}) {
    check(MPI_Isend(send[d], count_of(send_bytes[d]), MPI_BYTE, nb[d], kTag + d, comm,
                    &requests[pending]),
          "MPI_Isend");
    ++pending;
    stats.messages += 1;
    stats.bytes += static_cast<long long>(send_bytes[d]);
  }
}

void wait_all(MPI_Request* requests, int& pending) {
  const int n = pending;
  pending = 0;
  if (n > 0) check(MPI_Waitall(n, requests, MPI_STATUSES_IGNORE), "MPI_Waitall");
}

}  // namespace

HaloExchanger::HaloExchanger(MPI_Comm cart, const TileGeom& g)
    : cart_(cart),
      g_(g),
      host_packer_(std::make_unique<HostPacker>()),
      packer_(host_packer_.get()) {
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

void HaloExchanger::set_packer(HaloPacker* p) {
  if (pending_ != 0) throw std::logic_error("halo exchange set_packer: an exchange is in flight");
  packer_ = p ? p : host_packer_.get();
}

std::size_t HaloExchanger::bytes_of_all(std::span<const Ghosts> parts, Side side) const {
  return dist::bytes_of_all(parts, RectOf{{g_.nx, g_.ny}, side});
}

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
void HaloExchanger::start_phase(std::span<const Ghosts> parts, int a, int b, Side send_a,
                                Side send_b, Side recv_a, Side recv_b) {
  const HaloRects R{g_.nx, g_.ny};
  for (const auto& [d, s, r] : {std::tuple{a, send_a, recv_a}, std::tuple{b, send_b, recv_b}}) {
    send_bytes_[d] = bytes_of_all(parts, s);
    send_[d] = packer_->buffer(d, send_bytes_[d]);
    packer_->pack(parts, RectOf{R, s}, send_[d]);
    recv_bytes_[d] = bytes_of_all(parts, r);
    recv_[d] = packer_->buffer(4 + d, recv_bytes_[d]);
  }
  packer_->ready();
  const int nb[4] = {left_, right_, down_, up_};
  post(cart_, nb, a, b, send_, send_bytes_, recv_, recv_bytes_, requests_, pending_, stats_);
}

// Waits for the phase, then copies (or adds) what came from a and b into the
// rectangles into_a and into_b.
void HaloExchanger::finish_phase(std::span<const Ghosts> parts, int a, int b, Side into_a,
                                 Side into_b, bool add) {
  wait_all(requests_, pending_);
  const HaloRects R{g_.nx, g_.ny};
  for (const auto& [d, r] : {std::pair{a, into_a}, std::pair{b, into_b}})
    packer_->unpack(parts, RectOf{R, r}, recv_[d], add);
}

void HaloExchanger::begin_fill(std::span<const Ghosts> parts) {
  if (pending_ != 0)
    throw std::logic_error("halo exchange begin_fill: an exchange is already in flight");
  check_all(parts, "begin_fill");
  if (!any_width(parts)) return;
  // x phase, owned rows: our first/last w columns go left/right.
  start_phase(parts, kLeft, kRight, &HaloRects::left_edge, &HaloRects::right_edge,
              &HaloRects::left_ghost, &HaloRects::right_ghost);
}

void HaloExchanger::finish_fill(std::span<const Ghosts> parts) {
  check_all(parts, "finish_fill");
  if (pending_ == 0) {
    if (!any_width(parts)) return;  // begin_fill with width 0 posted nothing
    throw std::logic_error("halo exchange finish_fill: no begin_fill is in flight");
  }
  if (recv_bytes_[kLeft] != bytes_of_all(parts, &HaloRects::left_ghost) ||
      recv_bytes_[kRight] != bytes_of_all(parts, &HaloRects::right_ghost))
    throw std::logic_error(
        "halo exchange finish_fill: widths or types differ from the matching begin_fill");
  finish_phase(parts, kLeft, kRight, &HaloRects::left_ghost, &HaloRects::right_ghost, false);
  // y phase, full padded width (carries the corners): our first/last w rows
  // go down/up.
  start_phase(parts, kDown, kUp, &HaloRects::down_edge, &HaloRects::up_edge, &HaloRects::down_ghost,
              &HaloRects::up_ghost);
  finish_phase(parts, kDown, kUp, &HaloRects::down_ghost, &HaloRects::up_ghost, false);
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
  start_phase(parts, kDown, kUp, &HaloRects::down_ghost, &HaloRects::up_ghost, &HaloRects::up_ghost,
              &HaloRects::down_ghost);
  finish_phase(parts, kDown, kUp, &HaloRects::down_edge, &HaloRects::up_edge, true);
  // x phase, owned rows: ghost columns go to their owners left/right.
  start_phase(parts, kLeft, kRight, &HaloRects::left_ghost, &HaloRects::right_ghost,
              &HaloRects::right_ghost, &HaloRects::left_ghost);
  finish_phase(parts, kLeft, kRight, &HaloRects::left_edge, &HaloRects::right_edge, true);
  const HaloRects R{g_.nx, g_.ny};
  for (const Side r : {&HaloRects::down_ghost, &HaloRects::up_ghost, &HaloRects::left_ghost,
                       &HaloRects::right_ghost})
    packer_->zero(parts, RectOf{R, r});
}

}  // namespace erg::dist

// SPDX-License-Identifier: Apache-2.0
// Halo exchange between the tiles of a periodic Cartesian communicator.
//
// fill(): every ghost cell (width w) gets the value of the owned cell it
// stands for on the torus (gather). sum(): every ghost cell's value is added
// to that owned cell and the ghost is zeroed (scatter-sum, the reverse halo
// accumulation of AMReX SumBoundary / Cabana scatter(Sum)).
//
// Two phases: x (left/right neighbours, owned rows), then y (up/down
// neighbours, full padded width, which carries the corners); sum() runs them
// in the reverse order. Non-blocking Isend/Irecv with one tag per direction
// (the receive uses the flipped direction's tag), so a neighbour that is both
// left and right (2 tiles along x) or a tile that is its own neighbour (1 tile
// along x) is exchanged correctly. (Not neighbourhood collectives: Open MPI
// 4.1 swaps halos with them when a dimension has 1 or 2 ranks.)
//
// Requirements: w <= the tile's halo and w <= the size of this tile and of
// every neighbour along each axis (checked; throws std::invalid_argument).
// The check uses the smallest halo and tile side over all ranks (learnt by
// the constructor), so every rank throws alike instead of some waiting
// forever for ranks that threw.
#pragma once

#include <mpi.h>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "core/field.h"
#include "dist/ghosts.h"
#include "dist/halo_packer.h"

namespace erg::dist {

class HaloExchanger {
 public:
  // cart: 2-D periodic Cartesian communicator (dims[0] along x, dims[1]
  // along y); g: this rank's tile (its nx, ny, halo, pitch). Collective: every
  // rank learns its neighbours' tile sizes.
  HaloExchanger(MPI_Comm cart, const TileGeom& g);

  // Every field of the list with its own width, in one message per
  // neighbour and phase (4 messages per fill or sum, whatever the count).
  void fill(std::span<const Ghosts> fields);
  void sum(std::span<const Ghosts> fields);
  // Split fill for overlapping interior work with the transfer: begin_fill
  // posts the x phase; finish_fill (same list) completes it, then runs the
  // y phase. Nothing else may be exchanged between the two calls.
  void begin_fill(std::span<const Ghosts> fields);
  void finish_fill(std::span<const Ghosts> fields);

  // One field.
  template <class T>
  void fill(Field<T>& f, int w) {
    const Ghosts g{&f, w};
    fill(std::span<const Ghosts>(&g, 1));
  }
  template <class T>
  void sum(Field<T>& f, int w) {
    const Ghosts g{&f, w};
    sum(std::span<const Ghosts>(&g, 1));
  }
  template <class T>
  void begin_fill(Field<T>& f, int w) {
    const Ghosts g{&f, w};
    begin_fill(std::span<const Ghosts>(&g, 1));
  }
  template <class T>
  void finish_fill(Field<T>& f, int w) {
    const Ghosts g{&f, w};
    finish_fill(std::span<const Ghosts>(&g, 1));
  }

  // Packs through `p` (which must outlive its use) instead of the host
  // packer; nullptr returns to the host packer. Not while an exchange is in
  // flight.
  void set_packer(HaloPacker* p);

  // Messages and bytes this rank has sent since construction or reset.
  struct Stats {
    long long messages = 0;
    long long bytes = 0;
  };
  Stats stats() const { return stats_; }
  void reset_stats() { stats_ = {}; }

  int left() const { return left_; }
  int right() const { return right_; }
  int down() const { return down_; }
  int up() const { return up_; }

 private:
  void check_all(std::span<const Ghosts> fields, const char* what) const;
  using Side = Rect (HaloRects::*)(int) const;
  void start_phase(std::span<const Ghosts> fields, int a, int b, Side send_a, Side send_b,
                   Side recv_a, Side recv_b);
  void finish_phase(std::span<const Ghosts> fields, int a, int b, Side into_a, Side into_b,
                    bool add);
  std::size_t bytes_of_all(std::span<const Ghosts> fields, Side side) const;
  MPI_Comm cart_;
  TileGeom g_;
  int left_ = 0, right_ = 0, down_ = 0, up_ = 0;              // ranks
  int nx_left_ = 0, nx_right_ = 0, ny_down_ = 0, ny_up_ = 0;  // their tile sizes
  int max_width_ = 0;                        // smallest halo, nx and ny over all ranks
  std::unique_ptr<HaloPacker> host_packer_;  // host fields, host memory
  HaloPacker* packer_ = nullptr;             // the one in use
  // This exchange's messages per direction (the packer's buffers).
  char *send_[4] = {}, *recv_[4] = {};
  std::size_t send_bytes_[4] = {}, recv_bytes_[4] = {};
  MPI_Request requests_[8];
  int pending_ = 0;
  Stats stats_;
};

}  // namespace erg::dist

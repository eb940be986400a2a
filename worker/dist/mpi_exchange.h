// SPDX-License-Identifier: Apache-2.0
// The Exchange of a tile on an MPI rank: ghosts through HaloExchanger,
// exact sums through collectives; the coarse window of the wind warping
// point-to-point with the tiles that cover it.
#pragma once

#include <mpi.h>

#include "dist/decomposition.h"
#include "dist/exchange.h"
#include "dist/halo.h"

namespace erg::dist {

class MpiExchange final : public Exchange {
 public:
  // cart: the periodic Cartesian communicator of the decomposition `d`; g:
  // this rank's tile; cx, cy: fine cells per coarse wind cell (tiles are
  // aligned to them). Collective.
  MpiExchange(MPI_Comm cart, const Decomposition& d, const TileGeom& g, int cx, int cy);

  void ghosts(GhostOp op, std::span<const Ghosts> fields) override;

  void sum_exact(std::vector<total_t>& v) override;
  bool any(bool local) override;
  void coarse_window(const std::vector<double>& mine, int tcnx, int tcny, int hx, int hy,
                     std::vector<double>& window) override;

  int tiles() const override { return size_; }
  MpiCudaSupport cuda_support() const override { return cuda_; }
  void set_packer(HaloPacker* p) override { halo_.set_packer(p); }

 protected:
  Stats traffic() const override {
    const HaloExchanger::Stats s = halo_.stats();
    return {s.messages + coarse_messages_, s.bytes + coarse_bytes_, 0};
  }

 private:
  MPI_Comm cart_;
  Decomposition d_;
  int cx_, cy_;
  int size_ = 1;
  HaloExchanger halo_;
  MpiCudaSupport cuda_;  // asked once (mpi_cuda_support)
  int rank_ = 0;
  // The coarse columns of every tile column and the coarse rows of every
  // tile row: origin and size in coarse cells; the rank of every tile.
  std::vector<int> col0_, ncol_, row0_, nrow_, rank_of_;  // rank_of_[tj * px + ti]
  std::vector<int> ti_of_, tj_of_;                        // tile coordinates of every rank
  // Who sends which coarse cells for a halo (hx, hy), made on first use.
  struct Peer {
    int rank;
    std::vector<int> cols, rows;  // global coarse columns and rows, ascending
    std::vector<double> buf;
  };
  struct Plan {
    int hx = -1, hy = -1;
    std::vector<Peer> from, to;  // the tiles this window needs; the windows that need this tile
    // Window column i: tile column and index among that peer's cols (rows alike).
    std::vector<int> col_tile, col_pos, row_tile, row_pos;
    std::vector<int> from_of_tile;  // [tj * px + ti] -> index into from, or -1
  };
  void make_plan(int hx, int hy);
  Plan plan_;
  long long coarse_messages_ = 0, coarse_bytes_ = 0;
};

}  // namespace erg::dist

// SPDX-License-Identifier: Apache-2.0
// The Exchange of a tile on an MPI rank: ghosts through HaloExchanger,
// exact sums and the coarse wind grid through collectives.
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
  void gather_coarse(const std::vector<double>& mine, std::vector<double>& all) override;

  int tiles() const override { return size_; }

 protected:
  Stats traffic() const override {
    const HaloExchanger::Stats s = halo_.stats();
    return {s.messages, s.bytes, 0};
  }

 private:
  MPI_Comm cart_;
  Decomposition d_;
  int cx_, cy_;
  int size_ = 1;
  HaloExchanger halo_;
  // The coarse rectangle of every rank: origin and size in coarse cells.
  std::vector<int> cx0_, cy0_, cnx_, cny_, counts_, displs_;
};

}  // namespace erg::dist

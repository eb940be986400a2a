// SPDX-License-Identifier: Apache-2.0
// How a tile talks to the rest of the torus: its ghosts are filled from
// their owners, scatters into ghosts are summed back, and exact totals are
// summed over all tiles. One tile that is the whole domain wraps onto
// itself (PeriodicExchange); tiles on MPI ranks exchange messages
// (MpiExchange, dist/mpi_exchange.h). The backends see only this interface,
// so the step pipeline is the same on one process and on many.
#pragma once

#include <memory>
#include <span>
#include <stdexcept>
#include <vector>

#include "core/field.h"
#include "core/units.h"
#include "dist/ghosts.h"
#include "dist/halo_path.h"

namespace erg::dist {

class HaloPacker;  // dist/halo.h

class Exchange {
 public:
  virtual ~Exchange() = default;

  // The ghosts of every listed field, each as wide as listed: filled from
  // their owners, or summed into them (GhostOp), in one message per
  // neighbour and phase for all of them.
  virtual void ghosts(GhostOp op, std::span<const Ghosts> fields) = 0;

  // Exact element-wise sums over all tiles, in place.
  virtual void sum_exact(std::vector<total_t>& v) = 0;
  // Logical or over all tiles.
  virtual bool any(bool local) = 0;
  // The coarse window of the wind warping: `mine` holds this tile's coarse
  // cells (row-major [tcny][tcnx]; tiles are aligned to coarse cells);
  // `window` receives the (tcny + 2 hy) x (tcnx + 2 hx) coarse cells around
  // them on the torus, row-major, the tile's cell (0, 0) at (hx, hy). The
  // halo may be wider than any tile and than the domain (it wraps); only the
  // tiles covering it are asked, and every value is a copy, so the window is
  // the same whatever the tiling.
  virtual void coarse_window(const std::vector<double>& mine, int tcnx, int tcny, int hx, int hy,
                             std::vector<double>& window) = 0;

  // Messages and bytes sent by this tile so far (0 on one process), and the
  // bytes a device backend staged through host memory for the exchanges
  // (both directions, as it reports them with count_host_staged).
  struct Stats {
    long long messages = 0;
    long long bytes = 0;
    long long host_staged_bytes = 0;
  };
  Stats stats() const {
    Stats s = traffic();
    s.host_staged_bytes = host_staged_;
    return s;
  }
  void count_host_staged(long long bytes) { host_staged_ += bytes; }
  virtual int tiles() const { return 1; }

  // Whether the MPI library reads device memory (dist/halo_path.h; never on
  // one process, which sends nothing).
  virtual MpiCudaSupport cuda_support() const { return {}; }
  // Ghosts travel through `p` (dist/halo.h) from now on, nullptr: through
  // host memory again. Only an exchange that sends messages takes one.
  virtual void set_packer(HaloPacker*) {
    throw std::logic_error("this exchange sends no messages: it takes no packer");
  }

 protected:
  // Messages and bytes sent (host_staged_bytes is the base class's).
  virtual Stats traffic() const { return {}; }

 private:
  long long host_staged_ = 0;
};

// One tile that is the whole torus: ghosts wrap onto its own cells.
class PeriodicExchange final : public Exchange {
 public:
  void ghosts(GhostOp op, std::span<const Ghosts> fields) override;
  void sum_exact(std::vector<total_t>&) override {}
  bool any(bool local) override { return local; }
  void coarse_window(const std::vector<double>& mine, int tcnx, int tcny, int hx, int hy,
                     std::vector<double>& window) override;
};

// The periodic wrap of a whole-domain tile (halos wider than the tile wrap
// several times).
template <class T>
void fill_periodic(Field<T>& f, int width);
template <class T>
void sum_periodic(Field<T>& f, int width);

}  // namespace erg::dist

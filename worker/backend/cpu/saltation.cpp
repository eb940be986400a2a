// SPDX-License-Identifier: Apache-2.0
// Saltation on the CPU (stages/saltation.h): lift, scatter of airborne sand
// one hop downwind, reverse halo accumulation, deposition/bounce/abrasion.
#include "stages/saltation.h"

#include <algorithm>
#include <vector>

#include "backend/cpu/cpu_backend.h"
#include "backend/cpu/saltation_rows.h"
#include "core/for_each.h"
#include "core/philox.h"

namespace erg::cpu {

namespace {

// Row kernels live outside the OpenMP regions, with restrict-qualified
// outputs, so that GCC vectorises them (it does not inside the regions).
void lift_row(units_t* __restrict s, units_t* __restrict air, const float* sh, const float* v,
              const float* wx, const float* wy, const float* echo, const TileGeom& g, int y,
              std::uint64_t seed, std::uint64_t step, const saltation::Params& p) {
  const int nx = g.nx;
  if (p.stochastic) {
    for (int x = 0; x < nx; ++x) {
      const float u = u01(random4(seed, step, g.global_index(x, y), RandomStream::kLift).v[0]);
      const units_t q =
          saltation::lift_stochastic(s[x], sh[x], v[x], length(Vec2{wx[x], wy[x]}), u, p, echo[x]);
      s[x] -= q;
      air[x] += q;
    }
  } else {
    for (int x = 0; x < nx; ++x) {
      const units_t q =
          saltation::lift_expected(s[x], sh[x], v[x], length(Vec2{wx[x], wy[x]}), p, echo[x]);
      s[x] -= q;
      air[x] += q;
    }
  }
}

// Returns whether any bedrock was abraded. The reptation strength sr is
// written over the shadow sh and the deposited sand over the landed sand
// `in`, cell by cell (shared storage, core/fields.h): each cell's values are
// read before its results are written.
bool impact_row(const units_t* in, units_t* __restrict s, units_t* __restrict b,
                units_t* __restrict air, const float* sh, const float* v, const float* r,
                const float* wx, const float* wy, const float* echo, float* sr, units_t* deposited,
                const TileGeom& g, int y, std::uint64_t seed, std::uint64_t step,
                const saltation::Params& p) {
  const int nx = g.nx;
  units_t abraded = 0;
  if (p.stochastic) {
    for (int x = 0; x < nx; ++x) {
      const float u =
          in[x] > 0 ? u01(random4(seed, step, g.global_index(x, y), RandomStream::kDeposit).v[0])
                    : 0.0f;
      const saltation::Impact im = saltation::impact(in[x], s[x], sh[x], v[x], r[x],
                                                     length(Vec2{wx[x], wy[x]}), u, p, echo[x]);
      abraded |= saltation::settle(im, s[x], b[x], air[x], sr[x], deposited[x]);
    }
  } else {
    for (int x = 0; x < nx; ++x) {
      const saltation::Impact im = saltation::impact(in[x], s[x], sh[x], v[x], r[x],
                                                     length(Vec2{wx[x], wy[x]}), 0.0f, p, echo[x]);
      abraded |= saltation::settle(im, s[x], b[x], air[x], sr[x], deposited[x]);
    }
  }
  return abraded != 0;
}

}  // namespace

void CpuBackend::saltation_hop(std::int64_t step) {
  const saltation::Params p = m_.saltation;
  const std::uint64_t seed = m_.seed;
  const auto ustep = static_cast<std::uint64_t>(step);

  // (1) Lift into the airborne buffer (which holds last step's bounces).
  for_each_row(threads_, g_, [&](int y) {
    lift_row(f_.sand.row(y), f_.airborne.row(y), f_.shadow.row(y), f_.vegetation.row(y),
             f_.wind_x.row(y), f_.wind_y.row(y), echo_row(y), g_, y, seed, ustep, p);
  });

  // (2) Scatter one hop downwind into `f_.landed` (owned + ghosts). Rows are cut
  // into bands taller than twice the hop reach; even bands run in parallel,
  // then odd bands, so no two threads ever add to the same cell. The sums are
  // integers: the result is the same for any band or thread layout.
  std::fill(f_.landed.data(), f_.landed.data() + f_.landed.size(), units_t{0});
  const int reach = m_.halo_saltation();
  const int band = std::max(2 * reach + 2, 8);
  const int nbands = std::max(1, g_.ny / band);
  for (int parity = 0; parity < 2; ++parity) {
#pragma omp parallel for num_threads(threads_) schedule(dynamic, 1)
    for (int bi = parity; bi < nbands; bi += 2) {
      const int y_begin = bi * g_.ny / nbands, y_end = (bi + 1) * g_.ny / nbands;
      std::vector<long> target(static_cast<size_t>(g_.nx));
      std::vector<units_t> parts(saltation::kLandingCells * static_cast<size_t>(g_.nx));
      for (int y = y_begin; y < y_end; ++y) {
        if (any_obstacles_ || p.stochastic) {
          scatter_row(f_.airborne.row(y), f_.wind_x.row(y), f_.wind_y.row(y), g_, y, seed, ustep, p,
                      any_obstacles_, f_.height_m.data() + g_.at(0, 0),
                      f_.obstacles.data() + g_.at(0, 0), f_.landed.data());
        } else {
          // Landing points and exact splits in a vectorised pass, then the
          // adds (which may collide) in a scalar one.
          const auto split = p.slope_k > 0.0f ? split_row<true> : split_row<false>;
          split(f_.airborne.row(y), f_.wind_x.row(y), f_.wind_y.row(y), f_.height_m.row(y), g_.nx,
                y, static_cast<long>(g_.at(0, 0)), g_.pitch, p, target.data(), parts.data());
          add_splits(target.data(), parts.data(), g_.nx, g_.pitch, f_.landed.data());
        }
      }
    }
  }
}

// After the landed ghosts are summed into their owners (Simulation::step):
// sand that left the tile re-enters on the opposite side (the torus).
void CpuBackend::saltation_impact(std::int64_t step) {
  const saltation::Params p = m_.saltation;
  const std::uint64_t seed = m_.seed;
  const auto ustep = static_cast<std::uint64_t>(step);
  // (3) Deposit, bounce, abrade; record the reptation strength.
  bool abraded = false;
#pragma omp parallel for num_threads(threads_) schedule(static) reduction(|| : abraded)
  for (int y = 0; y < g_.ny; ++y)
    abraded = impact_row(f_.landed.row(y), f_.sand.row(y), f_.bedrock.row(y), f_.airborne.row(y),
                         f_.shadow.row(y), f_.vegetation.row(y), f_.resistance.row(y),
                         f_.wind_x.row(y), f_.wind_y.row(y), echo_row(y), f_.reptation.row(y),
                         f_.deposited.row(y), g_, y, seed, ustep, p) ||
              abraded;
  shadow_valid_ = false;  // the reptation strength is in its storage now
  if (abraded) bedrock_changed_ = true;
}

}  // namespace erg::cpu

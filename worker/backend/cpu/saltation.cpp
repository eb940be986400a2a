// SPDX-License-Identifier: Apache-2.0
// Saltation on the CPU (stages/saltation.h): lift, scatter of airborne sand
// one hop downwind, reverse halo accumulation, deposition/bounce/abrasion.
#include "stages/saltation.h"

#include <algorithm>
#include <vector>

#include "backend/cpu/cpu_backend.h"
#include "core/philox.h"
#include "stages/obstacles.h"

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

// Returns whether any bedrock was abraded.
bool impact_row(const units_t* in, units_t* __restrict s, units_t* __restrict b,
                units_t* __restrict air, const float* sh, const float* v, const float* r,
                const float* wx, const float* wy, const float* echo, float* __restrict sr,
                units_t* __restrict deposited, const TileGeom& g, int y, std::uint64_t seed,
                std::uint64_t step, const saltation::Params& p) {
  const int nx = g.nx;
  units_t abraded = 0;
  if (p.stochastic) {
    for (int x = 0; x < nx; ++x) {
      const float u =
          in[x] > 0 ? u01(random4(seed, step, g.global_index(x, y), RandomStream::kDeposit).v[0])
                    : 0.0f;
      const saltation::Impact im = saltation::impact(in[x], s[x], sh[x], v[x], r[x],
                                                     length(Vec2{wx[x], wy[x]}), u, p, echo[x]);
      s[x] += im.deposited + im.abraded;
      b[x] -= im.abraded;
      air[x] = im.bounced;
      sr[x] = im.reptation_m;
      deposited[x] = im.deposited;
      abraded |= im.abraded;
    }
  } else {
    for (int x = 0; x < nx; ++x) {
      const saltation::Impact im = saltation::impact(in[x], s[x], sh[x], v[x], r[x],
                                                     length(Vec2{wx[x], wy[x]}), 0.0f, p, echo[x]);
      s[x] += im.deposited + im.abraded;
      b[x] -= im.abraded;
      air[x] = im.bounced;
      sr[x] = im.reptation_m;
      deposited[x] = im.deposited;
      abraded |= im.abraded;
    }
  }
  return abraded != 0;
}

// Expected transport: where each cell's airborne sand lands (storage index
// of the lower-left receiving cell) and its exact four-way split. Empties
// the airborne buffer (everything is in flight).
void split_row(units_t* __restrict air, const float* __restrict wx, const float* __restrict wy,
               int nx, int y, long origin, long pitch, const saltation::Params p,
               long* __restrict target, units_t* __restrict parts) {
  // (Parameters by value: int64 stores could alias fields read through a
  // reference, which would block vectorisation.)
  for (int x = 0; x < nx; ++x) {
    const saltation::Landing L = saltation::landing(x, y, {wx[x], wy[x]}, p);
    units_t q[4];
    saltation::split_bilinear(air[x], L.fx, L.fy, q);
    target[x] = origin + static_cast<long>(L.y0) * pitch + L.x0;
    parts[4 * x] = q[0];
    parts[4 * x + 1] = q[1];
    parts[4 * x + 2] = q[2];
    parts[4 * x + 3] = q[3];
    air[x] = 0;
  }
}

// Stochastic transport: each cell's airborne sand lands whole in one of the
// four cells, drawn with the bilinear weights.
void scatter_row_stochastic(units_t* air, const float* wx, const float* wy, const TileGeom& g,
                            int y, std::uint64_t seed, std::uint64_t step,
                            const saltation::Params& p, Field<units_t>& landed) {
  for (int x = 0; x < g.nx; ++x) {
    const units_t a = air[x];
    if (a == 0) continue;
    air[x] = 0;
    const saltation::Landing L = saltation::landing(x, y, {wx[x], wy[x]}, p);
    const float u = u01(random4(seed, step, g.global_index(x, y), RandomStream::kLanding).v[0]);
    const int k = saltation::pick_corner(L.fx, L.fy, u);
    landed(L.x0 + (k & 1), L.y0 + (k >> 1)) += a;
  }
}

// With obstacles within reach: each hop walks its path and never lands in an
// obstacle (stages/obstacles.h, [BR04 4.1]); both transport modes, scalar.
// Without any in reach the result is exactly that of the rows above.
void scatter_row_obstacles(units_t* air, const float* wx, const float* wy, const TileGeom& g, int y,
                           std::uint64_t seed, std::uint64_t step, const saltation::Params& p,
                           const float* o_base, Field<units_t>& landed) {
  const long pitch = g.pitch;
  for (int x = 0; x < g.nx; ++x) {
    const units_t a = air[x];
    if (a == 0) continue;
    air[x] = 0;
    const saltation::Landing L = saltation::landing(x, y, {wx[x], wy[x]}, p);
    const obstacles::Path path =
        obstacles::hop_path(o_base, pitch, x, y, static_cast<float>(L.x0 - x) + L.fx,
                            static_cast<float>(L.y0 - y) + L.fy);
    if (p.stochastic) {
      const float u = u01(random4(seed, step, g.global_index(x, y), RandomStream::kLanding).v[0]);
      const int k = saltation::pick_corner(L.fx, L.fy, u);
      const obstacles::Cell c =
          obstacles::receiver(o_base, pitch, L.x0 + (k & 1), L.y0 + (k >> 1), path);
      landed(c.x, c.y) += a;
    } else {
      units_t q[4];
      saltation::split_bilinear(a, L.fx, L.fy, q);
      for (int k = 0; k < 4; ++k) {
        const obstacles::Cell c =
            obstacles::receiver(o_base, pitch, L.x0 + (k & 1), L.y0 + (k >> 1), path);
        landed(c.x, c.y) += q[k];
      }
    }
  }
}

}  // namespace

void CpuBackend::saltation_hop(std::int64_t step) {
  const saltation::Params p = m_.saltation;
  const std::uint64_t seed = m_.seed;
  const auto ustep = static_cast<std::uint64_t>(step);

  // (1) Lift into the airborne buffer (which holds last step's bounces).
#pragma omp parallel for num_threads(threads_) schedule(static)
  for (int y = 0; y < g_.ny; ++y)
    lift_row(f_.sand.row(y), f_.airborne.row(y), f_.shadow.row(y), f_.vegetation.row(y),
             f_.wind_x.row(y), f_.wind_y.row(y), f_.echo.row(y), g_, y, seed, ustep, p);

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
      std::vector<units_t> parts(4 * static_cast<size_t>(g_.nx));
      for (int y = y_begin; y < y_end; ++y) {
        if (any_obstacles_) {
          scatter_row_obstacles(f_.airborne.row(y), f_.wind_x.row(y), f_.wind_y.row(y), g_, y, seed,
                                ustep, p, f_.obstacles.data() + g_.at(0, 0), f_.landed);
        } else if (p.stochastic) {
          scatter_row_stochastic(f_.airborne.row(y), f_.wind_x.row(y), f_.wind_y.row(y), g_, y,
                                 seed, ustep, p, f_.landed);
        } else {
          // Landing points and exact splits in a vectorised pass, then the
          // adds (which may collide) in a scalar one.
          split_row(f_.airborne.row(y), f_.wind_x.row(y), f_.wind_y.row(y), g_.nx, y,
                    static_cast<long>(g_.at(0, 0)), g_.pitch, p, target.data(), parts.data());
          units_t* base = f_.landed.data();
          const long pitch = g_.pitch;
          for (int x = 0; x < g_.nx; ++x) {
            const size_t k = 4 * static_cast<size_t>(x);
            const long t = target[static_cast<size_t>(x)];
            base[t] += parts[k];
            base[t + 1] += parts[k + 1];
            base[t + pitch] += parts[k + 2];
            base[t + pitch + 1] += parts[k + 3];
          }
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
                         f_.wind_x.row(y), f_.wind_y.row(y), f_.echo.row(y), f_.reptation.row(y),
                         f_.deposited.row(y), g_, y, seed, ustep, p) ||
              abraded;
  if (abraded) bedrock_changed_ = true;
}

}  // namespace erg::cpu

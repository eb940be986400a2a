// SPDX-License-Identifier: Apache-2.0
// Saltation on the GPU (stages/saltation.h), as backend/cpu/saltation.cpp:
// (1) lift into the airborne buffer, (2) scatter every airborne amount one hop
// downwind into `landed` (64-bit integer atomics: exact, any order), fold the
// ghosts back onto their owners (the torus), (3) deposit, bounce, abrade and
// record the reptation strength.
#include "backend/cuda/cuda_backend.h"
#include "backend/cuda/for_each.cuh"
#include "core/philox.h"
#include "stages/hop_landing.h"
#include "stages/saltation.h"

namespace erg::gpu {

namespace {

__device__ __forceinline__ void add_units(units_t* cell, units_t q) {
  // Two's-complement addition: the same bits as a signed add, in any order.
  atomicAdd(reinterpret_cast<unsigned long long*>(cell), static_cast<unsigned long long>(q));
}

// (3) Deposit, bounce, abrade; record the reptation strength.
__global__ void impact_kernel(TileGeom g, saltation::Params p, std::uint64_t seed,
                              std::uint64_t step, const units_t* landed, units_t* sand,
                              units_t* bedrock, units_t* airborne, const float* shadow,
                              const float* vegetation, const float* resistance, const float* wind_x,
                              const float* wind_y, const float* echo, float* reptation,
                              units_t* deposited, int* abraded) {
  int x, y;
  if (!owned_cell(g, x, y)) return;
  const std::size_t i = g.at(x, y);
  const units_t in = landed[i];
  float u = 0.0f;
  if (p.stochastic && in > 0)
    u = u01(random4(seed, step, g.global_index(x, y), RandomStream::kDeposit).v[0]);
  const saltation::Impact im =
      saltation::impact(in, sand[i], shadow[i], vegetation[i], resistance[i],
                        length(Vec2{wind_x[i], wind_y[i]}), u, p, echo[i]);
  if (saltation::settle(im, sand[i], bedrock[i], airborne[i], reptation[i], deposited[i]) != 0)
    *abraded = 1;  // every writer writes 1: a harmless race
}

}  // namespace

void CudaBackend::saltation_hop(std::int64_t step) {
  const saltation::Params p = m_.saltation;
  const std::uint64_t seed = m_.seed;
  const auto ustep = static_cast<std::uint64_t>(step);

  const TileGeom g = g_;
  units_t* airborne = d_.airborne.get();
  const float* wind_x = d_.wind_x.get();
  const float* wind_y = d_.wind_y.get();

  // (1) Lift (last step's bounces are already in the airborne buffer).
  units_t* sand = d_.sand.get();
  const float* shadow = d_.shadow.get();
  const float* vegetation = d_.vegetation.get();
  const float* echo = d_.echo.get();
  for_each_cell(g, "saltation lift", [=] __device__(int x, int y, std::size_t i) {
    const float speed = length(Vec2{wind_x[i], wind_y[i]});
    units_t q;
    if (p.stochastic) {
      const float u = u01(random4(seed, ustep, g.global_index(x, y), RandomStream::kLift).v[0]);
      q = saltation::lift_stochastic(sand[i], shadow[i], vegetation[i], speed, u, p, echo[i]);
    } else {
      q = saltation::lift_expected(sand[i], shadow[i], vegetation[i], speed, p, echo[i]);
    }
    sand[i] -= q;
    airborne[i] += q;
  });

  // (2) One hop downwind into `landed` (owned + ghosts), 64-bit integer
  // atomics: exact in any order. Hops never land in an obstacle [BR04 4.1].
  ERG_CUDA_CHECK(cudaMemsetAsync(d_.landed.get(), 0, d_.landed.bytes()));
  const bool obstacles = any_obstacles_;
  units_t* landed = d_.landed.get() + g.at(0, 0);
  const float* o_base = d_.obstacles.get() + g.at(0, 0);
  const float* h_base = d_.height_m.get() + g.at(0, 0);
  for_each_cell(g, "saltation scatter", [=] __device__(int x, int y, std::size_t i) {
    const units_t a = airborne[i];
    if (a == 0) return;
    airborne[i] = 0;
    const long c = static_cast<long>(y) * g.pitch + x;
    const saltation::Landing L =
        saltation::landing_over(x, y, {wind_x[i], wind_y[i]}, h_base + c, o_base + c, g.pitch, p);
    const saltation::LandingDraw u =
        p.stochastic ? saltation::landing_draw(seed, ustep, g.global_index(x, y))
                     : saltation::LandingDraw{0.0f, 0.0f};
    saltation::land_hop(a, x, y, L, u, p, obstacles, o_base, g.pitch,
                        [&](int cx, int cy, units_t q) {
                          add_units(landed + static_cast<long>(cy) * g.pitch + cx, q);
                        });
  });
}

// After the landed ghosts are summed into their owners (Simulation::step):
// sand that left the tile re-enters on the opposite side (the torus).
void CudaBackend::saltation_impact(std::int64_t step) {
  const saltation::Params p = m_.saltation;
  const std::uint64_t seed = m_.seed;
  const auto ustep = static_cast<std::uint64_t>(step);
  const Launch l = owned_cells(g_);
  ERG_LAUNCH(impact_kernel, l.grid, l.block, g_, p, seed, ustep, d_.landed.get(), d_.sand.get(),
             d_.bedrock.get(), d_.airborne.get(), d_.shadow.get(), d_.vegetation.get(),
             d_.resistance.get(), d_.wind_x.get(), d_.wind_y.get(), d_.echo.get(),
             d_.reptation.get(), d_.deposited.get(), abraded_.get());
}

}  // namespace erg::gpu

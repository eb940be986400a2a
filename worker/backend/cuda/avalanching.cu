// SPDX-License-Identifier: Apache-2.0
// Avalanching on the GPU (stages/avalanching.h), sand and bedrock, as
// backend/cpu/avalanching.cpp: every iteration is two gather passes over
// double-buffered heights. Pass 1 (avalanching::donor) gives each donor its
// fraction and the total it sends; pass 2 (avalanching::inflow) has each
// receiver recompute what its neighbours send it. As on the CPU, iterations
// run in rounds (Model::rounds): the j-th iteration of a round of R runs on
// the tile grown by 2 (R - j) cells, and a new round refills the ghosts of
// the layer that moves.
//
// A step iterates until settled or model.avalanche_iterations, the cap
// (docs/design.md, "Avalanching until settled"). The CPU stops once nothing
// moved and nothing can move later. One tile here reads back one flag every
// kCheckEvery iterations, not every iteration: once an iteration at the
// largest k_c still to come moves nothing, every donor has f = 0 and out =
// 0 from then on, so pass 2 is the identity and the iterations run past the
// CPU's stop leave the state unchanged. Each iteration sets a device flag
// when any donor sends sand; the flags are read back at the end, and the
// count of set flags is the CPU's count of iterations that moved sand.
// Several tiles read back, at each round boundary, whether the last
// iteration had any donor at all, and stop when no tile had (as the CPU).
#include <vector>

#include "backend/cuda/cuda_backend.h"
#include "stages/avalanching.h"
#include "stages/obstacles.h"

namespace erg::gpu {

namespace {

// One tile: iterations between the read-backs that decide whether to stop.
constexpr int kCheckEvery = 16;

// Whether an iteration after `it` of `n` runs at a larger k_c than `kc`.
bool larger_kc_later(int it, int n, float kc, float kc_full, float kc_damped) {
  for (int j = it + 1; j <= n; ++j)
    if (avalanching::kc_for(j, n, kc_full, kc_damped) > kc) return true;
  return false;
}

// Level-0 heights in metres: b + s for sand, b for bedrock.
// ghosts_only: the owned cells' heights are current (a new round of the
// same width), only the refilled ghosts change.
__global__ void level0_kernel(TileGeom g, int grow, bool ghosts_only, bool bedrock_only,
                              const units_t* bedrock, const units_t* sand, const float* ob,
                              float* h) {
  int x, y;
  if (!grown_cell(g, grow, x, y)) return;
  if (ghosts_only && x >= 0 && x < g.nx && y >= 0 && y < g.ny) return;
  const std::size_t i = g.at(x, y);
  h[i] = obstacles::avalanche_height(units_to_m(bedrock_only ? bedrock[i] : bedrock[i] + sand[i]),
                                     ob[i]);
}

// Pass 1: fraction and total sent by every donor (the complete donor(), with
// its rare correction loop: the CPU's common path plus corrections give the
// same values cell by cell). kBedrock: unlimited supply and one repose tangent.
template <bool kBedrock>
__global__ void donor_kernel(TileGeom g, int grow, Offsets off, const float* h, const float* tan_l,
                             float tan_l_const, bool isotropic, const units_t* sand,
                             const float* ob, float kc, float* frac, units_t* out, int* moved,
                             int* donors) {
  int x, y;
  if (!grown_cell(g, grow, x, y)) return;
  const long long i = static_cast<long long>(g.at(x, y));
  float hn[8];
  for (int k = 0; k < 8; ++k) hn[k] = h[i + off.o[k]];
  const float t = avalanching::donor_tangent(kBedrock ? tan_l_const : tan_l[i], hn, isotropic);
  const units_t avail = kBedrock ? kUnlimited : sand[i];
  avalanching::Donor d = avalanching::donor(h[i], hn, t, avail, kc);
  if (obstacles::is_obstacle(ob[i])) d = {0.0f, 0, false};  // a wall gives nothing
  frac[i] = d.f;
  out[i] = d.out;
  // Every writer stores the same value.
  if (d.out > 0) *moved = 1;
  if (d.f > 0.0f) *donors = 1;
}

// Pass 2: units each cell receives from its 8 neighbours, then the new layer
// and its heights in the other height buffer.
template <bool kBedrock>
__global__ void inflow_kernel(TileGeom g, int grow, Offsets off, const float* h, const float* tan_l,
                              float tan_l_const, bool isotropic, const float* frac,
                              const units_t* out, bool to_sand, units_t* target, units_t* sand,
                              const units_t* bedrock, const float* ob, float* h_next) {
  int x, y;
  if (!grown_cell(g, grow, x, y)) return;
  const long long i = static_cast<long long>(g.at(x, y));
  units_t in = 0;
  for (int k = 0; k < 8; ++k) {
    // The donor is the neighbour; it saw this cell in the opposite direction,
    // at the same distance.
    const long long j = i + off.o[k];
    // The donor's tangent as donor_kernel computed it (isotropic: from its
    // 3 x 3 heights, read only then; the branch is uniform over the launch).
    float t = kBedrock ? tan_l_const : tan_l[j];
    if (isotropic) {
      float hj[8];
      for (int n = 0; n < 8; ++n) hj[n] = h[j + off.o[n]];
      t = avalanching::donor_tangent(t, hj, true);
    }
    in += avalanching::inflow(frac[j], h[j], h[i], t, neighbour(k).dist);
  }
  if (!kBedrock) {
    target[i] = target[i] - out[i] + in;
    h_next[i] = obstacles::avalanche_height(units_to_m(bedrock[i] + target[i]), ob[i]);
  } else if (to_sand) {
    // Fallen rock breaks into sand where it lands [N24 3.8].
    target[i] -= out[i];
    sand[i] += in;
    h_next[i] = obstacles::avalanche_height(units_to_m(target[i]), ob[i]);
  } else {
    target[i] = target[i] - out[i] + in;
    h_next[i] = obstacles::avalanche_height(units_to_m(target[i]), ob[i]);
  }
}

}  // namespace

AvalancheResult CudaBackend::avalanche(bool bedrock, int iterations, const Refill& refill,
                                       bool* settled) {
  if (settled) *settled = false;
  if (iterations <= 0) return {};
  const Offsets off = neighbour_offsets(g_.pitch);
  DeviceBuffer<units_t>& target = bedrock ? d_.bedrock : d_.sand;
  AvalancheRounds::Round round = m_.rounds.of(1, iterations);
  int e = 2 * round.length;
  const bool alone = ex_.tiles() == 1;

  ERG_LAUNCH(level0_kernel, grown_cells(g_, e).grid, grown_cells(g_, e).block, g_, e, false,
             bedrock, d_.bedrock.get(), d_.sand.get(), d_.obstacles.get(), h_a_.get());
  // moved_[it - 1]: iteration it sent sand; moved_[iterations + it - 1]: it
  // had a donor (f > 0).
  ERG_CUDA_CHECK(
      cudaMemsetAsync(moved_.get(), 0, sizeof(int) * 2 * static_cast<std::size_t>(iterations)));

  const float kc_full = m_.kc;
  int ran = iterations;
  bool stopped = false;  // stopped before the cap (on every tile alike)
  for (int it = 1; it <= iterations; ++it) {
    if (alone && it > 1 && (it - 1) % kCheckEvery == 0) {
      // Iteration it - 1 moved nothing, and no larger k_c follows: every
      // later iteration is the identity.
      int moved_last = 0;
      ERG_CUDA_CHECK(
          cudaMemcpy(&moved_last, moved_.get() + (it - 2), sizeof(int), cudaMemcpyDeviceToHost));
      const float kc_last = avalanching::kc_for(it - 1, iterations, kc_full, m_.kc_damped);
      if (moved_last == 0 && !larger_kc_later(it - 1, iterations, kc_last, kc_full, m_.kc_damped)) {
        ran = it - 1;
        stopped = true;
        break;
      }
    }
    if (it > 1 && it == round.first + round.length) {
      if (!alone) {
        int donors = 0;
        ERG_CUDA_CHECK(cudaMemcpy(&donors, moved_.get() + iterations + (it - 2), sizeof(int),
                                  cudaMemcpyDeviceToHost));
        if (!ex_.any(donors != 0)) {
          ran = it - 1;
          stopped = true;
          break;
        }
      }
      // A new round: refill the ghosts of the layer that moved (and of
      // bedrock under sand when the round is wider than the first) and
      // recompute the heights of the grown tile.
      round = m_.rounds.of(it, iterations);
      const int e_last = e;
      e = 2 * round.length;
      refill_round(refill, bedrock, e, e_last);
      ERG_LAUNCH(level0_kernel, grown_cells(g_, e).grid, grown_cells(g_, e).block, g_, e,
                 e <= e_last, bedrock, d_.bedrock.get(), d_.sand.get(), d_.obstacles.get(),
                 h_a_.get());
    }
    const int j = it - round.first + 1;  // iteration within the round
    const float kc = avalanching::kc_for(it, iterations, kc_full, m_.kc_damped);
    const int grow1 = 2 * (round.length - j) + 1, grow2 = grow1 - 1;  // pass 1, pass 2
    const Launch l1 = grown_cells(g_, grow1), l2 = grown_cells(g_, grow2);
    int* moved = moved_.get() + (it - 1);
    int* donors = moved_.get() + iterations + (it - 1);
    if (bedrock)
      ERG_LAUNCH(donor_kernel<true>, l1.grid, l1.block, g_, grow1, off, h_a_.get(), nullptr,
                 m_.tan_l_bedrock, m_.repose_isotropic, nullptr, d_.obstacles.get(), kc,
                 frac_.get(), out_.get(), moved, donors);
    else
      ERG_LAUNCH(donor_kernel<false>, l1.grid, l1.block, g_, grow1, off, h_a_.get(), d_.tan_l.get(),
                 0.0f, m_.repose_isotropic, d_.sand.get(), d_.obstacles.get(), kc, frac_.get(),
                 out_.get(), moved, donors);

    if (bedrock)
      ERG_LAUNCH(inflow_kernel<true>, l2.grid, l2.block, g_, grow2, off, h_a_.get(), nullptr,
                 m_.tan_l_bedrock, m_.repose_isotropic, frac_.get(), out_.get(), m_.bedrock_to_sand,
                 target.get(), d_.sand.get(), d_.bedrock.get(), d_.obstacles.get(), h_b_.get());
    else
      ERG_LAUNCH(inflow_kernel<false>, l2.grid, l2.block, g_, grow2, off, h_a_.get(),
                 d_.tan_l.get(), 0.0f, m_.repose_isotropic, frac_.get(), out_.get(), false,
                 target.get(), d_.sand.get(), d_.bedrock.get(), d_.obstacles.get(), h_b_.get());
    h_a_.swap(h_b_);
  }

  std::vector<int> flags(static_cast<std::size_t>(ran));
  ERG_CUDA_CHECK(
      cudaMemcpy(flags.data(), moved_.get(), sizeof(int) * flags.size(), cudaMemcpyDeviceToHost));
  int moved_iterations = 0;
  for (const int f : flags) moved_iterations += f != 0 ? 1 : 0;
  // At the cap with sand still moving (on any tile: every tile reaches the
  // cap together). Bedrock runs its few iterations [N24 3.8] and is not asked.
  bool capped = false;
  if (!bedrock && !stopped) {
    const bool here = !flags.empty() && flags.back() != 0;
    capped = alone ? here : ex_.any(here);
  }
  if (settled && ran > 0) {
    // The last iteration run had no donor: nothing here exceeds repose, so
    // the same avalanche on the same terrain is the identity.
    int donors = 0;
    ERG_CUDA_CHECK(cudaMemcpy(&donors, moved_.get() + iterations + (ran - 1), sizeof(int),
                              cudaMemcpyDeviceToHost));
    *settled = donors == 0;
  }
  return {moved_iterations, capped};
}

AvalancheResult CudaBackend::avalanche_sand(const Refill& refill) {
  if (m_.avalanche_iterations <= 0) return {};
  return avalanche(false, m_.avalanche_iterations, refill);
}

// Bedrock only changes by abrasion and events. Once an avalanche found it
// settled on every tile, running it again on the same bedrock is the
// identity, so it is skipped until bedrock changes somewhere, as on the CPU
// (cpu/avalanching.cpp). Abrasion is learnt from one device flag (4 bytes).
void CudaBackend::avalanche_bedrock(const Refill& refill) {
  int abraded = 0;
  ERG_CUDA_CHECK(cudaMemcpy(&abraded, abraded_.get(), sizeof(int), cudaMemcpyDeviceToHost));
  if (abraded != 0) {
    bedrock_changed_ = true;
    ERG_CUDA_CHECK(cudaMemset(abraded_.get(), 0, sizeof(int)));
  }
  if (!ex_.any(bedrock_changed_)) return;
  bool settled = false;
  avalanche(true, m_.bedrock_iterations, refill, &settled);
  bedrock_changed_ = !settled;
}

}  // namespace erg::gpu

// Avalanching on the CPU (stages/avalanching.h), sand and bedrock.
//
// Each iteration is two gather passes over double-buffered heights; row
// kernels are written so the compiler vectorises them (no early exits in the
// common path; the rare corrections run in a scalar pass over the row).
// Iterations stop early once nothing moved and nothing can move later: the
// remaining iterations would be the identity, so the result is unchanged.
#include <algorithm>
#include <limits>

#include "backend/cpu/cpu_backend.h"
#include "stages/avalanching.h"

namespace erg::cpu {

namespace {

// Neighbour offsets in storage, in kNeighbours order.
struct Offsets {
  long o[8];
  explicit Offsets(int pitch) {
    for (int k = 0; k < 8; ++k) o[k] = static_cast<long>(kNeighbours[k].dy) * pitch + kNeighbours[k].dx;
  }
};

constexpr units_t kUnlimited = std::numeric_limits<units_t>::max() / 4;

struct RowFlags {
  bool moved = false;
  bool stuck = false;
};

// Pass 1 on one row: fraction and total sent by every donor.
// kBedrock: unlimited supply and one repose tangent for all cells.
template <bool kBedrock>
RowFlags donor_row(const float* h, const float* tan_l, float tan_l_const, const units_t* sand,
                   float kc, const Offsets& off, int n, float* frac, units_t* out) {
  // Offsets in locals: loads through `off` inside the loop would not be
  // hoisted (the stores to frac/out might alias it) and block vectorisation.
  const long o0 = off.o[0], o1 = off.o[1], o2 = off.o[2], o3 = off.o[3];
  const long o4 = off.o[4], o5 = off.o[5], o6 = off.o[6], o7 = off.o[7];
  for (int x = 0; x < n; ++x) {
    const float hn[8] = {h[x + o0], h[x + o1], h[x + o2], h[x + o3],
                         h[x + o4], h[x + o5], h[x + o6], h[x + o7]};
    const float t = kBedrock ? tan_l_const : tan_l[x];
    const units_t avail = kBedrock ? kUnlimited : sand[x];
    const avalanching::Donor d = avalanching::donor_shares(h[x], hn, t, avail, kc);
    frac[x] = d.f;
    out[x] = d.out;
  }
  RowFlags flags;
  for (int x = 0; x < n; ++x) {
    const units_t avail = kBedrock ? kUnlimited : sand[x];
    if (out[x] > avail || out[x] == 0) {
      if (out[x] == 0 && frac[x] == 0.0f) continue;
      float hn[8];
      for (int k = 0; k < 8; ++k) hn[k] = h[x + off.o[k]];
      const float t = kBedrock ? tan_l_const : tan_l[x];
      const avalanching::Donor d = avalanching::donor(h[x], hn, t, avail, kc);
      frac[x] = d.f;
      out[x] = d.out;
      flags.stuck |= d.stuck;
    }
    flags.moved |= out[x] > 0;
  }
  return flags;
}

// Pass 2 on one row: units each cell receives from its 8 neighbours.
template <bool kBedrock>
void inflow_row(const float* h, const float* tan_l, float tan_l_const, const float* frac,
                const Offsets& off, int n, units_t* in) {
  for (int x = 0; x < n; ++x) {
    units_t sum = 0;
    ERG_UNROLL
    for (int k = 0; k < 8; ++k) {
      // The donor is the neighbour; it saw this cell in the opposite direction,
      // at the same distance.
      const long j = x + off.o[k];
      const float t = kBedrock ? tan_l_const : tan_l[j];
      sum += avalanching::inflow(frac[j], h[j], h[x], t, kNeighbours[k].dist);
    }
    in[x] = sum;
  }
}

}  // namespace

int CpuBackend::avalanche(bool bedrock, int iterations, bool* settled) {
  if (settled) *settled = false;
  if (iterations <= 0) return 0;
  const Offsets off(g_.pitch);
  const int n = g_.nx;
  Field<units_t>& target = bedrock ? bedrock_ : sand_;

  // Level-0 heights in metres.
#pragma omp parallel for num_threads(threads_) schedule(static)
  for (int y = 0; y < g_.ny; ++y) {
    const units_t* b = bedrock_.row(y);
    const units_t* s = sand_.row(y);
    float* h = h_a_.row(y);
    for (int x = 0; x < n; ++x) h[x] = units_to_m(bedrock ? b[x] : b[x] + s[x]);
  }
  fill_halo_periodic(h_a_, 1);

  const float kc_full = m_.kc;
  int moved_iterations = 0;
  for (int it = 1; it <= iterations; ++it) {
    const float kc = avalanching::kc_for(it, iterations, kc_full, m_.kc_damped);
    bool moved = false, stuck = false;
#pragma omp parallel for num_threads(threads_) schedule(static) reduction(|| : moved, stuck)
    for (int y = 0; y < g_.ny; ++y) {
      const RowFlags f =
          bedrock ? donor_row<true>(h_a_.row(y), nullptr, m_.tan_l_bedrock, nullptr, kc, off, n,
                                    frac_.row(y), out_.row(y))
                  : donor_row<false>(h_a_.row(y), tan_l_.row(y), 0.0f, sand_.row(y), kc, off, n,
                                     frac_.row(y), out_.row(y));
      moved = moved || f.moved;
      stuck = stuck || f.stuck;
    }
    if (!moved) {
      // Nothing moved: the same heights come back next iteration. Only a
      // larger k_c later could move a stuck donor.
      bool larger_kc_later = false;
      for (int j = it + 1; j <= iterations; ++j)
        larger_kc_later |= avalanching::kc_for(j, iterations, kc_full, m_.kc_damped) > kc;
      if (settled) *settled = !stuck;
      if (!stuck || !larger_kc_later) break;
      continue;
    }
    ++moved_iterations;
    fill_halo_periodic(frac_, 1);

#pragma omp parallel for num_threads(threads_) schedule(static)
    for (int y = 0; y < g_.ny; ++y) {
      units_t* in = sand_next_.row(y);  // scratch: inflow, then the new layer
      if (bedrock) inflow_row<true>(h_a_.row(y), nullptr, m_.tan_l_bedrock, frac_.row(y), off, n, in);
      else inflow_row<false>(h_a_.row(y), tan_l_.row(y), 0.0f, frac_.row(y), off, n, in);
      const units_t* out = out_.row(y);
      units_t* t = target.row(y);
      units_t* s = sand_.row(y);
      const units_t* b = bedrock_.row(y);
      float* h = h_b_.row(y);
      if (!bedrock) {
        for (int x = 0; x < n; ++x) {
          t[x] = t[x] - out[x] + in[x];
          h[x] = units_to_m(b[x] + t[x]);
        }
      } else if (m_.bedrock_to_sand) {
        // Fallen rock breaks into sand where it lands [N24 3.8].
        for (int x = 0; x < n; ++x) {
          t[x] -= out[x];
          s[x] += in[x];
          h[x] = units_to_m(t[x]);
        }
      } else {
        for (int x = 0; x < n; ++x) {
          t[x] = t[x] - out[x] + in[x];
          h[x] = units_to_m(t[x]);
        }
      }
    }
    h_a_.swap(h_b_);
    fill_halo_periodic(h_a_, 1);
  }
  return moved_iterations;
}

int CpuBackend::avalanche_sand() {
  if (m_.avalanche_iterations <= 0) return 0;
  return avalanche(false, m_.avalanche_iterations, nullptr);
}

// Bedrock only changes by abrasion and events. Once an avalanche found it
// settled (nothing moved, no donor waiting for a larger k_c), running it again
// on the same bedrock is the identity, so it is skipped until bedrock changes.
void CpuBackend::avalanche_bedrock() {
  if (!bedrock_changed_) return;
  bool settled = false;
  avalanche(true, m_.bedrock_iterations, &settled);
  bedrock_changed_ = !settled;
}

}  // namespace erg::cpu

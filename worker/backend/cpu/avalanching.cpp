// Avalanching on the CPU (stages/avalanching.h), sand and bedrock.
//
// Each iteration is two gather passes: pass 1 computes every donor's
// fraction f, pass 2 every cell's inflow and outflow (both sides evaluate the
// same shares, so they agree to the unit), then the changed heights are
// recomputed. Heights are read only from the previous iteration.
//
// Ghost-zone expansion (docs/design.md, "Tiling"): iterations run in rounds of R;
// a round starts from layers whose ghosts are filled 2R + 1 cells wide, and
// its j-th iteration runs on the tile grown by 2(R - j) cells, so after R
// iterations the owned cells are exact, with no exchange in between. Ghost
// cells are recomputed exactly as their owners compute them (same inputs,
// same functions). With several tiles the rounds are kTiledRounds
// (sim/model.h: 4 iterations, then the rest in one): the first round's ghosts
// come with the exchange before reptation, and at a later round boundary the
// tiles first agree (one logical or) whether any of them still has something
// to move, so a settled terrain (most steps, after the first few) costs no
// refill at all.
// One tile refills its ghosts, a local copy, before every iteration (R = 1).
//
// Work is tracked in segments of 64 cells of a row. After the first
// iteration, which visits every cell, an iteration visits only the segments
// where something can happen: pass 1 where a height within two cells changed
// in the last iteration (or where a donor still has f > 0), pass 2 within one
// cell of a donor. Everywhere else the iteration is the identity, so the
// result is exactly that of visiting every cell, at a fraction of the cost
// once the terrain is mostly settled. Iterations stop once nothing moved and
// nothing can move later: on one tile at once, with several at the end of
// the round in which every tile has found so (results do not depend on it:
// the skipped iterations are identities).
#include "stages/avalanching.h"

#include <algorithm>
#include <cstdint>
#include <limits>
#include <vector>

#include "backend/cpu/cpu_backend.h"
#include "stages/obstacles.h"

namespace erg::cpu {

namespace {

constexpr int kSegment = 64;
constexpr units_t kUnlimited = std::numeric_limits<units_t>::max() / 4;

struct Stencil {
  long o[8];  // storage offsets of the neighbours, kNeighbours order
  explicit Stencil(int pitch) {
    for (int k = 0; k < 8; ++k)
      o[k] = static_cast<long>(kNeighbours[k].dy) * pitch + kNeighbours[k].dx;
  }
};

// Pass 1 on cells [x0, x1) of a row. Returns whether any f > 0.
// kBedrock: unlimited supply and one repose tangent for all cells.
template <bool kBedrock>
bool fraction_segment(const float* h, const float* tan_l, float tan_l_const, const units_t* sand,
                      const float* ob, float kc, const Stencil& st, int x0, int x1,
                      float* __restrict frac) {
  const long o0 = st.o[0], o1 = st.o[1], o2 = st.o[2], o3 = st.o[3];
  const long o4 = st.o[4], o5 = st.o[5], o6 = st.o[6], o7 = st.o[7];
  int checks = 0, positive = 0;
  for (int x = x0; x < x1; ++x) {
    const float hn[8] = {h[x + o0], h[x + o1], h[x + o2], h[x + o3],
                         h[x + o4], h[x + o5], h[x + o6], h[x + o7]};
    const avalanching::Fraction fr = avalanching::fraction(
        h[x], hn, kBedrock ? tan_l_const : tan_l[x], kBedrock ? kUnlimited : sand[x], kc);
    // An obstacle gives nothing (it is a wall, stages/obstacles.h).
    const bool wall = obstacles::is_obstacle(ob[x]);
    frac[x] = wall ? 0.0f : fr.f;
    checks += fr.check & !wall;
    positive += (fr.f > 0.0f) & !wall;
  }
  if (checks > 0) {
    // Rare: shares that might exceed the sand present; the complete donor()
    // shrinks f until they fit.
    for (int x = x0; x < x1; ++x) {
      const float hn[8] = {h[x + o0], h[x + o1], h[x + o2], h[x + o3],
                           h[x + o4], h[x + o5], h[x + o6], h[x + o7]};
      const float t = kBedrock ? tan_l_const : tan_l[x];
      const units_t avail = kBedrock ? kUnlimited : sand[x];
      if (avalanching::fraction(h[x], hn, t, avail, kc).check && !obstacles::is_obstacle(ob[x]))
        frac[x] = avalanching::donor(h[x], hn, t, avail, kc).f;
    }
  }
  return positive > 0;
}

// Pass 2 on cells [x0, x1) of a row: units each cell gains and loses.
// Returns whether any cell sent or received anything.
template <bool kBedrock>
bool exchange_segment(const float* h, const float* tan_l, float tan_l_const, const float* frac,
                      const Stencil& st, int x0, int x1, units_t* __restrict gain,
                      units_t* __restrict loss) {
  const long o0 = st.o[0], o1 = st.o[1], o2 = st.o[2], o3 = st.o[3];
  const long o4 = st.o[4], o5 = st.o[5], o6 = st.o[6], o7 = st.o[7];
  int active = 0;
  for (int x = x0; x < x1; ++x) {
    const float hx = h[x];
    // The donor is the neighbour; it saw this cell in the opposite
    // direction, at the same distance.
    auto in = [=](long o, float dist) {
      return avalanching::inflow(frac[x + o], h[x + o], hx, kBedrock ? tan_l_const : tan_l[x + o],
                                 dist);
    };
    const units_t received = in(o0, 1.0f) + in(o1, kSqrt2) + in(o2, 1.0f) + in(o3, kSqrt2) +
                             in(o4, 1.0f) + in(o5, kSqrt2) + in(o6, 1.0f) + in(o7, kSqrt2);
    const float hn[8] = {h[x + o0], h[x + o1], h[x + o2], h[x + o3],
                         h[x + o4], h[x + o5], h[x + o6], h[x + o7]};
    const units_t sent = avalanching::outflow(
        frac[x], avalanching::excesses(hx, hn, kBedrock ? tan_l_const : tan_l[x]));
    gain[x - x0] = received;
    loss[x - x0] = sent;
    active += (received | sent) != 0;
  }
  return active > 0;
}

// Marks, in `out`, the segments within `dy` rows and one segment of a marked
// segment of `in` (clipped at the region's edges: the region is a tile with
// its ghosts, not a torus).
void dilate(const std::vector<std::uint8_t>& in, std::vector<std::uint8_t>& out, int rows, int segs,
            int dy) {
  std::fill(out.begin(), out.end(), 0);
  for (int y = 0; y < rows; ++y)
    for (int s = 0; s < segs; ++s) {
      if (!in[static_cast<size_t>(y) * segs + s]) continue;
      for (int yy = std::max(0, y - dy); yy <= std::min(rows - 1, y + dy); ++yy) {
        std::uint8_t* r = out.data() + static_cast<size_t>(yy) * segs;
        for (int ss = std::max(0, s - 1); ss <= std::min(segs - 1, s + 1); ++ss) r[ss] = 1;
      }
    }
}

}  // namespace

int CpuBackend::avalanche(bool bedrock, int iterations, bool* settled) {
  if (settled) *settled = false;
  if (iterations <= 0) return 0;
  const Stencil st(g_.pitch);
  const int nx = g_.nx, ny = g_.ny;
  // Iteration j of a round of R runs pass 2 on the tile grown by 2 (R - j)
  // cells and pass 1 on one more; a round starts at e = 2R, within the ghosts
  // the exchange before reptation (or the refill of the round) filled. The
  // segment masks cover the widest round, E = 2 max(R).
  const int widest = 2 * m_.rounds.widest(iterations);
  const int rows = ny + 2 * widest, cols = nx + 2 * widest;
  const int segs = (cols + kSegment - 1) / kSegment;
  const size_t nseg = static_cast<size_t>(rows) * segs;
  Field<units_t>& target = bedrock ? bedrock_ : sand_;
  const float tan_b = m_.tan_l_bedrock;

  // Heights in metres on rows [y0, y1) and columns [x0, x1).
  auto heights = [&](int y0, int y1, int x0, int x1) {
#pragma omp parallel for num_threads(threads_) schedule(static)
    for (int y = y0; y < y1; ++y) {
      const units_t* b = bedrock_.row(y);
      const units_t* s = sand_.row(y);
      const float* o = obstacles_.row(y);
      float* h = h_a_.row(y);
      for (int x = x0; x < x1; ++x)
        h[x] = obstacles::avalanche_height(units_to_m(bedrock ? b[x] : b[x] + s[x]), o[x]);
    }
  };
  AvalancheRounds::Round round = m_.rounds.of(1, iterations);
  int e = 2 * round.length;
  heights(-e, ny + e, -e, nx + e);

  // Segment (r, s) covers row r - E, columns [s * 64 - E, (s + 1) * 64 - E).
  std::vector<std::uint8_t> visit(nseg, 1), positive(nseg, 0), exchange(nseg, 0), changed(nseg, 0);
  int moved_iterations = 0;
  // With several tiles a tile that finds nothing left to move still takes
  // part in the refills until every tile has found so: a neighbour's sand
  // may yet flow across its edge in a later round.
  const bool alone = ex_.tiles() == 1;
  bool stopped_here = false;  // nothing moves here before the round ends
  bool no_donors = false;     // ... nor in any later step on this terrain
  for (int it = 1; it <= iterations; ++it) {
    const float kc = avalanching::kc_for(it, iterations, m_.kc, m_.kc_damped);
    if (it > 1 && it == round.first + round.length) {
      if (!alone) {
        if (!ex_.any(!stopped_here)) break;
        stopped_here = false;
      }
      // A new round: refill the ghosts of the layer that moved, recompute
      // their heights, and revisit every cell that reads them.
      round = m_.rounds.of(it, iterations);
      const int e_last = e;
      e = 2 * round.length;
      ex_.fill(target, e + 1);
      if (e <= e_last) {
        heights(-e, 0, -e, nx + e);
        heights(ny, ny + e, -e, nx + e);
        heights(0, ny, -e, 0);
        heights(0, ny, nx, nx + e);
        for (int r = 0; r < rows; ++r)
          for (int s = 0; s < segs; ++s) {
            const int y = r - widest, x0 = s * kSegment - widest, x1 = x0 + kSegment;
            const bool near_edge = y < e + 2 || y >= ny - e - 2 || x0 < e + 2 || x1 > nx - e - 2;
            if (near_edge) visit[static_cast<size_t>(r) * segs + s] = 1;
          }
      } else {
        // A wider round (the rest of the iterations in one, several tiles):
        // the other layer's ghosts too, and every cell.
        if (!bedrock) ex_.fill(bedrock_, e + 1);
        heights(-e, ny + e, -e, nx + e);
        std::fill(visit.begin(), visit.end(), 1);
      }
    }
    if (stopped_here) continue;                                       // until the round ends
    const int j = it - round.first + 1;                               // iteration within the round
    const int grow1 = 2 * (round.length - j) + 1, grow2 = grow1 - 1;  // pass 1, pass 2

    // Pass 1: fractions where heights may have changed, or donors remain.
    bool any_positive = false;
#pragma omp parallel for num_threads(threads_) schedule(dynamic, 4) reduction(|| : any_positive)
    for (int r = 0; r < rows; ++r) {
      const int y = r - widest;
      for (int s = 0; s < segs; ++s) {
        const size_t k = static_cast<size_t>(r) * segs + s;
        positive[k] = 0;
        if (!visit[k] || y < -grow1 || y >= ny + grow1) continue;
        const int x0 = std::max(s * kSegment - widest, -grow1);
        const int x1 = std::min((s + 1) * kSegment - widest, nx + grow1);
        if (x0 >= x1) continue;
        positive[k] =
            bedrock ? fraction_segment<true>(h_a_.row(y), nullptr, tan_b, nullptr,
                                             obstacles_.row(y), kc, st, x0, x1, frac_.row(y))
                    : fraction_segment<false>(h_a_.row(y), tan_l_.row(y), 0.0f, sand_.row(y),
                                              obstacles_.row(y), kc, st, x0, x1, frac_.row(y));
        any_positive = any_positive || positive[k];
      }
    }
    no_donors = !any_positive;
    if (no_donors) {
      // Every f is 0: nothing exceeds repose (or nothing is available), for
      // any k_c. This and every later iteration are the identity.
      stopped_here = true;
      if (alone) break;
      continue;
    }

    // Pass 2: exchanges within one cell of a donor (it reads f only inside
    // this iteration's pass-1 region).
    dilate(positive, exchange, rows, segs, 1);
    if (m_.avalanche_everywhere) std::fill(exchange.begin(), exchange.end(), 1);
    bool any_change = false;
#pragma omp parallel for num_threads(threads_) schedule(dynamic, 4) reduction(|| : any_change)
    for (int r = 0; r < rows; ++r) {
      const int y = r - widest;
      units_t gain[kSegment], loss[kSegment];
      for (int s = 0; s < segs; ++s) {
        const size_t k = static_cast<size_t>(r) * segs + s;
        changed[k] = 0;
        if (!exchange[k] || y < -grow2 || y >= ny + grow2) continue;
        const int x0 = std::max(s * kSegment - widest, -grow2);
        const int x1 = std::min((s + 1) * kSegment - widest, nx + grow2);
        if (x0 >= x1) continue;
        const bool active = bedrock ? exchange_segment<true>(h_a_.row(y), nullptr, tan_b,
                                                             frac_.row(y), st, x0, x1, gain, loss)
                                    : exchange_segment<false>(h_a_.row(y), tan_l_.row(y), 0.0f,
                                                              frac_.row(y), st, x0, x1, gain, loss);
        if (!active) continue;
        // Pass 2 reads only heights and fractions, so the layers can be
        // updated in place.
        units_t* t = target.row(y);
        units_t* sd = sand_.row(y);
        if (bedrock && m_.bedrock_to_sand) {
          // Fallen rock breaks into sand where it lands [N24 3.8].
          for (int x = x0; x < x1; ++x) {
            t[x] -= loss[x - x0];
            sd[x] += gain[x - x0];
          }
        } else {
          for (int x = x0; x < x1; ++x) t[x] += gain[x - x0] - loss[x - x0];
        }
        changed[k] = 1;
        any_change = true;
      }
    }
    if (!any_change) {
      // Donors exist but every share rounds to 0. Only a larger k_c later
      // could move them.
      bool larger_kc_later = false;
      for (int j = it + 1; j <= iterations; ++j)
        larger_kc_later |= avalanching::kc_for(j, iterations, m_.kc, m_.kc_damped) > kc;
      if (!larger_kc_later) {
        stopped_here = true;
        if (alone) break;
        continue;
      }
      visit = positive;
      if (m_.avalanche_everywhere) std::fill(visit.begin(), visit.end(), 1);
      continue;
    }
    ++moved_iterations;

    // New heights where layers changed (after pass 2: it read the old ones).
#pragma omp parallel for num_threads(threads_) schedule(dynamic, 4)
    for (int r = 0; r < rows; ++r) {
      const int y = r - widest;
      for (int s = 0; s < segs; ++s) {
        if (!changed[static_cast<size_t>(r) * segs + s]) continue;
        const int x0 = std::max(s * kSegment - widest, -grow2);
        const int x1 = std::min((s + 1) * kSegment - widest, nx + grow2);
        const units_t* b = bedrock_.row(y);
        const units_t* sd = sand_.row(y);
        const float* o = obstacles_.row(y);
        float* h = h_a_.row(y);
        for (int x = x0; x < x1; ++x)
          h[x] = obstacles::avalanche_height(units_to_m(bedrock ? b[x] : b[x] + sd[x]), o[x]);
      }
    }

    // Next pass 1: within two cells of a change, and wherever donors remain
    // (k_c may change their f).
    dilate(changed, visit, rows, segs, 2);
    for (size_t k = 0; k < nseg; ++k)
      visit[k] |= positive[k] | static_cast<std::uint8_t>(m_.avalanche_everywhere);
  }
  if (settled) *settled = no_donors;
  return moved_iterations;
}

int CpuBackend::avalanche_sand() {
  if (m_.avalanche_iterations <= 0) return 0;
  return avalanche(false, m_.avalanche_iterations, nullptr);
}

// Bedrock only changes by abrasion and events. Once an avalanche found it
// settled on every tile (no cell exceeds the bedrock repose angle), running
// it again on the same bedrock is the identity, so it is skipped until
// bedrock changes somewhere.
void CpuBackend::avalanche_bedrock() {
  if (!ex_.any(bedrock_changed_)) return;
  bool settled = false;
  avalanche(true, m_.bedrock_iterations, &settled);
  bedrock_changed_ = !settled;
}

}  // namespace erg::cpu

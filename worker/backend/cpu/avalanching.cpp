// SPDX-License-Identifier: Apache-2.0
// Avalanching on the CPU (stages/avalanching.h), sand and bedrock.
//
// Each iteration is two gather passes: pass 1 computes every donor's
// fraction f, pass 2 every cell's inflow and outflow (both sides evaluate the
// same shares, so they agree to the unit), then the changed heights are
// recomputed. Heights are read only from the previous iteration.
//
// A step iterates until the terrain settles: until an iteration finds no
// donor, or moves nothing and no larger k_c follows (docs/design.md,
// "Avalanching until settled"). `iterations` (model.avalanche_iterations,
// [N24]'s 50 by default) caps it; a step that reaches it with sand still moving says so
// (AvalancheResult::capped, the same on every tile).
//
// Ghost-zone expansion (docs/design.md, "Tiling"): iterations run in rounds of R;
// a round starts from layers whose ghosts are filled 2R + 1 cells wide, and
// its j-th iteration runs on the tile grown by 2(R - j) cells, so after R
// iterations the owned cells are exact, with no exchange in between. Ghost
// cells are recomputed exactly as their owners compute them (same inputs,
// same functions). With several tiles the rounds are kTiledRounds
// (sim/model.h: 4 iterations, then rounds of 46): the first round's ghosts
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
#include <utility>
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

// The layers an avalanche reads and moves, and its work arrays
// (CpuBackend's fields).
struct AvalancheLayers {
  Field<units_t>& bedrock;
  Field<units_t>& sand;
  const Field<float>& obstacles;
  const Field<float>& tan_l;  // sand repose tangents
  Field<float>& h;            // heights in metres (h_a)
  Field<float>& frac;         // each donor's fraction f
};

// One avalanche of sand or bedrock over `iterations` iterations, in rounds
// (see the top of this file): the round boundaries, the two passes and the
// segment masks that say where each pass must look.
class AvalancheSweep {
 public:
  AvalancheSweep(const Model& m, const TileGeom& g, int threads, dist::Exchange& ex,
                 const Refill& refill, const AvalancheLayers& f, bool bedrock, int iterations)
      : m_(m),
        g_(g),
        threads_(threads),
        ex_(ex),
        refill_(refill),
        f_(f),
        bedrock_(bedrock),
        iterations_(iterations),
        st_(g.pitch),
        // Iteration j of a round of R runs pass 2 on the tile grown by
        // 2 (R - j) cells and pass 1 on one more; a round starts at e = 2R,
        // within the ghosts the exchange before reptation (or the refill of
        // the round) filled. The segment masks cover the widest round,
        // E = 2 max(R).
        widest_(2 * m.rounds.widest(iterations)),
        rows_(g.ny + 2 * widest_),
        segs_((g.nx + 2 * widest_ + kSegment - 1) / kSegment),
        // Segment (r, s) covers row r - E, columns [s * 64 - E, (s + 1) * 64 - E).
        visit_(static_cast<size_t>(rows_) * segs_, 1),
        positive_(visit_.size(), 0),
        exchange_(visit_.size(), 0),
        changed_(visit_.size(), 0),
        target_(bedrock ? f.bedrock : f.sand) {}

  // The number of iterations that moved something, and whether the cap was
  // reached with sand still moving; `settled`: no donor is left (nothing
  // exceeds repose).
  AvalancheResult run(bool* settled) {
    const int nx = g_.nx, ny = g_.ny;
    round_ = m_.rounds.of(1, iterations_);
    e_ = 2 * round_.length;
    heights(-e_, ny + e_, -e_, nx + e_);
    int moved_iterations = 0;
    // With several tiles a tile that finds nothing left to move still takes
    // part in the refills until every tile has found so: a neighbour's sand
    // may yet flow across its edge in a later round.
    const bool alone = ex_.tiles() == 1;
    bool stopped_here = false;  // nothing moves here before the round ends
    bool no_donors = false;     // ... nor in any later step on this terrain
    bool stopped = false;       // every tile stopped before the cap
    for (int it = 1; it <= iterations_; ++it) {
      const float kc = avalanching::kc_for(it, iterations_, m_.kc, m_.kc_damped);
      if (it > 1 && it == round_.first + round_.length) {
        if (!alone) {
          if (!ex_.any(!stopped_here)) {
            stopped = true;
            break;
          }
          stopped_here = false;
        }
        next_round(it);
      }
      if (stopped_here) continue;           // until the round ends
      const int j = it - round_.first + 1;  // iteration within the round
      const int grow1 = 2 * (round_.length - j) + 1, grow2 = grow1 - 1;  // pass 1, pass 2
      no_donors = !fractions(kc, grow1);
      if (no_donors) {
        // Every f is 0: nothing exceeds repose (or nothing is available),
        // for any k_c. This and every later iteration are the identity.
        stopped_here = true;
        if (alone) {
          stopped = true;
          break;
        }
        continue;
      }
      if (!exchanges(grow2)) {
        // Donors exist but every share rounds to 0. Only a larger k_c later
        // could move them.
        if (!larger_kc_later(it, kc)) {
          stopped_here = true;
          if (alone) {
            stopped = true;
            break;
          }
          continue;
        }
        visit_ = positive_;
        if (m_.avalanche_everywhere) std::fill(visit_.begin(), visit_.end(), 1);
        continue;
      }
      ++moved_iterations;
      new_heights(grow2);
      next_visit();
    }
    if (settled) *settled = no_donors;
    // At the cap: still moving if the last iteration moved something on any
    // tile (every tile reaches the cap together: the loop ends early only
    // on the decision all tiles share). Bedrock runs its few iterations
    // [N24 3.8] and is not asked.
    const bool capped = !bedrock_ && !stopped && (alone ? !stopped_here : ex_.any(!stopped_here));
    return {moved_iterations, capped};
  }

 private:
  // Heights in metres on rows [y0, y1) and columns [x0, x1).
  void heights(int y0, int y1, int x0, int x1) {
#pragma omp parallel for num_threads(threads_) schedule(static)
    for (int y = y0; y < y1; ++y) height_row(y, x0, x1);
  }

  void height_row(int y, int x0, int x1) {
    const units_t* b = f_.bedrock.row(y);
    const units_t* s = f_.sand.row(y);
    const float* o = f_.obstacles.row(y);
    float* h = f_.h.row(y);
    for (int x = x0; x < x1; ++x)
      h[x] = obstacles::avalanche_height(units_to_m(bedrock_ ? b[x] : b[x] + s[x]), o[x]);
  }

  // A new round at iteration `it`: refill the ghosts of the layer that
  // moved, recompute their heights, and revisit every cell that reads them.
  void next_round(int it) {
    const int nx = g_.nx, ny = g_.ny;
    round_ = m_.rounds.of(it, iterations_);
    const int e_last = e_;
    e_ = 2 * round_.length;
    refill_round(refill_, bedrock_, e_, e_last);
    if (e_ <= e_last) {
      heights(-e_, 0, -e_, nx + e_);
      heights(ny, ny + e_, -e_, nx + e_);
      heights(0, ny, -e_, 0);
      heights(0, ny, nx, nx + e_);
      for (int r = 0; r < rows_; ++r)
        for (int s = 0; s < segs_; ++s) {
          const int y = r - widest_, x0 = s * kSegment - widest_, x1 = x0 + kSegment;
          const bool near_edge = y < e_ + 2 || y >= ny - e_ - 2 || x0 < e_ + 2 || x1 > nx - e_ - 2;
          if (near_edge) visit_[static_cast<size_t>(r) * segs_ + s] = 1;
        }
    } else {
      // A wider round (the rest of the iterations in one, several tiles):
      // the other layer's ghosts too (refilled above), and every cell.
      heights(-e_, ny + e_, -e_, nx + e_);
      std::fill(visit_.begin(), visit_.end(), 1);
    }
  }

  // Columns [x0, x1) of segment s clipped to the tile grown by `grow`.
  std::pair<int, int> columns(int s, int grow) const {
    return {std::max(s * kSegment - widest_, -grow),
            std::min((s + 1) * kSegment - widest_, g_.nx + grow)};
  }

  // Pass 1: fractions where heights may have changed, or donors remain, on
  // the tile grown by `grow1`. Whether any f > 0.
  bool fractions(float kc, int grow1) {
    const int ny = g_.ny;
    const float tan_b = m_.tan_l_bedrock;
    bool any_positive = false;
#pragma omp parallel for num_threads(threads_) schedule(dynamic, 4) reduction(|| : any_positive)
    for (int r = 0; r < rows_; ++r) {
      const int y = r - widest_;
      for (int s = 0; s < segs_; ++s) {
        const size_t k = static_cast<size_t>(r) * segs_ + s;
        positive_[k] = 0;
        if (!visit_[k] || y < -grow1 || y >= ny + grow1) continue;
        const auto [x0, x1] = columns(s, grow1);
        if (x0 >= x1) continue;
        positive_[k] =
            bedrock_
                ? fraction_segment<true>(f_.h.row(y), nullptr, tan_b, nullptr, f_.obstacles.row(y),
                                         kc, st_, x0, x1, f_.frac.row(y))
                : fraction_segment<false>(f_.h.row(y), f_.tan_l.row(y), 0.0f, f_.sand.row(y),
                                          f_.obstacles.row(y), kc, st_, x0, x1, f_.frac.row(y));
        any_positive = any_positive || positive_[k];
      }
    }
    return any_positive;
  }

  // Pass 2: exchanges within one cell of a donor (it reads f only inside
  // this iteration's pass-1 region), on the tile grown by `grow2`. Whether
  // any unit moved.
  bool exchanges(int grow2) {
    const int ny = g_.ny;
    const float tan_b = m_.tan_l_bedrock;
    dilate(positive_, exchange_, rows_, segs_, 1);
    if (m_.avalanche_everywhere) std::fill(exchange_.begin(), exchange_.end(), 1);
    bool any_change = false;
#pragma omp parallel for num_threads(threads_) schedule(dynamic, 4) reduction(|| : any_change)
    for (int r = 0; r < rows_; ++r) {
      const int y = r - widest_;
      units_t gain[kSegment], loss[kSegment];
      for (int s = 0; s < segs_; ++s) {
        const size_t k = static_cast<size_t>(r) * segs_ + s;
        changed_[k] = 0;
        if (!exchange_[k] || y < -grow2 || y >= ny + grow2) continue;
        const auto [x0, x1] = columns(s, grow2);
        if (x0 >= x1) continue;
        const bool active = bedrock_
                                ? exchange_segment<true>(f_.h.row(y), nullptr, tan_b,
                                                         f_.frac.row(y), st_, x0, x1, gain, loss)
                                : exchange_segment<false>(f_.h.row(y), f_.tan_l.row(y), 0.0f,
                                                          f_.frac.row(y), st_, x0, x1, gain, loss);
        if (!active) continue;
        apply(y, x0, x1, gain, loss);
        changed_[k] = 1;
        any_change = true;
      }
    }
    return any_change;
  }

  // Pass 2 reads only heights and fractions, so the layers can be updated
  // in place.
  void apply(int y, int x0, int x1, const units_t* gain, const units_t* loss) {
    units_t* t = target_.row(y);
    units_t* sd = f_.sand.row(y);
    if (bedrock_ && m_.bedrock_to_sand) {
      // Fallen rock breaks into sand where it lands [N24 3.8].
      for (int x = x0; x < x1; ++x) {
        t[x] -= loss[x - x0];
        sd[x] += gain[x - x0];
      }
    } else {
      for (int x = x0; x < x1; ++x) t[x] += gain[x - x0] - loss[x - x0];
    }
  }

  bool larger_kc_later(int it, float kc) const {
    for (int j = it + 1; j <= iterations_; ++j)
      if (avalanching::kc_for(j, iterations_, m_.kc, m_.kc_damped) > kc) return true;
    return false;
  }

  // New heights where layers changed (after pass 2: it read the old ones).
  void new_heights(int grow2) {
#pragma omp parallel for num_threads(threads_) schedule(dynamic, 4)
    for (int r = 0; r < rows_; ++r) {
      const int y = r - widest_;
      for (int s = 0; s < segs_; ++s) {
        if (!changed_[static_cast<size_t>(r) * segs_ + s]) continue;
        const auto [x0, x1] = columns(s, grow2);
        height_row(y, x0, x1);
      }
    }
  }

  // Next pass 1: within two cells of a change, and wherever donors remain
  // (k_c may change their f).
  void next_visit() {
    dilate(changed_, visit_, rows_, segs_, 2);
    for (size_t k = 0; k < visit_.size(); ++k)
      visit_[k] |= positive_[k] | static_cast<std::uint8_t>(m_.avalanche_everywhere);
  }

  const Model& m_;
  const TileGeom& g_;
  const int threads_;
  dist::Exchange& ex_;    // tiles() and any()
  const Refill& refill_;  // the step's halo fill, between rounds
  const AvalancheLayers f_;
  const bool bedrock_;
  const int iterations_;
  const Stencil st_;
  const int widest_, rows_, segs_;
  std::vector<std::uint8_t> visit_, positive_, exchange_, changed_;
  Field<units_t>& target_;  // the layer that moves
  AvalancheRounds::Round round_;
  int e_ = 0;  // the round's ghost width: 2 R
};

}  // namespace

AvalancheResult CpuBackend::avalanche(bool bedrock, int iterations, const Refill& refill,
                                      bool* settled) {
  if (settled) *settled = false;
  if (iterations <= 0) return {};
  // h_a and f are the two halves of the work buffer that held the wind.
  wind_valid_ = false;
  const AvalancheLayers layers{f_.bedrock, f_.sand, f_.obstacles, f_.tan_l, h_a_, frac_};
  return AvalancheSweep(m_, g_, threads_, ex_, refill, layers, bedrock, iterations).run(settled);
}

AvalancheResult CpuBackend::avalanche_sand(const Refill& refill) {
  if (m_.avalanche_iterations <= 0) return {};
  repose_tangents();  // into storage the reptation strength held (cpu_backend.h)
  return avalanche(false, m_.avalanche_iterations, refill, nullptr);
}

// Bedrock only changes by abrasion and events. Once an avalanche found it
// settled on every tile (no cell exceeds the bedrock repose angle), running
// it again on the same bedrock is the identity, so it is skipped until
// bedrock changes somewhere.
void CpuBackend::avalanche_bedrock(const Refill& refill) {
  if (!ex_.any(bedrock_changed_)) return;
  bool settled = false;
  avalanche(true, m_.bedrock_iterations, refill, &settled);
  bedrock_changed_ = !settled;
}

}  // namespace erg::cpu

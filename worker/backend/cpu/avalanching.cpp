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
// Work is tracked cell by cell, in one 64-bit mask per 64-cell segment of a
// row. After the first iteration, which visits every cell, an iteration
// visits only the cells where something can happen: pass 1 within one cell
// of a cell whose layer changed in the last iteration (f reads the 3 x 3
// heights and the cell's own layer; an isotropic repose's tangent reads the
// same 3 x 3, and pass 2 reads each donor's where pass 1 kept it), where a donor
// still has f > 0 (k_c may change it) and next to ghosts a refill rewrote; pass 2 within one cell
// of a donor. Everywhere else the iteration is the identity, so the result is exactly that of
// visiting every cell, at a fraction of the cost once the terrain is mostly settled: a slip face
// still relaxing is a band a few cells wide, and a step that settles it runs hundreds of iterations
// on it. Each segment computes the run from its first to its last marked cell (a cell recomputed
// without need gets the same value again), so the passes keep their vectorised loops. Iterations
// stop once nothing moved and nothing can move later: on one tile at once, with several at the end
// of the round in which every tile has found so (results do not depend on it: the skipped
// iterations are identities).
#include "stages/avalanching.h"

#include <algorithm>
#include <bit>
#include <cstdint>
#include <limits>
#include <type_traits>
#include <utility>
#include <vector>

#include "backend/cpu/cpu_backend.h"
#include "stages/obstacles.h"

namespace erg::cpu {

namespace {

constexpr int kSegment = 64;
constexpr int kParallelSegments = 16;  // parallel(): about 1000 cells
// Cell masks: bit b of segment (r, s) is the cell of row r - E, column
// s * 64 + b - E (E: the widest ghost width, AvalancheSweep::widest_).
using Mask = std::uint64_t;
constexpr Mask kAll = ~Mask{0};

constexpr units_t kUnlimited = std::numeric_limits<units_t>::max() / 4;

struct Stencil {
  long o[8];  // storage offsets of the neighbours, kNeighbours order
  explicit Stencil(int pitch) {
    for (int k = 0; k < 8; ++k)
      o[k] = static_cast<long>(kNeighbours[k].dy) * pitch + kNeighbours[k].dx;
  }
};

// Pass 1 on cells [x0, x1) of a row segment whose first cell is column
// `base`. Returns the donors: the cells with f > 0 before the rare
// correction below (which may set a donor that is stuck at this k_c to 0; it
// stays marked, so it is visited again when k_c grows).
// kBedrock: unlimited supply and one repose tangent for all cells.
// kIsotropic: model.repose ISOTROPIC (a template parameter, so that [N24]'s
// neighbour pairs run the loops they ran before the option existed); each
// cell's tangent, which reads its 3 x 3 heights, is kept in tan_d for pass 2.
template <bool kBedrock, bool kIsotropic>
Mask fraction_segment(const float* h, const float* tan_l, float tan_l_const, const units_t* sand,
                      const float* ob, float kc, const Stencil& st, int base, int x0, int x1,
                      float* __restrict frac, float* __restrict tan_d) {
  const long o0 = st.o[0], o1 = st.o[1], o2 = st.o[2], o3 = st.o[3];
  const long o4 = st.o[4], o5 = st.o[5], o6 = st.o[6], o7 = st.o[7];
  int checks = 0;
  for (int x = x0; x < x1; ++x) {
    const float hn[8] = {h[x + o0], h[x + o1], h[x + o2], h[x + o3],
                         h[x + o4], h[x + o5], h[x + o6], h[x + o7]};
    const float t = avalanching::donor_tangent(kBedrock ? tan_l_const : tan_l[x], hn, kIsotropic);
    if constexpr (kIsotropic) tan_d[x] = t;
    const avalanching::Fraction fr =
        avalanching::fraction(h[x], hn, t, kBedrock ? kUnlimited : sand[x], kc);
    // An obstacle gives nothing (it is a wall, stages/obstacles.h).
    const bool wall = obstacles::is_obstacle(ob[x]);
    frac[x] = wall ? 0.0f : fr.f;
    checks += fr.check & !wall;
  }
  Mask donors = 0;
  for (int x = x0; x < x1; ++x) donors |= static_cast<Mask>(frac[x] > 0.0f) << (x - base);
  if (checks > 0) {
    // Rare: shares that might exceed the sand present; the complete donor()
    // shrinks f until they fit.
    for (int x = x0; x < x1; ++x) {
      const float hn[8] = {h[x + o0], h[x + o1], h[x + o2], h[x + o3],
                           h[x + o4], h[x + o5], h[x + o6], h[x + o7]};
      const float t = avalanching::donor_tangent(kBedrock ? tan_l_const : tan_l[x], hn, kIsotropic);
      const units_t avail = kBedrock ? kUnlimited : sand[x];
      if (avalanching::fraction(h[x], hn, t, avail, kc).check && !obstacles::is_obstacle(ob[x]))
        frac[x] = avalanching::donor(h[x], hn, t, avail, kc).f;
    }
  }
  return donors;
}

// Pass 2 on cells [x0, x1) of a row: units each cell gains and loses.
// Returns whether any cell sent or received anything.
template <bool kBedrock, bool kIsotropic>
bool exchange_segment(const float* h, const float* tan_l, float tan_l_const, const float* frac,
                      const float* tan_d, const Stencil& st, int x0, int x1,
                      units_t* __restrict gain, units_t* __restrict loss) {
  const long o0 = st.o[0], o1 = st.o[1], o2 = st.o[2], o3 = st.o[3];
  const long o4 = st.o[4], o5 = st.o[5], o6 = st.o[6], o7 = st.o[7];
  // The tangent of the donor at c, as pass 1 computed it (isotropic: kept
  // where pass 1 computed f, from the same heights, so it is current
  // wherever f is).
  auto tangent = [=](long c) {
    if constexpr (kIsotropic) return tan_d[c];
    return kBedrock ? tan_l_const : tan_l[c];
  };
  int active = 0;
  for (int x = x0; x < x1; ++x) {
    const float hx = h[x];
    // The donor is the neighbour; it saw this cell in the opposite
    // direction, at the same distance.
    auto in = [=](long o, float dist) {
      return avalanching::inflow(frac[x + o], h[x + o], hx, tangent(x + o), dist);
    };
    const units_t received = in(o0, 1.0f) + in(o1, kSqrt2) + in(o2, 1.0f) + in(o3, kSqrt2) +
                             in(o4, 1.0f) + in(o5, kSqrt2) + in(o6, 1.0f) + in(o7, kSqrt2);
    const float hn[8] = {h[x + o0], h[x + o1], h[x + o2], h[x + o3],
                         h[x + o4], h[x + o5], h[x + o6], h[x + o7]};
    const units_t sent = avalanching::outflow(frac[x], avalanching::excesses(hx, hn, tangent(x)));
    gain[x - x0] = received;
    loss[x - x0] = sent;
    active += (received | sent) != 0;
  }
  return active > 0;
}

// Calls run(std::bool_constant<iso>{}): a pass's loops compiled for the
// repose the job chose.
template <class Run>
decltype(auto) with_repose(bool iso, Run&& run) {
  return iso ? run(std::true_type{}) : run(std::false_type{});
}

// The cells of segment (r, s) within one cell (8-neighbourhood) of a marked
// cell of `m` (clipped at the region's edges: the region is a tile with its
// ghosts, not a torus).
Mask dilated(const std::vector<Mask>& m, int rows, int segs, int r, int s) {
  Mask row[3] = {0, 0, 0};  // columns s - 1, s, s + 1, over rows r - 1 .. r + 1
  for (int rr = std::max(0, r - 1); rr <= std::min(rows - 1, r + 1); ++rr) {
    const Mask* w = m.data() + static_cast<size_t>(rr) * segs;
    if (s > 0) row[0] |= w[s - 1];
    row[1] |= w[s];
    if (s + 1 < segs) row[2] |= w[s + 1];
  }
  return row[1] | (row[1] << 1) | (row[1] >> 1) | (row[0] >> 63) | (row[2] << 63);
}

// The bits of cells [x0, x1) of a segment whose first cell is column `base`.
Mask span_bits(int base, int x0, int x1) {
  const int lo = x0 - base, hi = x1 - base;  // 0 <= lo < hi <= 64
  const Mask upper = hi >= kSegment ? kAll : (Mask{1} << hi) - 1;
  return upper & ~((Mask{1} << lo) - 1);
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
  Field<float>& tan_d;        // each cell's donor tangent (ISOTROPIC only)
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
        visit_(static_cast<size_t>(rows_) * segs_, kAll),
        donors_(visit_.size(), 0),
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
        continue;  // the next pass 1 visits the donors again
      }
      ++moved_iterations;
      new_heights(grow2);
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
  // One tile whose cells within the ghost width of its edges have not
  // changed since the last refill skips it: the local copy would write the
  // values the ghosts hold.
  void next_round(int it) {
    const int nx = g_.nx, ny = g_.ny;
    round_ = m_.rounds.of(it, iterations_);
    const int e_last = e_;
    e_ = 2 * round_.length;
    const bool unchanged = ex_.tiles() == 1 && e_ == e_last && !edge_changed_;
    edge_changed_ = false;
    if (unchanged) return;
    refill_round(refill_, bedrock_, e_, e_last);
    if (e_ <= e_last) {
      heights(-e_, 0, -e_, nx + e_);
      heights(ny, ny + e_, -e_, nx + e_);
      heights(0, ny, -e_, 0);
      heights(0, ny, nx, nx + e_);
      // The refilled ghosts, and the owned cells that read them (within one
      // cell; two, to be generous).
      constexpr int kIn = 2;
      for (int r = 0; r < rows_; ++r) {
        const int y = r - widest_;
        const bool edge_row = y < kIn || y >= ny - kIn;
        for (int s = 0; s < segs_; ++s) {
          const Mask band = edge_row ? kAll : edge_columns(s, kIn);
          visit_[static_cast<size_t>(r) * segs_ + s] |= band;
          busy_ += band != 0;
        }
      }
    } else {
      // A wider round (the rest of the iterations in one, several tiles):
      // the other layer's ghosts too (refilled above), and every cell.
      heights(-e_, ny + e_, -e_, nx + e_);
      std::fill(visit_.begin(), visit_.end(), kAll);
      busy_ = static_cast<int>(visit_.size());
    }
  }

  // The cells of segment s in columns x < w or x >= nx - w.
  Mask edge_columns(int s, int w) const {
    const int base = s * kSegment - widest_;
    Mask m = 0;
    if (base < w) m |= span_bits(base, base, std::min(w, base + kSegment));
    if (base + kSegment > g_.nx - w)
      m |= span_bits(base, std::max(g_.nx - w, base), base + kSegment);
    return m;
  }

  // Whether a pass with `segments` segments of work runs on several
  // threads: a few hundred cells (most iterations of a long settle) take
  // less time than waking the threads.
  bool parallel(int segments) const {
    return threads_ > 1 && segments >= kParallelSegments;
  }

  // Columns [x0, x1) of segment s clipped to the tile grown by `grow`.
  std::pair<int, int> columns(int s, int grow) const {
    return {std::max(s * kSegment - widest_, -grow),
            std::min((s + 1) * kSegment - widest_, g_.nx + grow)};
  }

  // Calls run(x0, x1) on the columns from the first to the last cell of `m`
  // in segment s, clipped to the tile grown by `grow` (if any): one call
  // over the whole span, unmarked cells included, keeps the loops long
  // enough to vectorise (one call per run of marked cells was not faster).
  template <class Run>
  void for_span(Mask m, int s, int grow, Run&& run) const {
    const auto [c0, c1] = columns(s, grow);
    if (c0 >= c1) return;
    const int base = s * kSegment - widest_;
    m &= span_bits(base, c0, c1);
    if (m != 0) run(base + std::countr_zero(m), base + kSegment - std::countl_zero(m));
  }

  // Pass 1 on the tile grown by `grow1`, where f may differ from the last
  // time it was computed: within one cell of a cell whose layer changed in
  // the last pass 2 (f reads the 3 x 3 heights and its own layer), at the
  // donors of the last pass 1 (k_c may change their f), and at the cells
  // marked in visit_ (every cell at first, ghosts a refill rewrote), which
  // it clears. Whether any f > 0.
  bool fractions(float kc, int grow1) {
    const int ny = g_.ny;
    const float tan_b = m_.tan_l_bedrock;
    const bool iso = m_.repose_isotropic;
    bool any_positive = false;
    int donor_segments = 0;
#pragma omp parallel for num_threads(threads_) if (parallel(busy_)) schedule(dynamic, 4) \
    reduction(|| : any_positive) reduction(+ : donor_segments)
    for (int r = 0; r < rows_; ++r) {
      const int y = r - widest_;
      for (int s = 0; s < segs_; ++s) {
        const size_t k = static_cast<size_t>(r) * segs_ + s;
        const Mask visit = m_.avalanche_everywhere
                               ? kAll
                               : visit_[k] | donors_[k] | dilated(changed_, rows_, segs_, r, s);
        visit_[k] = 0;
        donors_[k] = 0;
        if (!visit || y < -grow1 || y >= ny + grow1) continue;
        const int base = s * kSegment - widest_;
        Mask donors = 0;
        for_span(visit, s, grow1, [&](int x0, int x1) {
          donors |= with_repose(iso, [&](auto is) {
            constexpr bool kIso = decltype(is)::value;
            float* tan_d = kIso ? f_.tan_d.row(y) : nullptr;
            return bedrock_
                       ? fraction_segment<true, kIso>(f_.h.row(y), nullptr, tan_b, nullptr,
                                                      f_.obstacles.row(y), kc, st_, base, x0, x1,
                                                      f_.frac.row(y), tan_d)
                       : fraction_segment<false, kIso>(f_.h.row(y), f_.tan_l.row(y), 0.0f,
                                                       f_.sand.row(y), f_.obstacles.row(y), kc, st_,
                                                       base, x0, x1, f_.frac.row(y), tan_d);
          });
        });
        donors_[k] = donors;
        any_positive = any_positive || donors != 0;
        donor_segments += donors != 0;
      }
    }
    donor_segments_ = donor_segments;
    busy_ = m_.avalanche_everywhere ? static_cast<int>(visit_.size()) : 0;
    return any_positive;
  }

  // Pass 2: exchanges within one cell of a donor (it reads f only inside
  // this iteration's pass-1 region), on the tile grown by `grow2`. Whether
  // any unit moved.
  bool exchanges(int grow2) {
    const int ny = g_.ny;
    const float tan_b = m_.tan_l_bedrock;
    const bool iso = m_.repose_isotropic;
    bool any_change = false, edge_change = false;
    int changed_segments = 0;
    const int fill = e_ + 1;  // refill_round fills the ghosts e + 1 wide
#pragma omp parallel for num_threads(threads_) if (parallel(3 * donor_segments_)) \
    schedule(dynamic, 4) reduction(|| : any_change, edge_change) reduction(+ : changed_segments)
    for (int r = 0; r < rows_; ++r) {
      const int y = r - widest_;
      units_t gain[kSegment], loss[kSegment];
      for (int s = 0; s < segs_; ++s) {
        const size_t k = static_cast<size_t>(r) * segs_ + s;
        changed_[k] = 0;
        if (y < -grow2 || y >= ny + grow2) continue;
        const Mask near_donor =
            m_.avalanche_everywhere ? kAll : dilated(donors_, rows_, segs_, r, s);
        const int base = s * kSegment - widest_;
        Mask changed = 0;
        for_span(near_donor, s, grow2, [&](int x0, int x1) {
          const bool active = with_repose(iso, [&](auto is) {
            constexpr bool kIso = decltype(is)::value;
            const float* tan_d = kIso ? f_.tan_d.row(y) : nullptr;
            return bedrock_
                       ? exchange_segment<true, kIso>(f_.h.row(y), nullptr, tan_b, f_.frac.row(y),
                                                      tan_d, st_, x0, x1, gain, loss)
                       : exchange_segment<false, kIso>(f_.h.row(y), f_.tan_l.row(y), 0.0f,
                                                       f_.frac.row(y), tan_d, st_, x0, x1, gain,
                                                       loss);
          });
          if (!active) return;
          changed |= apply(y, x0, x1, base, gain, loss);
          any_change = true;
        });
        changed_[k] = changed;
        if (changed == 0) continue;
        ++changed_segments;
        // A change within the refilled width of an edge, which a one-tile
        // refill copies into the ghosts.
        edge_change =
            edge_change || y < fill || y >= ny - fill || (changed & edge_columns(s, fill)) != 0;
      }
    }
    changed_segments_ = changed_segments;
    edge_changed_ = edge_changed_ || edge_change;
    // The next pass 1 visits within one cell of the changes and the donors.
    busy_ += 3 * changed_segments + donor_segments_;
    return any_change;
  }

  // Pass 2 reads only heights and fractions, so the layers can be updated
  // in place. Returns the cells whose avalanching height changed (segment
  // whose first cell is column `base`).
  Mask apply(int y, int x0, int x1, int base, const units_t* gain, const units_t* loss) {
    units_t* t = target_.row(y);
    units_t* sd = f_.sand.row(y);
    Mask changed = 0;
    if (bedrock_ && m_.bedrock_to_sand) {
      // Fallen rock breaks into sand where it lands [N24 3.8].
      for (int x = x0; x < x1; ++x) {
        t[x] -= loss[x - x0];
        sd[x] += gain[x - x0];
        changed |= static_cast<Mask>(loss[x - x0] != 0) << (x - base);
      }
    } else {
      for (int x = x0; x < x1; ++x) {
        t[x] += gain[x - x0] - loss[x - x0];
        changed |= static_cast<Mask>(gain[x - x0] != loss[x - x0]) << (x - base);
      }
    }
    return changed;
  }

  bool larger_kc_later(int it, float kc) const {
    for (int j = it + 1; j <= iterations_; ++j)
      if (avalanching::kc_for(j, iterations_, m_.kc, m_.kc_damped) > kc) return true;
    return false;
  }

  // New heights where layers changed (after pass 2: it read the old ones).
  void new_heights(int grow2) {
#pragma omp parallel for num_threads(threads_) if (parallel(changed_segments_)) schedule(dynamic, 4)
    for (int r = 0; r < rows_; ++r) {
      const int y = r - widest_;
      for (int s = 0; s < segs_; ++s) {
        const Mask c = changed_[static_cast<size_t>(r) * segs_ + s];
        if (c == 0) continue;
        for_span(c, s, grow2, [&](int x0, int x1) { height_row(y, x0, x1); });
      }
    }
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
  std::vector<Mask> visit_, donors_, changed_;
  Field<units_t>& target_;  // the layer that moves
  AvalancheRounds::Round round_;
  int e_ = 0;  // the round's ghost width: 2 R
  // Segments with work, counted by the last passes, for parallel(): those
  // the next pass 1 visits (every one at first), the last donors and changes.
  int busy_ = std::numeric_limits<int>::max(), donor_segments_ = 0, changed_segments_ = 0;
  bool edge_changed_ = false;  // a change near an edge since the last refill
};

}  // namespace

AvalancheResult CpuBackend::avalanche(bool bedrock, int iterations, const Refill& refill,
                                      bool* settled) {
  if (settled) *settled = false;
  if (iterations <= 0) return {};
  // h_a and f are the two halves of the work buffer that held the wind.
  wind_valid_ = false;
  const AvalancheLayers layers{f_.bedrock, f_.sand, f_.obstacles, f_.tan_l, h_a_, frac_, tan_d_};
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

// SPDX-License-Identifier: Apache-2.0
// Two runs of one job, compared at the end of every stage of every step
// (Simulation::set_stage_observer): on two backends (CPU against CUDA,
// tests/gpu) or two configurations of one (thread counts, tests/sim).
//
// Run a is the reference. During each of its steps, every stage's result is
// kept: the exact state (integer units exactly, float state by bits) and
// every derived field at the owned cells. Run b then takes the same step and
// is compared at the same stage boundaries. A field the caller bounds (its
// two sides use different operations, e.g. FFTs that sum in different
// orders) may differ by at most its bound; b then takes a's values, so that
// the next stage gets the same inputs on both sides and each stage is judged
// on its own. Any other difference fails, naming the step, the stage, the
// field, the first cell that differs and how many do.
#pragma once

#include <gtest/gtest.h>

#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <string>
#include <type_traits>
#include <vector>

#include "core/fields.h"
#include "sim/simulation.h"

namespace erg::test_support {

// A float field that may differ between the two runs, by at most max_abs
// (in its unit), and why.
struct FieldBound {
  fields::Id id;
  double max_abs;
  const char* why;
};

// What one run's stage left, at the owned cells.
struct StageResult {
  TileState state;
  std::array<std::vector<float>, fields::kCount> derived;  // empty for state fields
};

inline StageResult stage_result(Simulation& sim) {
  StageResult r;
  r.state = sim.state();
  for (int i = 0; i < fields::kCount; ++i) {
    const auto id = static_cast<fields::Id>(i);
    // A field whose storage the next stage that reads it writes over
    // (fields::Storage::kReplaced: landed, reptation) holds its values only
    // within its lifetime, and is judged by the field written over it.
    if (!fields::info(id).state && fields::info(id).storage != fields::Storage::kReplaced)
      sim.backend().download_owned(id, r.derived[i]);
  }
  return r;
}

// The largest differences of each bounded field, over the whole comparison.
struct Agreement {
  std::array<double, fields::kCount> max_abs{};
  int stages_compared = 0;
  long long avalanche_iterations = 0;  // run b's iterations that moved sand: work was compared
};

namespace detail {

inline std::string where(std::int64_t step, Stage stage, fields::Id id) {
  return "step " + std::to_string(step) + ", after " + kStageNames[stage] + ", field " +
         fields::info(id).name;
}

// Compares bits; returns the number of cells that differ and, in *first, the
// first one (row-major index), *max_abs the largest |a - b| (NaN: infinite).
template <class T>
long differing(const T* a, const T* b, std::size_t n, std::size_t* first, double* max_abs) {
  long count = 0;
  for (std::size_t i = 0; i < n; ++i) {
    bool same;
    if constexpr (std::is_same_v<T, float>)
      same = std::bit_cast<std::uint32_t>(a[i]) == std::bit_cast<std::uint32_t>(b[i]);
    else
      same = a[i] == b[i];
    if (same) continue;
    if (count++ == 0) *first = i;
    const double d = std::fabs(static_cast<double>(a[i]) - static_cast<double>(b[i]));
    *max_abs = std::isnan(d) ? INFINITY : std::fmax(*max_abs, d);
  }
  return count;
}

}  // namespace detail

// The first difference of `got` from `want` that the bounds do not allow,
// described; empty when none. Bounded fields that differ (within bound) are
// listed in *adopt, their largest differences kept in *agreement.
inline std::string stage_mismatch(const StageResult& want, const StageResult& got,
                                  const std::vector<FieldBound>& bounds, std::int64_t step, Stage s,
                                  Agreement* agreement, std::vector<fields::Id>* adopt) {
  for (int i = 0; i < fields::kCount; ++i) {
    const auto id = static_cast<fields::Id>(i);
    const fields::Info& f = fields::info(id);
    std::size_t first = 0, cells = 0;
    double max_abs = 0;
    long count = 0;
    const auto compare = [&](const auto& x, const auto& y) {
      cells = x.size();
      count = detail::differing(x.data(), y.data(), cells, &first, &max_abs);
    };
    // Between the wind and shadow stages the shadow is not defined on the
    // CPU backend (its storage is shared, fields::Storage): 0 there.
    if (id == fields::kShadow && s == kWind) continue;
    if (f.state && f.type == fields::Type::kUnits) {
      compare(owned_cells(want.state.units[id]), owned_cells(got.state.units[id]));
      max_abs = units_to_m_d(static_cast<units_t>(max_abs));
    } else if (f.state) {
      compare(owned_cells(want.state.reals[id]), owned_cells(got.state.reals[id]));
    } else {
      compare(want.derived[i], got.derived[i]);
    }
    if (count == 0) continue;
    const FieldBound* bound = nullptr;
    for (const FieldBound& fb : bounds)
      if (fb.id == id) bound = &fb;
    if (bound == nullptr || f.state || max_abs > bound->max_abs) {
      const int nx = want.state.geom.nx;
      return detail::where(step, s, id) + ": " + std::to_string(count) + " of " +
             std::to_string(cells) + " cells differ, the first at (" + std::to_string(first % nx) +
             ", " + std::to_string(first / nx) + "), by up to " + std::to_string(max_abs) +
             (bound ? " (bound " + std::to_string(bound->max_abs) + ": " + bound->why + ")"
                    : std::string(" (no difference allowed)"));
    }
    agreement->max_abs[i] = std::fmax(agreement->max_abs[i], max_abs);
    adopt->push_back(id);
  }
  return {};
}

// Runs `steps` steps of job a with options a and of job b with options b
// (usually the same job), comparing them stage by stage (see the top of
// this file). Returns the first mismatch (empty: none) and, in *agreement,
// the bounded fields' largest differences.
inline std::string first_stage_mismatch(const erg::v1::JobSpec& spec_a, const RunOptions& a,
                                        const erg::v1::JobSpec& spec_b, const RunOptions& b,
                                        int steps, const std::vector<FieldBound>& bounds,
                                        Agreement* agreement) {
  Simulation sa(spec_a, ".", a), sb(spec_b, ".", b);
  std::array<StageResult, kStageCount> ref;
  sa.set_stage_observer([&](Stage s) { ref[s] = stage_result(sa); });
  std::string mismatch;
  sb.set_stage_observer([&](Stage s) {
    if (!mismatch.empty()) return;
    ++agreement->stages_compared;
    std::vector<fields::Id> adopt;
    mismatch =
        stage_mismatch(ref[s], stage_result(sb), bounds, sb.step_index(), s, agreement, &adopt);
    for (const fields::Id id : adopt)
      sb.backend().upload_owned(id, ref[s].derived[id]);  // the next stage: a's inputs
  });
  for (int k = 0; k < steps && mismatch.empty(); ++k) {
    sa.step();
    sb.step();
  }
  agreement->avalanche_iterations = sb.times().avalanche_iterations;
  return mismatch;
}

// The same job on options a and b: every stage of every step agrees (within
// the bounds). Returns the bounded fields' largest differences.
inline Agreement expect_stages_agree(const erg::v1::JobSpec& spec, const RunOptions& a,
                                     const RunOptions& b, int steps,
                                     const std::vector<FieldBound>& bounds = {}) {
  Agreement agreement;
  const std::string mismatch = first_stage_mismatch(spec, a, spec, b, steps, bounds, &agreement);
  EXPECT_EQ(mismatch, "");
  if (mismatch.empty()) {
    EXPECT_EQ(agreement.stages_compared, steps * kStageCount);
  }
  return agreement;
}

}  // namespace erg::test_support

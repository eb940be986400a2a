// SPDX-License-Identifier: Apache-2.0
// The steps/s and ETA of progress events.
//
// A run's time is its steps plus the files it writes. The two are measured
// apart, because they scale apart: a snapshot of a continent-scale domain
// can take minutes while its steps take seconds, and the files a run still
// owes are known exactly from its cadence (run.snapshot_every,
// run.checkpoint_every, and both after the last step).
//
// Steps: a run's rate changes. The first steps pay for setup and for the
// avalanching of the initial layers. The mean since the start carries those
// costs for the whole run (an ETA of hours in the first seconds of a
// one-minute job), so the rate here is measured over a moving window of the
// most recent steps' compute time (the files' time taken out): the last
// max(kMinWindowS, kWindowFraction x elapsed) seconds, long enough to average
// out noise, short enough to forget the start. The first step is never in
// the window.
//
// Files: each kind costs what its latest write took (OutputCosts). A new run
// writes a snapshot before its first step, and a checkpoint too when it has a
// checkpoint cadence, so those costs are known from the start. A run without
// one writes its only checkpoint after the last step; until then it is not
// counted (it is the cheaper file, with no overview and no preview: 0.07 s
// against a snapshot's 0.3 s for 512^2 cells here), and a resumed run counts
// each kind from its first write on.
#pragma once

#include <algorithm>
#include <cstdint>
#include <deque>

namespace erg::sim {

class MovingRate {
 public:
  static constexpr double kMinWindowS = 3.0;
  static constexpr double kWindowFraction = 0.3;

  // One sample per step: `t` seconds of stepping since the run (or resume)
  // started, `step` the steps done by then.
  void add(double t, std::int64_t step) {
    samples_.push_back({t, step});
    const double window = std::max(kMinWindowS, kWindowFraction * t);
    // Keep the oldest sample at or before the window's start, so that the
    // window is covered whole.
    while (samples_.size() > 2 && samples_[1].t <= t - window) samples_.pop_front();
  }

  // Steps per second over the window; 0 before two samples.
  double steps_per_s() const {
    if (samples_.size() < 2) return 0;
    const Sample& a = samples_.front();
    const Sample& b = samples_.back();
    return b.t > a.t ? static_cast<double>(b.step - a.step) / (b.t - a.t) : 0;
  }

  // Seconds of stepping to reach `last_step` at the window's rate; -1 while
  // unknown.
  double eta_s(std::int64_t last_step) const {
    const double r = steps_per_s();
    if (r <= 0) return -1;
    return static_cast<double>(last_step - samples_.back().step) / r;
  }

 private:
  struct Sample {
    double t;
    std::int64_t step;
  };
  std::deque<Sample> samples_;
};

// Whether a run ending at step `last` writes a file of cadence `every`
// after step s: at every multiple of `every` (none when `every` <= 0), and
// both kinds after the last step. The runner writes by it; files_due counts
// it.
inline bool file_due(std::int64_t s, std::int64_t last, std::int64_t every) {
  return s == last || (every > 0 && s % every == 0);
}

// How many steps in (after, last] file_due holds for: the multiples of
// `every` there, plus `last` itself when it is not one; `every` <= 0: `last`
// alone. 0 when after >= last.
inline std::int64_t files_due(std::int64_t after, std::int64_t last, std::int64_t every) {
  if (after >= last) return 0;
  if (every <= 0) return 1;
  const std::int64_t multiples = last / every - after / every;
  return multiples + (last % every != 0 ? 1 : 0);
}

// What the latest snapshot and checkpoint took to write, and so what the
// files a run still owes will take.
class OutputCosts {
 public:
  void snapshot_took(double s) { snapshot_s_ = s; }
  void checkpoint_took(double s) { checkpoint_s_ = s; }

  // Seconds to write the files due after step `after` up to `last`.
  double due_s(std::int64_t after, std::int64_t last, std::int64_t snapshot_every,
               std::int64_t checkpoint_every) const {
    return static_cast<double>(files_due(after, last, snapshot_every)) * snapshot_s_ +
           static_cast<double>(files_due(after, last, checkpoint_every)) * checkpoint_s_;
  }

 private:
  double snapshot_s_ = 0;  // 0 until written in this process
  double checkpoint_s_ = 0;
};

}  // namespace erg::sim

// SPDX-License-Identifier: Apache-2.0
// The steps/s and ETA of progress events. A run's rate changes: the first
// steps pay for setup and for the avalanching of the initial layers, and
// snapshots and checkpoints stall a step now and then. The mean since the
// start carries those costs for the whole run (an ETA of hours in the first
// seconds of a one-minute job), so the rate here is measured over a moving
// window of the most recent steps: the last max(kMinWindowS, kWindowFraction
// x elapsed) seconds, long enough to average over the stalls of snapshots,
// short enough to forget the start. The first step is never in the window.
#pragma once

#include <algorithm>
#include <cstdint>
#include <deque>

namespace erg::sim {

class MovingRate {
 public:
  static constexpr double kMinWindowS = 3.0;
  static constexpr double kWindowFraction = 0.3;

  // One sample per step: `t` seconds since the run (or resume) started,
  // `step` the steps done by then.
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

  // Seconds to reach `last_step` at the window's rate; -1 while unknown.
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

}  // namespace erg::sim

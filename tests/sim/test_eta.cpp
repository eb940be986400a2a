// SPDX-License-Identifier: Apache-2.0
// The ETA's parts (sim/moving_rate.h): the files a run still owes, counted
// from its cadence, and what they cost. The whole ETA on a real run is
// tests/e2e/test_eta.py.
#include <gtest/gtest.h>

#include "sim/moving_rate.h"

namespace erg::sim {
namespace {

TEST(FilesDue, CountsTheCadenceAndTheEnd) {
  // Every 100 steps up to 1000: 200, ..., 1000 after step 150; 1000 is both.
  EXPECT_EQ(files_due(150, 1000, 100), 9);
  // The end is not a multiple: 300, 400, and 450 itself.
  EXPECT_EQ(files_due(250, 450, 100), 3);
  // A file just written is not due again.
  EXPECT_EQ(files_due(200, 450, 100), 3);
  EXPECT_EQ(files_due(199, 450, 100), 4);
  // No cadence: the end alone.
  EXPECT_EQ(files_due(0, 450, 0), 1);
  EXPECT_EQ(files_due(449, 450, -1), 1);
  // At the end, nothing is due.
  EXPECT_EQ(files_due(450, 450, 100), 0);
  EXPECT_EQ(files_due(450, 450, 0), 0);
}

TEST(FilesDue, CountsTheStepsTheRunnerWritesAt) {
  // The count is the runner's predicate summed, for any cadence and start.
  for (std::int64_t every : {-1, 0, 1, 7, 100, 450, 1000})
    for (std::int64_t after : {0, 1, 99, 100, 101, 449, 450}) {
      std::int64_t n = 0;
      for (std::int64_t s = after + 1; s <= 450; ++s) n += file_due(s, 450, every) ? 1 : 0;
      EXPECT_EQ(files_due(after, 450, every), n) << "every " << every << ", after " << after;
    }
}

TEST(OutputCosts, FilesDueAtTheirLatestCost) {
  OutputCosts c;
  EXPECT_EQ(c.due_s(0, 1000, 100, 0), 0.0) << "nothing timed yet";
  c.snapshot_took(2.0);
  // 10 snapshots; the end's checkpoint, not yet timed, is not counted.
  EXPECT_DOUBLE_EQ(c.due_s(0, 1000, 100, 0), 10 * 2.0);
  c.checkpoint_took(0.5);
  EXPECT_DOUBLE_EQ(c.due_s(0, 1000, 100, 0), 10 * 2.0 + 0.5);
  c.snapshot_took(3.0);  // the latest write counts
  EXPECT_DOUBLE_EQ(c.due_s(950, 1000, 100, 250), 3.0 + 0.5);
  EXPECT_EQ(c.due_s(1000, 1000, 100, 250), 0.0);
}

TEST(MovingRate, ForgetsASlowStart) {
  MovingRate r;
  EXPECT_EQ(r.eta_s(100), -1) << "no rate before two samples";
  // A slow first second (setup), then 10 steps/s of stepping.
  r.add(1.0, 1);
  for (int s = 2; s <= 100; ++s) r.add(1.0 + 0.1 * (s - 1), s);
  EXPECT_NEAR(r.steps_per_s(), 10.0, 1e-9);
  EXPECT_NEAR(r.eta_s(200), 10.0, 1e-9);
}

}  // namespace
}  // namespace erg::sim

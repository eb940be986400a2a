// SPDX-License-Identifier: Apache-2.0
// device_for_rank(): every rank of a node on its own device while there are
// enough, evenly shared when there are not, and a clear error without any.
#include <gtest/gtest.h>

#include <stdexcept>
#include <vector>

#include "backend/device_choice.h"

namespace erg {
namespace {

TEST(DeviceChoice, RanksOfANodeTakeTheDevicesInTurn) {
  // 4 ranks on a 4-GPU node: one device each, rank r on device r.
  for (int r = 0; r < 4; ++r) EXPECT_EQ(device_for_rank(r, 4), r);
  // 8 ranks on 4 GPUs: each device serves exactly two ranks.
  std::vector<int> users(4, 0);
  for (int r = 0; r < 8; ++r) ++users.at(static_cast<std::size_t>(device_for_rank(r, 4)));
  for (int u : users) EXPECT_EQ(u, 2);
  // 3 ranks on 8 GPUs: no two ranks share a device.
  EXPECT_EQ(device_for_rank(0, 8), 0);
  EXPECT_EQ(device_for_rank(1, 8), 1);
  EXPECT_EQ(device_for_rank(2, 8), 2);
}

TEST(DeviceChoice, OneVisibleDevicePerTaskIsTaken) {
  // A launcher that binds one GPU per task shows each process one device.
  for (int r = 0; r < 5; ++r) EXPECT_EQ(device_for_rank(r, 1), 0);
}

TEST(DeviceChoice, NoDeviceOrANegativeRankIsAnError) {
  EXPECT_THROW(device_for_rank(0, 0), std::invalid_argument);
  EXPECT_THROW(device_for_rank(1, -1), std::invalid_argument);
  EXPECT_THROW(device_for_rank(-1, 2), std::invalid_argument);
  try {
    device_for_rank(0, 0);
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("no CUDA device"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace erg

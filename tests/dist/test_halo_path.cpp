// SPDX-License-Identifier: Apache-2.0
// The rules a device backend follows for its halos (dist/halo_path.h),
// without a device or MPI: which path it takes, what each ghost operation
// does when on the host-staged path (so that the copies overlap only work
// that cannot see them), where several fields' frames lie in one staging
// buffer, and the bytes counted as staged. test_halo.cpp runs the same
// steps through real exchanges under mpirun.
#include <gtest/gtest.h>

#include <cstddef>
#include <cstdint>
#include <set>
#include <string>
#include <vector>

#include "dist/halo_path.h"

namespace erg::dist {
namespace {

TEST(HaloPath, DeviceBuffersGoToMpiOnlyWhenBuiltAndReportedAtRunTime) {
  for (const bool built : {false, true})
    for (const bool runtime : {false, true})
      for (const bool allowed : {false, true}) {
        const MpiCudaSupport s{built, runtime, allowed};
        const std::string at =
            std::to_string(built) + std::to_string(runtime) + std::to_string(allowed);
        // Host fields: the exchange packs them, whatever MPI can do.
        EXPECT_EQ(choose_halo_path(false, 1, s), HaloPath::kHost) << at;
        EXPECT_EQ(choose_halo_path(false, 4, s), HaloPath::kHost) << at;
        // One tile: the periodic wrap on the device, no message.
        EXPECT_EQ(choose_halo_path(true, 1, s), HaloPath::kDevice) << at;
        const HaloPath several = choose_halo_path(true, 2, s);
        EXPECT_EQ(several,
                  built && runtime && allowed ? HaloPath::kDeviceDirect : HaloPath::kHostStaged)
            << at;
        EXPECT_EQ(choose_halo_path(true, 64, s), several) << at;
      }
  // A library built CUDA-aware that says no at run time (no GPU support
  // loaded, e.g. UCX without CUDA) is staged.
  EXPECT_EQ(choose_halo_path(true, 2, {true, false, true}), HaloPath::kHostStaged);
  EXPECT_EQ(choose_halo_path(true, 2, {}), HaloPath::kHostStaged);
}

TEST(HaloPath, NamesAreDistinct) {
  std::set<std::string> names;
  for (const HaloPath p :
       {HaloPath::kHost, HaloPath::kDevice, HaloPath::kHostStaged, HaloPath::kDeviceDirect})
    EXPECT_TRUE(names.insert(halo_path_name(p)).second) << halo_path_name(p);
  EXPECT_EQ(std::string(halo_path_name(HaloPath::kHostStaged)), "host-staged");
  EXPECT_EQ(std::string(halo_path_name(HaloPath::kDeviceDirect)), "cuda-aware-mpi");
}

TEST(StagingSteps, EveryOperationDownloadsExchangesAndUploadsOnce) {
  for (const GhostOp op : {GhostOp::kFill, GhostOp::kSum}) {
    const StagingSteps s = staging_steps(op);
    EXPECT_TRUE(s.download && s.exchange && s.upload);
    EXPECT_EQ(s.exchange_op, op);
  }
  // A split fill: the two halves together are one fill, the download in
  // the first (so that its copy overlaps the work in between) and the
  // exchange and the upload in the second.
  const StagingSteps begin = staging_steps(GhostOp::kBeginFill);
  const StagingSteps finish = staging_steps(GhostOp::kFinishFill);
  EXPECT_TRUE(begin.download);
  EXPECT_FALSE(begin.exchange);
  EXPECT_FALSE(begin.upload);
  EXPECT_FALSE(finish.download);
  EXPECT_TRUE(finish.exchange);
  EXPECT_EQ(finish.exchange_op, GhostOp::kFill);
  EXPECT_TRUE(finish.upload);
}

TEST(StagingSteps, OnlyFillsUploadGhostsAlone) {
  // A fill changes no owned cell: its upload writes the ghosts only, so it
  // may overlap kernels that read or write owned cells. A sum adds into the
  // owned cells within the width (and zeroes the ghosts): the whole frame.
  EXPECT_TRUE(staging_steps(GhostOp::kFill).ghosts_only);
  EXPECT_TRUE(staging_steps(GhostOp::kFinishFill).ghosts_only);
  EXPECT_FALSE(staging_steps(GhostOp::kSum).ghosts_only);
}

TEST(FrameLayout, FramesLieApartAlignedAndCountTheirBytes) {
  const TileGeom g = make_single_tile(40, 24, 12, 1.0f);
  const std::vector<int> widths = {12, 10, 9, 0, 30};  // 30: clipped to the halo
  const std::vector<std::size_t> elems = {4, 8, 8, 4, 4};
  const FrameLayout l = frame_layout(g, widths, elems);
  ASSERT_EQ(l.slots.size(), widths.size());
  std::size_t payload = 0, end = 0;
  for (std::size_t i = 0; i < l.slots.size(); ++i) {
    const FrameSlot& s = l.slots[i];
    const int w = widths[i] < g.halo ? widths[i] : g.halo;
    EXPECT_EQ(s.frame.w, w) << i;
    EXPECT_EQ(s.frame.nx, g.nx);
    EXPECT_EQ(s.frame.ny, g.ny);
    EXPECT_EQ(s.bytes, s.frame.size() * elems[i]) << i;
    EXPECT_EQ(s.offset % kFrameAlign, 0u) << i;
    EXPECT_GE(s.offset, end) << i << ": overlaps the slot before";
    end = s.offset + s.bytes;
    payload += s.bytes;
  }
  EXPECT_EQ(l.slots[3].bytes, 0u);  // width 0: no frame
  EXPECT_EQ(l.payload, payload);
  EXPECT_GE(l.bytes, end);
  EXPECT_LT(l.bytes, end + kFrameAlign);
  EXPECT_EQ(l.bytes % kFrameAlign, 0u);
}

TEST(FrameLayout, StagedBytesAreTheFramesOncePerDirection) {
  const TileGeom g = make_single_tile(64, 32, 12, 1.0f);
  const std::vector<int> widths = {9, 9};
  const std::vector<std::size_t> elems = {sizeof(std::int64_t), sizeof(float)};
  const FrameLayout l = frame_layout(g, widths, elems);
  const long long frame = static_cast<long long>(l.payload);
  EXPECT_EQ(staged_bytes(staging_steps(GhostOp::kFill), l), 2 * frame);
  EXPECT_EQ(staged_bytes(staging_steps(GhostOp::kSum), l), 2 * frame);
  EXPECT_EQ(staged_bytes(staging_steps(GhostOp::kBeginFill), l) +
                staged_bytes(staging_steps(GhostOp::kFinishFill), l),
            2 * frame);
  // The alignment padding is not staged data.
  EXPECT_LE(frame, static_cast<long long>(l.bytes));
  // The frame of an exchange of width w: the ghost ring and the owned ring
  // within w, never the tile's middle.
  const long long ring = (64 + 18) * (32 + 18) - (64 - 18) * (32 - 18);
  EXPECT_EQ(frame, ring * 12);
}

}  // namespace
}  // namespace erg::dist

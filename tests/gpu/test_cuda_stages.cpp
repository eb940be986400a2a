// SPDX-License-Identifier: Apache-2.0
// Stage by stage, the CUDA backend against the CPU backend (label gpu: it
// needs a device; CI, which has none, excludes the label by name in its
// preset). Both backends take the same job (tests/common/stage_scene.h:
// every stage has work: events of each kind, wind primitives, shadow,
// saltation with abrasion, reptation, sand and bedrock avalanching) and are
// compared after every stage of every step (tests/common/stage_agreement.h):
// - integer units (sand, airborne sand, bedrock) exactly;
// - float fields by bits, since both run the same stages/ code with the same
//   operations in the same order (no fused multiply-add on either side:
//   CMakeLists.txt), the wind's coarse smoothing included (truncated
//   Gaussians summed tap by tap in one order: stages/wind_warping.h).
// Where a stage differs, the failure names the step, the stage, the field
// and the first cell. One place may: the vortex's profile calls the double
// exp() of each side's math library (stages/wind_primitives.h), which need
// not round its last bit alike; no GPU has run this yet to say.
// The harness is proven on the CPU in CI (tests/sim/test_stage_agreement.cpp).
#include <gtest/gtest.h>

#include <string>

#include "../common/stage_agreement.h"
#include "../common/stage_scene.h"
#include "job/spec.h"

namespace erg {
namespace {

// "EXPECTED" or "STOCHASTIC", either with "+deflected" (the hop turned down
// the slope: test_support::deflected_stage_scene).
erg::v1::JobSpec scene(const std::string& param) {
  const auto [transport, variant] = test_support::split_scene_name(param);
  erg::v1::JobSpec spec =
      job::parse_json(variant == "deflected" ? test_support::deflected_stage_scene(transport)
                                             : test_support::stage_scene(transport),
                      "stage scene");
  job::apply_defaults(spec);
  for (const auto& p : job::validate(spec)) ADD_FAILURE() << p;
  return spec;
}

RunOptions on(BackendKind kind) {
  RunOptions o;
  o.backend = kind;
  o.threads = 2;
  return o;
}

class CudaStages : public ::testing::TestWithParam<std::string> {};

TEST_P(CudaStages, EveryStageGivesTheCpuBits) {
  ASSERT_TRUE(cuda_device_available()) << "this test needs a CUDA device";
  test_support::expect_stages_agree(scene(GetParam()), on(BackendKind::kCpu),
                                    on(BackendKind::kCuda), 4);
}

INSTANTIATE_TEST_SUITE_P(Transport, CudaStages,
                         ::testing::Values("EXPECTED", "STOCHASTIC", "EXPECTED+deflected",
                                           "STOCHASTIC+deflected"),
                         [](const auto& info) {
                           return test_support::scene_test_name(info.param);
                         });

}  // namespace
}  // namespace erg

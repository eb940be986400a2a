// SPDX-License-Identifier: Apache-2.0
// Stage by stage, the CPU backend gives the same bits
// - on 1 and 2 threads (no stage depends on how its rows are shared out);
// - with and without its avalanching fast path (the active segments against
//   visiting every cell, RunOptions::avalanche_everywhere),
// in both transport modes (and with the isotropic options), on a scene where
// every stage has work
// (tests/common/stage_scene.h). The comparison is the one the CUDA backend
// is held to against the CPU (tests/gpu/test_cuda_stages.cpp), here with no
// difference allowed anywhere.
#include <gtest/gtest.h>

#include <string>

#include "../common/stage_agreement.h"
#include "../common/stage_scene.h"
#include "sim_test_util.h"

namespace erg {
namespace {

class StageAgreement : public ::testing::TestWithParam<std::string> {};

// "EXPECTED", "STOCHASTIC", or either with "+isotropic": the shadow's cubic
// samples and the isotropic repose (model.shadow_sampling, model.repose),
// whose stencils read two cells out; or with "+deflected": the hop turned
// down the slope (test_support::deflected_stage_scene).
erg::v1::JobSpec scene(const std::string& param) {
  const auto [transport, variant] = test_support::split_scene_name(param);
  auto spec =
      test::spec_from(variant == "deflected" ? test_support::deflected_stage_scene(transport)
                                             : test_support::stage_scene(transport));
  if (variant == "isotropic") {
    spec.mutable_model()->set_shadow_sampling(erg::v1::ModelParameters::CUBIC);
    spec.mutable_model()->set_repose(erg::v1::ModelParameters::ISOTROPIC);
  }
  return spec;
}

TEST_P(StageAgreement, OneAndTwoThreadsAgreeAfterEveryStage) {
  const auto spec = scene(GetParam());
  const auto a =
      test_support::expect_stages_agree(spec, test::cpu_threads(1), test::cpu_threads(2), 4);
  EXPECT_GT(a.avalanche_iterations, 0);
}

TEST_P(StageAgreement, AvalanchingFastPathAgreesWithVisitingEveryCell) {
  const auto spec = scene(GetParam());
  RunOptions everywhere = test::cpu_threads(2);
  everywhere.avalanche_everywhere = true;
  const auto a = test_support::expect_stages_agree(spec, everywhere, test::cpu_threads(2), 4);
  EXPECT_GT(a.avalanche_iterations, 4);  // more than one iteration per step
}

// The comparison can fail, and says where: a wind turned by one degree is
// caught at the stage that computes the wind, in its x component; bounding
// the wind lets it through (b takes a's wind), and the runs then agree up
// to the first stage that reads the regime's direction itself.
TEST(StageAgreementHarness, NamesTheFirstStageAndFieldThatDiffer) {
  const auto spec = test::spec_from(test_support::stage_scene("EXPECTED"));
  auto turned = spec;
  turned.mutable_wind()->mutable_constant()->set_direction_deg(31);
  test_support::Agreement agreement;
  const std::string mismatch = test_support::first_stage_mismatch(
      spec, test::cpu_threads(1), turned, test::cpu_threads(1), 2, {}, &agreement);
  EXPECT_EQ(mismatch.rfind("step 0, after wind, field wind_x: ", 0), 0u) << mismatch;
  EXPECT_NE(mismatch.find("(no difference allowed)"), std::string::npos) << mismatch;
  EXPECT_EQ(agreement.stages_compared, 2);  // events, then wind

  test_support::Agreement bounded;
  const std::vector<test_support::FieldBound> wind = {{fields::kWindX, 100.0, "test: any wind"},
                                                      {fields::kWindY, 100.0, "test: any wind"}};
  const std::string later = test_support::first_stage_mismatch(
      spec, test::cpu_threads(1), turned, test::cpu_threads(1), 2, wind, &bounded);
  EXPECT_GT(bounded.max_abs[fields::kWindX], 0.0);
  EXPECT_GT(bounded.stages_compared, 2) << later;
}

INSTANTIATE_TEST_SUITE_P(Transport, StageAgreement,
                         ::testing::Values("EXPECTED", "STOCHASTIC", "STOCHASTIC+isotropic",
                                           "EXPECTED+deflected", "STOCHASTIC+deflected"),
                         [](const auto& info) {
                           return test_support::scene_test_name(info.param);
                         });

}  // namespace
}  // namespace erg

// SPDX-License-Identifier: Apache-2.0
// Stage by stage, the CUDA backend against the CPU backend (label gpu: it
// needs a device; CI, which has none, excludes the label by name in its
// preset). Both backends take the same job (tests/common/stage_scene.h:
// every stage has work: events of each kind, wind primitives, shadow,
// saltation with abrasion, reptation, sand and bedrock avalanching) and are
// compared after every stage of every step (tests/common/stage_agreement.h):
// - integer units (sand, airborne sand, bedrock) exactly;
// - float fields by bits, since both run the same stages/ code with the same
//   operations (no fused multiply-add on either side: CMakeLists.txt);
// - except the surface wind: its smoothing is an FFT on both sides (FFTW on
//   the CPU, cuFFT on the GPU), and the two sum in different orders. Its
//   smoothed heights agree to float rounding (about 1e-6 relative), so the
//   warped wind (|w| of a few m/s here) to well within 1e-3 m/s, the bound.
//   After the wind stage the CUDA run takes the CPU's wind, so every later
//   stage is judged on the same inputs.
// The harness is proven on the CPU in CI (tests/sim/test_stage_agreement.cpp).
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "../common/stage_agreement.h"
#include "../common/stage_scene.h"
#include "job/spec.h"

namespace erg {
namespace {

erg::v1::JobSpec scene(const std::string& transport) {
  erg::v1::JobSpec spec = job::parse_json(test_support::stage_scene(transport), "stage scene");
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
  const std::vector<test_support::FieldBound> fft = {
      {fields::kWindX, 1e-3, "FFTW and cuFFT sum in different orders"},
      {fields::kWindY, 1e-3, "FFTW and cuFFT sum in different orders"}};
  const test_support::Agreement a = test_support::expect_stages_agree(
      scene(GetParam()), on(BackendKind::kCpu), on(BackendKind::kCuda), 4, fft);
  // What the bound let through, for the record.
  std::printf("largest wind difference: x %.3g m/s, y %.3g m/s\n", a.max_abs[fields::kWindX],
              a.max_abs[fields::kWindY]);
}

INSTANTIATE_TEST_SUITE_P(Transport, CudaStages, ::testing::Values("EXPECTED", "STOCHASTIC"));

}  // namespace
}  // namespace erg

// SPDX-License-Identifier: Apache-2.0
// The job the stage-by-stage comparisons run (tests/common/stage_agreement.h):
// every stage has work in its first steps. Bedrock relief, sand patches
// steeper than the repose angle (avalanching), vegetation, an obstacle, two
// wind primitives, abrasion with bedrock turned to sand, echo dunes, and an
// event of each kind at steps 1 and 2.
#pragma once

#include <string>

namespace erg::test_support {

inline std::string stage_scene(const std::string& transport) {
  return R"({
  "name": "stages",
  "domain": {"nx": 128, "ny": 96, "cell_size_m": 1.0},
  "layers": {
    "bedrock": {"fbm": {"amplitude": 2, "wavelength_m": 64, "octaves": 2}},
    "sand": {"patches": {"coverage": 0.4, "radius_m": 10, "height": 3, "falloff_m": 2}},
    "vegetation": {"uniform": {"min": 0, "max": 0.2}},
    "obstacles": {"shapes": [{"height_m": 3, "disk": {"x_m": 60, "y_m": 40, "radius_m": 8}}]}
  },
  "wind": {"constant": {"speed_mps": 6, "direction_deg": 30}},
  "wind_primitives": [
    {"name": "eddy", "vortex": {"x_m": 40, "y_m": 60, "radius_m": 20, "peak_speed_mps": 3}},
    {"name": "gusts",
     "turbulence": {"amplitude_mps": 1.5, "wavelength_m": 24, "x_m": 64, "y_m": 48,
                    "radius_m": 40, "falloff_m": 10, "period_steps": 10,
                    "drift_m_per_step": 0.5, "drift_direction_deg": 0}}
  ],
  "events": [
    {"step": 1, "sand": {"x_m": 90, "y_m": 40, "radius_m": 12, "falloff_m": 4, "height": 3}},
    {"step": 1, "bedrock": {"x_m": 20, "y_m": 70, "radius_m": 15, "falloff_m": 5, "height": 4}},
    {"step": 2, "vegetation": {"x_m": 100, "y_m": 70, "radius_m": 10, "density": 0.8}},
    {"step": 2, "add_obstacle": {"height_m": 2, "rect": {"x_m": 10, "y_m": 2, "size_x_m": 2, "size_y_m": 12}}}
  ],
  "model": {"abrasion_k": 0.05, "bedrock_to_sand": true, "echo_dunes": true, "echo_reach_m": 12},
  "transport": ")" +
         transport + R"(",
  "seed": 5,
  "run": {"steps": 4}
})";
}

// The same scene in the physical mode (a shear velocity; the primitives'
// speeds stay model additions to the surface wind) with the hop turned down
// the slope (physics.hop_slope_deflection): the slope is read from the
// heights' ghosts, and next to the obstacles counted level.
inline std::string deflected_stage_scene(const std::string& transport) {
  std::string s = stage_scene(transport);
  const std::string wind = R"("wind": {"constant": {"speed_mps": 6, "direction_deg": 30}},)";
  s.replace(s.find(wind), wind.size(),
            R"("wind": {"speed_is": "SHEAR_VELOCITY",
           "constant": {"speed_mps": 0.45, "direction_deg": 30}},
  "physics": {"hop_slope_deflection": 0.34},)");
  return s;
}

// A stage test's parameter: "EXPECTED" or "STOCHASTIC", optionally with
// "+variant" (the tests that take it say which variants they know).
struct SceneName {
  std::string transport;
  std::string variant;  // "" without one
};
inline SceneName split_scene_name(const std::string& param) {
  const auto cut = param.find('+');
  return {param.substr(0, cut), cut == std::string::npos ? "" : param.substr(cut + 1)};
}
// The test name of such a parameter ('+' is not allowed in one).
inline std::string scene_test_name(std::string param) {
  for (char& c : param)
    if (c == '+') c = '_';
  return param;
}

}  // namespace erg::test_support

// SPDX-License-Identifier: Apache-2.0
// Export-time amplification [P19 6]: the final sand elevation of a region of
// a snapshot, upsampled K times, S~ = S + R + B, with wind ripples R
// (ripples.h) and sand bumps B around vegetation and obstacles (bumps.h).
// A post-process: it never feeds back into the simulation. Deterministic for
// a seed (single-threaded, fixed order); periodic where the region spans the
// whole torus, and the region may wrap across the domain's edges.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/vec2.h"
#include "erg/v1/job.pb.h"

namespace erg::amplify {

// The snapshot fields amplification reads, row-major [ny][nx], row 0 = y = 0.
struct AmplifyInput {
  int nx = 0, ny = 0;
  double cell_size_m = 1;
  std::vector<float> bedrock, sand, vegetation;  // metres, metres, [0, 1]
  std::vector<float> wind;                       // m/s, [ny][nx][2] (x, y)
  std::vector<float> shadow;                     // [0, 1]; empty: no shadow
  std::vector<float> obstacles;                  // [0, 1]; empty: no obstacles
  // High-altitude wind a(t) over the recent steps, oldest first, the last at
  // the snapshot's step: the ripples see each past wind as the snapshot's
  // local wind turned and scaled by a(t) / a(now) (one wind: asymmetric
  // ripples; alternating winds: symmetric ones [P19 6]).
  std::vector<Vec2> wind_history;
  std::uint64_t seed = 1;
};

// A rectangle of simulation cells; x0, y0 in [0, nx), [0, ny); it may run
// past the edge of the domain (it wraps), w <= nx, h <= ny.
struct Region {
  int x0 = 0, y0 = 0, w = 0, h = 0;
};

// The parameters of proto AmplifyParameters, defaults filled by the job code.
using AmplifyParams = erg::v1::AmplifyParameters;

// The amplified region, [h * K][w * K] row-major, cell size cell_size_m / K.
struct AmplifiedLayers {
  int nx = 0, ny = 0;
  double cell_size_m = 1;
  std::vector<float> bedrock;  // upsampled (Catmull-Rom bicubic)
  std::vector<float> base;     // bedrock + sand, upsampled (bicubic, sand >= 0)
  std::vector<float> ripples;  // R, metres
  std::vector<float> bumps;    // B, metres
  std::vector<float> height;   // bedrock + max(0, sand + R + B)
};

// Throws std::invalid_argument naming the bad argument (region, upsample,
// field sizes).
AmplifiedLayers amplify_layers(const AmplifyInput& in, const Region& region, int upsample,
                               const AmplifyParams& p);

// The amplified heightfield alone (AmplifiedLayers::height).
std::vector<float> amplify(const AmplifyInput& in, const Region& region, int upsample,
                           const AmplifyParams& p);

// Input from a snapshot file: its fields, the optional `obstacles` dataset
// when the file has one, and the wind history from the job spec it records
// (p.wind_history_steps steps up to the snapshot's step, via wind::at_step).
// `spec` receives the defaults-filled job of the snapshot.
AmplifyInput input_from_snapshot(const std::string& path, erg::v1::JobSpec& spec);

// Parses "X0,Y0,W,H" and checks it against the domain; throws
// std::invalid_argument naming the field and the allowed range.
Region parse_region(const std::string& text, int nx, int ny);

}  // namespace erg::amplify

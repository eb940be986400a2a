// SPDX-License-Identifier: Apache-2.0
#include "amplify/amplify.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "amplify/bumps.h"
#include "amplify/ripples.h"
#include "amplify/sampling.h"
#include "io/io.h"
#include "job/spec.h"
#include "wind/regime.h"

namespace erg::amplify {

using detail::bicubic;
using detail::bilinear;
using detail::wrap;

namespace {

// Coarse cells added around a region that does not span the torus, so that
// the ripple model (periodic on its own grid) meets its wrap-around seam
// outside the output.
constexpr int kRipplePad = 4;

void check_input(const AmplifyInput& in, const Region& region, int upsample) {
  const size_t n = static_cast<size_t>(in.nx) * static_cast<size_t>(in.ny);
  if (in.nx <= 0 || in.ny <= 0) throw std::invalid_argument("amplify: the snapshot has no cells");
  auto need = [&](const std::vector<float>& f, size_t size, const char* name, bool optional) {
    if (optional && f.empty()) return;
    if (f.size() != size)
      throw std::invalid_argument(std::string("amplify: field ") + name + " has " +
                                  std::to_string(f.size()) + " values; expected " +
                                  std::to_string(size));
  };
  need(in.bedrock, n, "bedrock", false);
  need(in.sand, n, "sand", false);
  need(in.vegetation, n, "vegetation", false);
  need(in.wind, 2 * n, "wind", false);
  need(in.shadow, n, "shadow", true);
  need(in.obstacles, n, "obstacles", true);
  if (upsample < 1 || upsample > 64)
    throw std::invalid_argument("amplify: upsample = " + std::to_string(upsample) +
                                " is out of range; allowed [1, 64]");
  if (region.x0 < 0 || region.x0 >= in.nx || region.y0 < 0 || region.y0 >= in.ny || region.w < 1 ||
      region.w > in.nx || region.h < 1 || region.h > in.ny)
    throw std::invalid_argument(
        "amplify: region " + std::to_string(region.x0) + "," + std::to_string(region.y0) + "," +
        std::to_string(region.w) + "," + std::to_string(region.h) +
        " is outside the domain; allowed X0 in [0, " + std::to_string(in.nx - 1) + "], Y0 in [0, " +
        std::to_string(in.ny - 1) + "], W in [1, " + std::to_string(in.nx) + "], H in [1, " +
        std::to_string(in.ny) + "]");
  const double cells = static_cast<double>(region.w) * region.h * upsample * upsample;
  if (cells > 1.0e9)
    throw std::invalid_argument("amplify: region x upsample gives " + std::to_string(cells) +
                                " cells; allowed at most 1e9");
}

// Where sand moves freely: open (unshadowed) sand, not under plants or
// obstacles, thick enough [P19 6: ripples weighted by the wind shadow].
float mobility_at(const AmplifyInput& in, const AmplifyParams& p, double x, double y) {
  const double sand = bilinear(in.sand, in.nx, in.ny, x, y);
  const double min_sand = p.ripple_min_sand_m();
  double m = min_sand > 0 ? std::clamp(sand / min_sand, 0.0, 1.0) : (sand > 0 ? 1.0 : 0.0);
  m *= 1.0 - std::clamp<double>(bilinear(in.vegetation, in.nx, in.ny, x, y), 0, 1);
  if (!in.shadow.empty())
    m *= 1.0 - std::clamp<double>(bilinear(in.shadow, in.nx, in.ny, x, y), 0, 1);
  if (!in.obstacles.empty())
    m *= 1.0 - std::clamp<double>(bilinear(in.obstacles, in.nx, in.ny, x, y), 0, 1);
  return static_cast<float>(m);
}

}  // namespace

AmplifiedLayers amplify_layers(const AmplifyInput& in, const Region& region, int upsample,
                               const AmplifyParams& p) {
  check_input(in, region, upsample);
  const int k = upsample;
  AmplifiedLayers out;
  out.nx = region.w * k;
  out.ny = region.h * k;
  out.cell_size_m = in.cell_size_m / k;
  const size_t n = static_cast<size_t>(out.nx) * out.ny;

  // Fine cell i of a grid starting at coarse cell x0 has its centre at
  // x0 + (i + 0.5) / k in continuous coordinates, i.e. at x0 + (i + 0.5) / k
  // - 0.5 in the cell-centre coordinates that bilinear() takes.
  auto cx = [&](int x0, int i) { return x0 + (i + 0.5) / k - 0.5; };

  out.base.resize(n);
  for (int j = 0; j < out.ny; ++j)
    for (int i = 0; i < out.nx; ++i) {
      const double x = cx(region.x0, i), y = cx(region.y0, j);
      out.base[static_cast<size_t>(j) * out.nx + i] =
          static_cast<float>(bicubic(in.bedrock, in.nx, in.ny, x, y) +
                             std::max(0.0f, bicubic(in.sand, in.nx, in.ny, x, y)));
    }

  // Ripples on the region plus a margin (none along an axis the region spans).
  const int px = region.w < in.nx ? kRipplePad : 0;
  const int py = region.h < in.ny ? kRipplePad : 0;
  RippleGrid g;
  g.nx = (region.w + 2 * px) * k;
  g.ny = (region.h + 2 * py) * k;
  g.gx0 = (region.x0 - px) * k;
  g.gy0 = (region.y0 - py) * k;
  g.gnx = in.nx * k;
  g.gny = in.ny * k;
  g.seed = in.seed;
  const size_t gn = static_cast<size_t>(g.nx) * g.ny;
  g.mobility.resize(gn);
  g.wind.resize(2 * gn);
  for (int j = 0; j < g.ny; ++j)
    for (int i = 0; i < g.nx; ++i) {
      const double x = cx(region.x0 - px, i), y = cx(region.y0 - py, j);
      const size_t c = static_cast<size_t>(j) * g.nx + i;
      g.mobility[c] = mobility_at(in, p, x, y);
      g.wind[2 * c] = bilinear(in.wind, in.nx, in.ny, x, y, 2, 0);
      g.wind[2 * c + 1] = bilinear(in.wind, in.nx, in.ny, x, y, 2, 1);
    }
  const std::vector<float> relief = ripple_relief(g, past_winds(in.wind_history), p);
  out.ripples.resize(n);
  for (int j = 0; j < out.ny; ++j)
    for (int i = 0; i < out.nx; ++i)
      out.ripples[static_cast<size_t>(j) * out.nx + i] =
          relief[static_cast<size_t>(j + py * k) * g.nx + (i + px * k)];

  out.bumps = sand_bumps(in, region, k, p);

  // S~ = S + R + B [P19 6], sand never below the bedrock.
  out.height.resize(n);
  out.bedrock.resize(n);
  for (int j = 0; j < out.ny; ++j)
    for (int i = 0; i < out.nx; ++i) {
      const size_t c = static_cast<size_t>(j) * out.nx + i;
      const double x = cx(region.x0, i), y = cx(region.y0, j);
      const double bed = bicubic(in.bedrock, in.nx, in.ny, x, y);
      const double sand = std::max(0.0f, bicubic(in.sand, in.nx, in.ny, x, y));
      out.bedrock[c] = static_cast<float>(bed);
      out.height[c] = static_cast<float>(bed + std::max(0.0, sand + out.ripples[c] + out.bumps[c]));
    }
  return out;
}

std::vector<float> amplify(const AmplifyInput& in, const Region& region, int upsample,
                           const AmplifyParams& p) {
  return amplify_layers(in, region, upsample, p).height;
}

AmplifyInput input_from_snapshot(const std::string& path, erg::v1::JobSpec& spec) {
  io::Snapshot snap = io::read_snapshot(path);
  if (snap.wind.empty()) throw io::IoError(path + ": snapshot has no /wind dataset");
  spec = job::parse_json(snap.meta.job_spec_json, path + " (job_spec attribute)");
  job::apply_defaults(spec);
  AmplifyInput in;
  in.nx = snap.meta.nx;
  in.ny = snap.meta.ny;
  in.cell_size_m = snap.meta.cell_size_m;
  in.bedrock = std::move(snap[fields::kBedrock]);
  in.sand = std::move(snap[fields::kSand]);
  in.vegetation = std::move(snap[fields::kVegetation]);
  in.wind = std::move(snap.wind);
  in.shadow = std::move(snap[fields::kShadow]);
  in.seed = snap.meta.seed;
  // /obstacles holds obstacle heights in metres (0: none); amplification
  // only needs where they are. Snapshots of runs without obstacles have no
  // such dataset, or one of zeros: both mean "no obstacles".
  if (!snap[fields::kObstacles].empty() &&
      std::any_of(snap[fields::kObstacles].begin(), snap[fields::kObstacles].end(),
                  [](float h) { return h > 0; })) {
    in.obstacles.resize(snap[fields::kObstacles].size());
    std::transform(snap[fields::kObstacles].begin(), snap[fields::kObstacles].end(),
                   in.obstacles.begin(), [](float h) { return h > 0 ? 1.0f : 0.0f; });
  }
  const std::int64_t steps = spec.amplify().wind_history_steps();
  const std::int64_t first = std::max<std::int64_t>(0, snap.meta.step - steps + 1);
  for (std::int64_t s = first; s <= snap.meta.step; ++s)
    in.wind_history.push_back(wind::at_step(spec, s));
  return in;
}

Region parse_region(const std::string& text, int nx, int ny) {
  Region r;
  char c1 = 0, c2 = 0, c3 = 0;
  std::istringstream is(text);
  if (!(is >> r.x0 >> c1 >> r.y0 >> c2 >> r.w >> c3 >> r.h) || c1 != ',' || c2 != ',' ||
      c3 != ',' || (is >> std::ws, !is.eof()))
    throw std::invalid_argument("--region '" + text + "' is not X0,Y0,W,H (four integers)");
  if (r.x0 < 0 || r.x0 >= nx)
    throw std::invalid_argument("--region X0 = " + std::to_string(r.x0) +
                                " is out of range; allowed [0, " + std::to_string(nx - 1) + "]");
  if (r.y0 < 0 || r.y0 >= ny)
    throw std::invalid_argument("--region Y0 = " + std::to_string(r.y0) +
                                " is out of range; allowed [0, " + std::to_string(ny - 1) + "]");
  if (r.w < 1 || r.w > nx)
    throw std::invalid_argument("--region W = " + std::to_string(r.w) +
                                " is out of range; allowed [1, " + std::to_string(nx) + "]");
  if (r.h < 1 || r.h > ny)
    throw std::invalid_argument("--region H = " + std::to_string(r.h) +
                                " is out of range; allowed [1, " + std::to_string(ny) + "]");
  return r;
}

}  // namespace erg::amplify

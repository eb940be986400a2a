// SPDX-License-Identifier: Apache-2.0
// Hillshaded PNG previews: what a person looks at first, so they should read
// like a map. North is up, light comes from the north-west (the cartographic
// convention, so dunes look raised rather than sunken), and colour says what
// covers the ground: grey bedrock, sand from pale to deep ochre as it
// thickens, green vegetation.
#include <png.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <string>
#include <vector>

#include "io/atomic_file.h"
#include "io/io.h"
#include "io/png_util.h"

namespace erg::io {
namespace {

struct Rgb {
  double r, g, b;
};

constexpr Rgb kBedrock = {150, 140, 130};
constexpr Rgb kSandPale = {235, 215, 170};
constexpr Rgb kSandDeep = {205, 140, 70};
constexpr Rgb kVegetation = {80, 130, 60};

// Brightness = ambient + diffuse * max(0, n . light). The ambient share keeps
// slopes facing away from the light readable instead of black.
constexpr double kAmbient = 0.35;
constexpr double kDiffuse = 0.65;

// Unit vector towards the light, x east, y north, z up: azimuth 315 degrees
// (clockwise from north, i.e. north-west), elevation 45 degrees.
constexpr double kLightX = -0.5;                 // cos(45) * sin(315)
constexpr double kLightY = 0.5;                  // cos(45) * cos(315)
constexpr double kLightZ = 0.70710678118654752;  // sin(45)

// Sand this thick (metres) hides the bedrock colour to 1 - 1/e; 5 cm of
// sand then covers 92%, as a thin veneer already looks sandy in the field.
constexpr double kSandCoverScale = 0.02;
// The pale-to-ochre ramp is logarithmic in thickness from kSandThin to
// kSandThick (fully ochre), so ripples and 100 m dunes both show contrast.
constexpr double kSandThin = 0.05;
constexpr double kSandThick = 10.0;

Rgb mix(const Rgb& a, const Rgb& b, double t) {
  return {a.r + (b.r - a.r) * t, a.g + (b.g - a.g) * t, a.b + (b.b - a.b) * t};
}

// NaN or infinite input (a diverged run) must not make the PNG garbage or
// the uint8 conversion undefined: such cells render as zero.
double finite_or_zero(float v) {
  return std::isfinite(v) ? static_cast<double>(v) : 0.0;
}

// Ground colour before lighting, from sand thickness and vegetation density.
Rgb ground_colour(double sand_m, double vegetation) {
  const double s = std::max(0.0, sand_m);
  const double cover = 1.0 - std::exp(-s / kSandCoverScale);
  double t = std::log1p(s / kSandThin) / std::log1p(kSandThick / kSandThin);
  t = std::clamp(t, 0.0, 1.0);
  t = t * t * (3.0 - 2.0 * t);  // smoothstep: no visible kink at either end
  const Rgb sand = mix(kSandPale, kSandDeep, t);
  return mix(mix(kBedrock, sand, cover), kVegetation, std::clamp(vegetation, 0.0, 1.0));
}

// Computes the lit colour of any cell of the full-resolution grid.
class Shader {
 public:
  Shader(int nx, int ny, double cell_size_m, const float* bedrock, const float* sand,
         const float* vegetation)
      : nx_(nx),
        ny_(ny),
        inv_2dx_(1.0 / (2.0 * cell_size_m)),
        bedrock_(bedrock),
        sand_(sand),
        vegetation_(vegetation) {}

  Rgb colour(int x, int y) const {
    // Central differences with periodic wrap: the domain is a torus, so the
    // cell left of x = 0 is x = nx - 1 (for nx = 1 both neighbours are the
    // cell itself and the slope is 0).
    const int xl = x == 0 ? nx_ - 1 : x - 1, xr = x == nx_ - 1 ? 0 : x + 1;
    const int yd = y == 0 ? ny_ - 1 : y - 1, yu = y == ny_ - 1 ? 0 : y + 1;
    const double dzdx = (height(xr, y) - height(xl, y)) * inv_2dx_;
    const double dzdy = (height(x, yu) - height(x, yd)) * inv_2dx_;
    // Surface normal (-dz/dx, -dz/dy, 1), normalised.
    const double inv_len = 1.0 / std::sqrt(dzdx * dzdx + dzdy * dzdy + 1.0);
    const double lambert = std::max(0.0, (-dzdx * kLightX - dzdy * kLightY + kLightZ) * inv_len);
    const double light = kAmbient + kDiffuse * lambert;

    const std::size_t i = index(x, y);
    const double veg = vegetation_ ? finite_or_zero(vegetation_[i]) : 0.0;
    const Rgb base = ground_colour(finite_or_zero(sand_[i]), veg);
    return {base.r * light, base.g * light, base.b * light};
  }

 private:
  std::size_t index(int x, int y) const {
    return static_cast<std::size_t>(y) * static_cast<std::size_t>(nx_) +
           static_cast<std::size_t>(x);
  }
  double height(int x, int y) const {
    const std::size_t i = index(x, y);
    return finite_or_zero(bedrock_[i]) + finite_or_zero(sand_[i]);
  }

  int nx_, ny_;
  double inv_2dx_;
  const float* bedrock_;
  const float* sand_;
  const float* vegetation_;
};

unsigned char to_byte(double v) {
  return static_cast<unsigned char>(std::lround(std::clamp(v, 0.0, 255.0)));
}

}  // namespace

void write_preview_png(const std::string& path, int nx, int ny, double cell_size_m,
                       const float* bedrock, const float* sand, const float* vegetation,
                       int max_px) {
  if (nx <= 0 || ny <= 0) {
    detail::fail(path, "invalid grid " + std::to_string(nx) + " x " + std::to_string(ny));
  }
  if (max_px <= 0) detail::fail(path, "max_px must be positive, got " + std::to_string(max_px));
  if (!(cell_size_m > 0) || !std::isfinite(cell_size_m)) {
    detail::fail(path, "cell size must be a positive number of metres");
  }
  if (!bedrock || !sand) detail::fail(path, "preview needs bedrock and sand (got a null pointer)");

  // Integer reduction factor so that the longest side fits in max_px; the
  // last block of a row or column may be partial and averages what it has.
  const int longest = std::max(nx, ny);
  const int f = (longest + max_px - 1) / max_px;
  const int out_w = (nx + f - 1) / f, out_h = (ny + f - 1) / f;

  // Shade at full resolution, then box-average the colours: averaging the
  // heights first would smooth away the ripples and slip faces that make a
  // reduced preview still read as dunes.
  const Shader shader(nx, ny, cell_size_m, bedrock, sand, vegetation);
  std::vector<double> acc(static_cast<std::size_t>(out_w) * 3);
  detail::write_png_atomically(
      path, out_w, out_h, 8, PNG_COLOR_TYPE_RGB, 3, [&](int row, unsigned char* out) {
        const int oy = out_h - 1 - row;  // image top = north = largest y
        const int y0 = oy * f, y1 = std::min(ny, y0 + f);
        std::fill(acc.begin(), acc.end(), 0.0);
        for (int y = y0; y < y1; ++y) {
          for (int x = 0; x < nx; ++x) {
            const Rgb c = shader.colour(x, y);
            double* a = &acc[static_cast<std::size_t>(x / f) * 3];
            a[0] += c.r;
            a[1] += c.g;
            a[2] += c.b;
          }
        }
        for (int ox = 0; ox < out_w; ++ox) {
          const int cells = (y1 - y0) * (std::min(nx, (ox + 1) * f) - ox * f);
          const double* a = &acc[static_cast<std::size_t>(ox) * 3];
          for (int k = 0; k < 3; ++k) out[3 * ox + k] = to_byte(a[k] / cells);
        }
      });
}

}  // namespace erg::io

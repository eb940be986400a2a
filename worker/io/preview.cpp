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
#include <cstdio>
#include <numbers>
#include <string>
#include <vector>

#include "io/atomic_file.h"
#include "io/bitmap_font.h"
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
    const std::size_t i = index(x, y);
    const double veg = vegetation_ ? finite_or_zero(vegetation_[i]) : 0.0;
    return lit(ground_colour(finite_or_zero(sand_[i]), veg), dzdx, dzdy);
  }

  // The colour at a point between cell centres, for an image with more
  // pixels than cells: heights, sand and vegetation interpolated bilinearly
  // at (u, v) (cell units, cell centres at integers, wrapping), and the slope
  // of the interpolated surface over one cell, so the light is computed at
  // the output's resolution and slopes shade smoothly instead of in blocks.
  Rgb colour_at(double u, double v) const {
    const double dzdx = (bilinear_height(u + 0.5, v) - bilinear_height(u - 0.5, v)) * inv_2dx_ * 2;
    const double dzdy = (bilinear_height(u, v + 0.5) - bilinear_height(u, v - 0.5)) * inv_2dx_ * 2;
    const double sand = bilinear(sand_, u, v);
    const double veg = vegetation_ ? bilinear(vegetation_, u, v) : 0.0;
    return lit(ground_colour(sand, veg), dzdx, dzdy);
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
  // Periodic cell index of a coordinate (the domain is a torus).
  static int wrap(int k, int n) { return ((k % n) + n) % n; }
  // The four cells around (u, v) and the weights of the upper ones.
  struct Corners {
    int x0, x1, y0, y1;
    double fx, fy;
  };
  Corners corners(double u, double v) const {
    const double fu = std::floor(u), fv = std::floor(v);
    const int iu = static_cast<int>(fu), iv = static_cast<int>(fv);
    return {wrap(iu, nx_), wrap(iu + 1, nx_), wrap(iv, ny_), wrap(iv + 1, ny_), u - fu, v - fv};
  }
  template <class At>
  static double blend(const Corners& c, const At& at) {
    return (at(c.x0, c.y0) * (1 - c.fx) + at(c.x1, c.y0) * c.fx) * (1 - c.fy) +
           (at(c.x0, c.y1) * (1 - c.fx) + at(c.x1, c.y1) * c.fx) * c.fy;
  }
  double bilinear_height(double u, double v) const {
    return blend(corners(u, v), [this](int x, int y) { return height(x, y); });
  }
  double bilinear(const float* layer, double u, double v) const {
    return blend(corners(u, v),
                 [this, layer](int x, int y) { return finite_or_zero(layer[index(x, y)]); });
  }
  // Brightness = ambient + diffuse * max(0, n . light), n the normal of the
  // surface with slopes (dzdx, dzdy).
  static Rgb lit(const Rgb& base, double dzdx, double dzdy) {
    const double inv_len = 1.0 / std::sqrt(dzdx * dzdx + dzdy * dzdy + 1.0);
    const double lambert = std::max(0.0, (-dzdx * kLightX - dzdy * kLightY + kLightZ) * inv_len);
    const double light = kAmbient + kDiffuse * lambert;
    return {base.r * light, base.g * light, base.b * light};
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

// ---- the labelled preview -------------------------------------------------
// Below the map a panel carries, left to right: a scale bar with its length
// in metres, the colour legend of sand thickness, the step and simulated
// time, and a compass with the current wind as an arrow (the direction it
// blows towards) over the regime's rose. Text uses io/bitmap_font.h.
constexpr int kMinLongSide = 768;  // a preview people can read on a screen
constexpr int kPanelH = 72;
constexpr int kMargin = 12, kGap = 32;
constexpr int kTextScale = 2;  // font pixels are 2 x 2: 10 x 14 px glyphs
constexpr int kBarH = 6;
constexpr int kLegendW = 180, kLegendH = 12;
constexpr int kWindR = 24;
constexpr Rgb kPanel = {40, 40, 40};
constexpr Rgb kWhite = {255, 255, 255};
constexpr Rgb kRing = {170, 170, 170};
constexpr Rgb kRoseColour = {110, 160, 210};
constexpr Rgb kArrow = {230, 60, 40};
// Flat ground in the map is lit by ambient + diffuse * sin(45 degrees): the
// legend uses that light, so its colours are those of level sand.
constexpr double kFlatLight = kAmbient + kDiffuse * kLightZ;

// The sand thickness at legend position u in [0, 1]: the inverse of the
// logarithmic ramp of ground_colour, so the legend spans it evenly.
double legend_sand(double u) {
  return kSandThin * (std::pow(1.0 + kSandThick / kSandThin, u) - 1.0);
}
double legend_pos(double sand_m) {
  return std::log1p(sand_m / kSandThin) / std::log1p(kSandThick / kSandThin);
}

// The largest 1, 2 or 5 x 10^k metres not longer than `max_m`.
double round_length(double max_m) {
  const double p = std::pow(10.0, std::floor(std::log10(max_m)));
  for (const double m : {5.0, 2.0, 1.0})
    if (m * p <= max_m * (1 + 1e-9)) return m * p;
  return p;
}

std::string format_number(const char* fmt, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, fmt, v);
  return buf;
}

std::string length_label(double m) {
  return m >= 1000 ? format_number("%g km", m / 1000) : format_number("%g m", m);
}

// Days under a year, then Julian years (365.25 days, as the worker reports).
std::string time_label(double days) {
  if (!std::isfinite(days) || days < 0) days = 0;
  if (days < 365.25) return format_number("%.0f d", days);
  const double years = days / 365.25;
  return format_number(years < 10 ? "%.1f yr" : "%.0f yr", years);
}

// An RGB image in memory, drawn on with clipping.
class Canvas {
 public:
  Canvas(int w, int h, const Rgb& bg) : w_(w), h_(h), px_(static_cast<std::size_t>(w) * h * 3) {
    fill(0, 0, w, h, bg);
  }
  void set(int x, int y, const Rgb& c) {
    if (x < 0 || y < 0 || x >= w_ || y >= h_) return;
    unsigned char* p = &px_[(static_cast<std::size_t>(y) * w_ + x) * 3];
    p[0] = to_byte(c.r);
    p[1] = to_byte(c.g);
    p[2] = to_byte(c.b);
  }
  void fill(int x0, int y0, int x1, int y1, const Rgb& c) {
    for (int y = y0; y < y1; ++y)
      for (int x = x0; x < x1; ++x) set(x, y, c);
  }
  void text(const std::string& t, int x, int y, const Rgb& c, int scale = kTextScale) {
    font::draw_text(t, x, y, scale, [&](int px, int py) { set(px, py, c); });
  }
  // Pixels within half_width of the segment a-b.
  void line(double ax, double ay, double bx, double by, double half_width, const Rgb& c) {
    const double dx = bx - ax, dy = by - ay, len2 = std::max(dx * dx + dy * dy, 1e-12);
    const int x0 = static_cast<int>(std::floor(std::min(ax, bx) - half_width));
    const int x1 = static_cast<int>(std::ceil(std::max(ax, bx) + half_width));
    const int y0 = static_cast<int>(std::floor(std::min(ay, by) - half_width));
    const int y1 = static_cast<int>(std::ceil(std::max(ay, by) + half_width));
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x) {
        const double t = std::clamp(((x - ax) * dx + (y - ay) * dy) / len2, 0.0, 1.0);
        const double ex = x - (ax + t * dx), ey = y - (ay + t * dy);
        if (ex * ex + ey * ey <= half_width * half_width) set(x, y, c);
      }
  }
  // A filled triangle (edge functions; either winding).
  void triangle(const double (&p)[3][2], const Rgb& c) {
    const auto edge = [](const double* a, const double* b, double x, double y) {
      return (b[0] - a[0]) * (y - a[1]) - (b[1] - a[1]) * (x - a[0]);
    };
    const int x0 = static_cast<int>(std::floor(std::min({p[0][0], p[1][0], p[2][0]})));
    const int x1 = static_cast<int>(std::ceil(std::max({p[0][0], p[1][0], p[2][0]})));
    const int y0 = static_cast<int>(std::floor(std::min({p[0][1], p[1][1], p[2][1]})));
    const int y1 = static_cast<int>(std::ceil(std::max({p[0][1], p[1][1], p[2][1]})));
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x) {
        const double e0 = edge(p[0], p[1], x, y), e1 = edge(p[1], p[2], x, y),
                     e2 = edge(p[2], p[0], x, y);
        if ((e0 >= 0 && e1 >= 0 && e2 >= 0) || (e0 <= 0 && e1 <= 0 && e2 <= 0)) set(x, y, c);
      }
  }
  void ring(double cx, double cy, double r, const Rgb& c) {
    for (int y = static_cast<int>(cy - r - 2); y <= static_cast<int>(cy + r + 2); ++y)
      for (int x = static_cast<int>(cx - r - 2); x <= static_cast<int>(cx + r + 2); ++x)
        if (std::abs(std::hypot(x - cx, y - cy) - r) <= 0.75) set(x, y, c);
  }
  unsigned char* row(int y) { return &px_[static_cast<std::size_t>(y) * w_ * 3]; }
  const unsigned char* row(int y) const { return &px_[static_cast<std::size_t>(y) * w_ * 3]; }
  int width() const { return w_; }
  int height() const { return h_; }

 private:
  int w_, h_;
  std::vector<unsigned char> px_;
};

// Output pixels per cell (>= 1: an upscale) and cells per output pixel
// (>= 1: a reduction) for a grid; one of them is 1.
struct Scale {
  int up = 1, down = 1;
};
Scale map_scale(int nx, int ny, int max_px, bool labelled) {
  const int longest = std::max(nx, ny);
  Scale s;
  if (labelled && longest < kMinLongSide) {
    s.up = (kMinLongSide + longest - 1) / longest;
  } else {
    const int limit = labelled ? std::max(max_px, kMinLongSide) : max_px;
    s.down = (longest + limit - 1) / limit;
  }
  return s;
}

// Shades the map into the top-left map_w x map_h pixels of `canvas`.
void draw_map(Canvas& canvas, const Shader& shader, int nx, int ny, const Scale& s, int map_w,
              int map_h) {
  if (s.up > 1) {
    for (int row = 0; row < map_h; ++row) {
      unsigned char* out = canvas.row(row);
      const double v = (map_h - 1 - row + 0.5) / s.up - 0.5;  // image top = north
      for (int px = 0; px < map_w; ++px) {
        const Rgb c = shader.colour_at((px + 0.5) / s.up - 0.5, v);
        out[3 * px] = to_byte(c.r);
        out[3 * px + 1] = to_byte(c.g);
        out[3 * px + 2] = to_byte(c.b);
      }
    }
    return;
  }
  // Shade at full resolution, then box-average the colours: averaging the
  // heights first would smooth away the ripples and slip faces that make a
  // reduced preview still read as dunes. The last block of a row or column
  // may be partial and averages what it has.
  const int f = s.down;
  std::vector<double> acc(static_cast<std::size_t>(map_w) * 3);
  for (int row = 0; row < map_h; ++row) {
    unsigned char* out = canvas.row(row);
    const int oy = map_h - 1 - row;
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
    for (int ox = 0; ox < map_w; ++ox) {
      const int cells = (y1 - y0) * (std::min(nx, (ox + 1) * f) - ox * f);
      const double* a = &acc[static_cast<std::size_t>(ox) * 3];
      for (int k = 0; k < 3; ++k) out[3 * ox + k] = to_byte(a[k] / cells);
    }
  }
}

void draw_panel(Canvas& c, const PreviewLayout& l, const PreviewLabels& labels) {
  const int top = l.map_h;
  // Scale bar, its length above it.
  c.text(length_label(l.bar_m), l.bar_x, top + 10, kWhite);
  c.fill(l.bar_x, l.bar_y, l.bar_x + l.bar_px, l.bar_y + kBarH, kWhite);
  // Legend: the colours of level sand from none to kSandThick, logarithmic.
  c.text("sand m", l.legend_x, top + 6, kWhite);
  for (int i = 0; i < l.legend_w; ++i) {
    const Rgb g = ground_colour(legend_sand(i / static_cast<double>(l.legend_w - 1)), 0.0);
    const Rgb lit = {g.r * kFlatLight, g.g * kFlatLight, g.b * kFlatLight};
    c.fill(l.legend_x + i, l.legend_y, l.legend_x + i + 1, l.legend_y + l.legend_h, lit);
  }
  const int ticks_y = l.legend_y + l.legend_h + 6;
  c.text("0", l.legend_x, ticks_y, kWhite);
  const int one = l.legend_x + static_cast<int>(std::lround(legend_pos(1.0) * (l.legend_w - 1)));
  c.text("1", one - font::text_width("1", kTextScale) / 2, ticks_y, kWhite);
  const std::string thick = format_number("%g", kSandThick);
  c.text(thick, l.legend_x + l.legend_w - font::text_width(thick, kTextScale), ticks_y, kWhite);
  // Step and simulated time.
  c.text("step " + std::to_string(labels.step), l.label_x, top + 10, kWhite);
  c.text(time_label(labels.time_days), l.label_x, top + 36, kWhite);
  // Compass: north up, the rose's spokes by weight, the current wind.
  const double cx = l.wind_cx, cy = l.wind_cy, r = l.wind_r;
  c.ring(cx, cy, r, kRing);
  c.text("N", static_cast<int>(cx) - font::text_width("N", 1) / 2,
         static_cast<int>(cy - r) - font::kGlyphH - 2, kWhite, 1);
  double max_w = 0;
  for (const auto& spoke : labels.rose) max_w = std::max(max_w, spoke.weight);
  if (labels.rose.size() > 1 && max_w > 0)
    for (const auto& spoke : labels.rose) {
      const double a = spoke.direction_deg * std::numbers::pi / 180.0;
      const double len = r * std::max(0.0, spoke.weight) / max_w;
      c.line(cx, cy, cx + len * std::cos(a), cy - len * std::sin(a), 1.5, kRoseColour);
    }
  const double speed = std::hypot(labels.wind_x, labels.wind_y);
  if (speed > 0 && std::isfinite(speed)) {
    // Image y grows southwards.
    const double dx = labels.wind_x / speed, dy = -labels.wind_y / speed;
    const double tail = 0.75 * r, neck = 0.3 * r, tip = 0.95 * r, half = 0.35 * r;
    c.line(cx - tail * dx, cy - tail * dy, cx + neck * dx, cy + neck * dy, 1.5, kArrow);
    const double head[3][2] = {{cx + tip * dx, cy + tip * dy},
                               {cx + neck * dx - half * dy, cy + neck * dy + half * dx},
                               {cx + neck * dx + half * dy, cy + neck * dy - half * dx}};
    c.triangle(head, kArrow);
  }
}

}  // namespace

PreviewLayout preview_layout(int nx, int ny, double cell_size_m, int max_px) {
  const Scale s = map_scale(nx, ny, max_px, true);
  PreviewLayout l;
  l.map_w = s.up > 1 ? nx * s.up : (nx + s.down - 1) / s.down;
  l.map_h = s.up > 1 ? ny * s.up : (ny + s.down - 1) / s.down;
  l.width = std::max(l.map_w, kMinLongSide);
  l.height = l.map_h + kPanelH;
  l.metres_per_px = cell_size_m * s.down / s.up;
  // At most a fifth of the map's width, a round number of metres.
  l.bar_m = round_length(l.map_w / 5.0 * l.metres_per_px);
  l.bar_px = static_cast<int>(std::lround(l.bar_m / l.metres_per_px));
  l.bar_x = kMargin;
  l.bar_y = l.map_h + 34;
  l.legend_x =
      kMargin + std::max(l.bar_px, font::text_width(length_label(l.bar_m), kTextScale)) + kGap;
  l.legend_y = l.map_h + 28;
  l.legend_w = kLegendW;
  l.legend_h = kLegendH;
  l.label_x = l.legend_x + l.legend_w + kGap;
  l.wind_r = kWindR;
  l.wind_cx = l.width - kMargin - kWindR - 4;
  l.wind_cy = l.map_h + 40;
  return l;
}

void write_preview_png(const std::string& path, int nx, int ny, double cell_size_m,
                       const float* bedrock, const float* sand, const float* vegetation, int max_px,
                       const PreviewLabels* labels) {
  if (nx <= 0 || ny <= 0) {
    detail::fail(path, "invalid grid " + std::to_string(nx) + " x " + std::to_string(ny));
  }
  if (max_px <= 0) detail::fail(path, "max_px must be positive, got " + std::to_string(max_px));
  if (!(cell_size_m > 0) || !std::isfinite(cell_size_m)) {
    detail::fail(path, "cell size must be a positive number of metres");
  }
  if (!bedrock || !sand) detail::fail(path, "preview needs bedrock and sand (got a null pointer)");

  const Scale s = map_scale(nx, ny, max_px, labels != nullptr);
  const Shader shader(nx, ny, cell_size_m, bedrock, sand, vegetation);
  PreviewLayout l;
  if (labels) {
    l = preview_layout(nx, ny, cell_size_m, max_px);
  } else {
    l.map_w = l.width = (nx + s.down - 1) / s.down;
    l.map_h = l.height = (ny + s.down - 1) / s.down;
  }
  Canvas canvas(l.width, l.height, kPanel);
  draw_map(canvas, shader, nx, ny, s, l.map_w, l.map_h);
  if (labels) draw_panel(canvas, l, *labels);
  detail::write_png_atomically(
      path, l.width, l.height, 8, PNG_COLOR_TYPE_RGB, 3, [&](int row, unsigned char* out) {
        std::copy_n(canvas.row(row), static_cast<std::size_t>(l.width) * 3, out);
      });
}

}  // namespace erg::io

// SPDX-License-Identifier: Apache-2.0
// Hillshaded previews: size and reduction, north-up orientation, lighting
// from the north-west, periodic slopes at the edges, and the ground colours;
// the labelled previews of a run: size, scale bar, legend, labels, wind.
#include <gtest/gtest.h>
#include <png.h>

#include <chrono>
#include <cmath>
#include <cstdint>
#include <iostream>
#include <numbers>
#include <string>
#include <vector>

#include "io/io.h"
#include "test_util.h"

namespace erg::io {
namespace {

using testing::decode_png;
using testing::DecodedPng;
using testing::TempDir;

struct Terrain {
  int nx, ny;
  std::vector<float> bedrock, sand, vegetation;
  Terrain(int nx_, int ny_)
      : nx(nx_),
        ny(ny_),
        bedrock(static_cast<std::size_t>(nx_) * ny_, 0.0f),
        sand(bedrock.size(), 0.0f),
        vegetation(bedrock.size(), 0.0f) {}
  std::size_t at(int x, int y) const { return static_cast<std::size_t>(y) * nx + x; }
};

struct Pixel {
  int r, g, b;
  int brightness() const { return r + g + b; }
  int yellowness() const { return (r + g) / 2 - b; }
};

// Pixel of cell column x, image row `row` (0 = top = north).
Pixel pixel(const DecodedPng& png, int x, int row) {
  const std::size_t i = (static_cast<std::size_t>(row) * png.width + x) * 3;
  return {png.bytes[i], png.bytes[i + 1], png.bytes[i + 2]};
}

// Pixel showing grid cell (x, y): north up, so y = ny - 1 is the top row.
Pixel cell(const DecodedPng& png, int x, int y) {
  return pixel(png, x, static_cast<int>(png.height) - 1 - y);
}

DecodedPng render(const TempDir& dir, const Terrain& t, double cell_size = 1.0, int max_px = 2048,
                  const std::string& name = "preview.png") {
  const std::string path = dir.file(name);
  write_preview_png(path, t.nx, t.ny, cell_size, t.bedrock.data(), t.sand.data(),
                    t.vegetation.data(), max_px);
  DecodedPng png = decode_png(path);
  EXPECT_TRUE(png.ok) << path;
  return png;
}

TEST(Preview, OnePixelPerCellRgb8) {
  TempDir dir;
  DecodedPng png = render(dir, Terrain(40, 25));
  EXPECT_EQ(png.width, 40u);
  EXPECT_EQ(png.height, 25u);
  EXPECT_EQ(png.format, static_cast<std::uint32_t>(PNG_FORMAT_RGB));  // 8-bit RGB, no alpha
  EXPECT_EQ(dir.entries(), std::set<std::string>{"preview.png"});
}

TEST(Preview, LargeGridsAreReducedByAnIntegerFactor) {
  TempDir dir;
  // Longest side 300 > 64: factor ceil(300 / 64) = 5, so 60 x 26 pixels.
  DecodedPng png = render(dir, Terrain(300, 130), 1.0, 64);
  EXPECT_EQ(png.width, 60u);
  EXPECT_EQ(png.height, 26u);
  // Tall grid, exact factor 2.
  png = render(dir, Terrain(50, 200), 1.0, 100);
  EXPECT_EQ(png.width, 25u);
  EXPECT_EQ(png.height, 100u);
}

TEST(Preview, ReductionAveragesColours) {
  // Flat bare rock with one fully vegetated column at x = 1: reduced by 2,
  // the first pixel averages a rock cell and a green cell.
  TempDir dir;
  Terrain t(64, 8);
  for (int y = 0; y < t.ny; ++y) t.vegetation[t.at(1, y)] = 1.0f;
  DecodedPng full = render(dir, t, 1.0, 2048, "full.png");
  DecodedPng half = render(dir, t, 1.0, 32, "half.png");
  ASSERT_EQ(half.width, 32u);
  ASSERT_EQ(half.height, 4u);
  const Pixel rock = cell(full, 0, 0), green = cell(full, 1, 0), mixed = cell(half, 0, 0);
  EXPECT_NEAR(mixed.r, (rock.r + green.r) / 2.0, 1.0);
  EXPECT_NEAR(mixed.g, (rock.g + green.g) / 2.0, 1.0);
  EXPECT_NEAR(mixed.b, (rock.b + green.b) / 2.0, 1.0);
  EXPECT_NE(mixed.g, rock.g);
}

TEST(Preview, FlatBedrockHasTheDocumentedShade) {
  // Flat ground: lambert = sin(45 deg), light = 0.35 + 0.65 * 0.7071 = 0.8096
  // on bedrock grey (150, 140, 130).
  TempDir dir;
  DecodedPng png = render(dir, Terrain(8, 8));
  const Pixel p = cell(png, 3, 3);
  EXPECT_EQ(p.r, 121);
  EXPECT_EQ(p.g, 113);
  EXPECT_EQ(p.b, 105);
}

TEST(Preview, LitFromTheNorthWest) {
  // A round hill: its north-west flank faces the light, the south-east one
  // faces away; north-east and south-west flanks are lit equally.
  TempDir dir;
  Terrain t(64, 64);
  for (int y = 0; y < t.ny; ++y) {
    for (int x = 0; x < t.nx; ++x) {
      const double r2 = (x - 32.0) * (x - 32.0) + (y - 32.0) * (y - 32.0);
      t.bedrock[t.at(x, y)] = static_cast<float>(20.0 * std::exp(-r2 / (2 * 8.0 * 8.0)));
    }
  }
  DecodedPng png = render(dir, t);
  const Pixel nw = cell(png, 24, 40), se = cell(png, 40, 24);
  const Pixel ne = cell(png, 40, 40), sw = cell(png, 24, 24);
  const Pixel flat = cell(png, 0, 0);
  EXPECT_GT(nw.brightness(), flat.brightness() + 30);
  EXPECT_LT(se.brightness(), flat.brightness() - 30);
  EXPECT_NEAR(ne.brightness(), sw.brightness(), 3);
  // The same heights over 100 m cells are gentle slopes: shading uses the
  // true cell size, so the flank is only a little brighter than flat ground.
  DecodedPng wide = render(dir, t, 100.0, 2048, "wide.png");
  EXPECT_GT(cell(wide, 24, 40).brightness(), flat.brightness());
  EXPECT_LT(cell(wide, 24, 40).brightness(), nw.brightness() - 20);
}

TEST(Preview, NorthIsUp) {
  // Sand only in the northern half: the top image rows are sandy.
  TempDir dir;
  Terrain t(16, 16);
  for (int y = 8; y < 16; ++y) {
    for (int x = 0; x < 16; ++x) t.sand[t.at(x, y)] = 1.0f;
  }
  DecodedPng png = render(dir, t);
  EXPECT_GT(pixel(png, 5, 2).yellowness(), pixel(png, 5, 13).yellowness() + 30);
}

TEST(Preview, SandIsYellowAndThickSandIsOchre) {
  TempDir dir;
  Terrain t(6, 1);
  const float thickness[] = {0.0f, 0.05f, 0.5f, 3.0f, 10.0f, 50.0f};
  for (int x = 0; x < 6; ++x) t.sand[t.at(x, 0)] = thickness[x];
  // Bedrock compensates so the surface is flat and only colour differs.
  for (int x = 0; x < 6; ++x) t.bedrock[t.at(x, 0)] = 100.0f - thickness[x];
  DecodedPng png = render(dir, t);
  const Pixel rock = cell(png, 0, 0), veneer = cell(png, 1, 0);
  EXPECT_GT(veneer.yellowness(), rock.yellowness() + 20) << "5 cm of sand already looks sandy";
  for (int x = 2; x < 5; ++x) {
    EXPECT_GT(cell(png, x, 0).yellowness(), cell(png, x - 1, 0).yellowness()) << x;
  }
  // >= 10 m is fully ochre: 10 m and 50 m look the same, (205,140,70) * 0.8096.
  const Pixel deep = cell(png, 4, 0), deeper = cell(png, 5, 0);
  EXPECT_EQ(deep.r, deeper.r);
  EXPECT_EQ(deep.g, deeper.g);
  EXPECT_EQ(deep.b, deeper.b);
  EXPECT_EQ(deep.r, 166);
  EXPECT_EQ(deep.g, 113);
  EXPECT_EQ(deep.b, 57);
}

TEST(Preview, VegetationIsGreen) {
  TempDir dir;
  Terrain t(2, 1);
  t.sand = {2.0f, 2.0f};
  t.vegetation = {0.0f, 0.8f};
  DecodedPng png = render(dir, t);
  const Pixel bare = cell(png, 0, 0), green = cell(png, 1, 0);
  EXPECT_GT(green.g - (green.r + green.b) / 2, bare.g - (bare.r + bare.b) / 2 + 20);
}

TEST(Preview, SlopesWrapAroundTheEdges) {
  // On a torus, rolling the terrain rolls the image: a renderer that clamped
  // slopes at the edges would shade the edge columns differently.
  TempDir dir;
  Terrain a(48, 8), b(48, 8);
  const int shift = 5;
  for (int y = 0; y < 8; ++y) {
    for (int x = 0; x < 48; ++x) {
      const float h =
          static_cast<float>(5.0 * std::sin(2 * std::numbers::pi * (x + 0.3 * y) / 48.0));
      a.bedrock[a.at(x, y)] = h;
      b.bedrock[b.at((x + shift) % 48, y)] = h;
    }
  }
  DecodedPng pa = render(dir, a, 1.0, 2048, "a.png"), pb = render(dir, b, 1.0, 2048, "b.png");
  for (int y = 0; y < 8; ++y) {
    for (int x = 0; x < 48; ++x) {
      const Pixel p = cell(pa, x, y), q = cell(pb, (x + shift) % 48, y);
      ASSERT_EQ(p.r, q.r) << x << "," << y;
      ASSERT_EQ(p.g, q.g) << x << "," << y;
      ASSERT_EQ(p.b, q.b) << x << "," << y;
    }
  }
  // And the slopes at the edge columns are not flat.
  EXPECT_NE(cell(pa, 0, 0).brightness(), cell(pa, 24, 0).brightness());
}

TEST(Preview, InvalidArgumentsThrow) {
  TempDir dir;
  Terrain t(4, 4);
  const std::string p = dir.file("p.png");
  EXPECT_THROW(write_preview_png(p, 0, 4, 1.0, t.bedrock.data(), t.sand.data(), nullptr), IoError);
  EXPECT_THROW(write_preview_png(p, 4, 4, 0.0, t.bedrock.data(), t.sand.data(), nullptr), IoError);
  EXPECT_THROW(write_preview_png(p, 4, 4, 1.0, nullptr, t.sand.data(), nullptr), IoError);
  EXPECT_THROW(write_preview_png(p, 4, 4, 1.0, t.bedrock.data(), t.sand.data(), nullptr, 0),
               IoError);
  EXPECT_TRUE(dir.entries().empty());
  // Vegetation is optional.
  write_preview_png(p, 4, 4, 1.0, t.bedrock.data(), t.sand.data(), nullptr);
  EXPECT_TRUE(decode_png(p).ok);
}

// ---- labelled previews --------------------------------------------------------
// Dunes: sand ridges 40 cells apart on flat bedrock.
Terrain dunes(int nx, int ny) {
  Terrain t(nx, ny);
  for (int y = 0; y < ny; ++y)
    for (int x = 0; x < nx; ++x)
      t.sand[t.at(x, y)] = static_cast<float>(
          2.0 + 1.5 * std::sin(2 * std::numbers::pi * x / 40.0 + 0.3 * std::sin(y / 9.0)));
  return t;
}

DecodedPng render_labelled(const TempDir& dir, const Terrain& t, const PreviewLabels& labels,
                           const std::string& name = "labelled.png", double cell_size = 1.0) {
  const std::string path = dir.file(name);
  write_preview_png(path, t.nx, t.ny, cell_size, t.bedrock.data(), t.sand.data(),
                    t.vegetation.data(), 2048, &labels);
  DecodedPng png = decode_png(path);
  EXPECT_TRUE(png.ok) << path;
  return png;
}

bool is(const Pixel& p, int r, int g, int b, int tol = 0) {
  return std::abs(p.r - r) <= tol && std::abs(p.g - g) <= tol && std::abs(p.b - b) <= tol;
}

// The centroid of the pixels of colour (r, g, b) in a square around (cx, cy).
struct Centroid {
  double x = 0, y = 0;
  int n = 0;
};
Centroid centroid(const DecodedPng& png, int cx, int cy, int half, int r, int g, int b) {
  Centroid c;
  for (int y = cy - half; y <= cy + half; ++y)
    for (int x = cx - half; x <= cx + half; ++x)
      if (is(pixel(png, x, y), r, g, b)) {
        c.x += x;
        c.y += y;
        ++c.n;
      }
  if (c.n) c.x /= c.n, c.y /= c.n;
  return c;
}

TEST(LabelledPreview, DefaultJobIsUpscaledWithAScaleBarInRoundMetres) {
  TempDir dir;
  PreviewLabels labels;
  labels.step = 2500;
  labels.time_days = 3.2 * 365.25;
  labels.wind_x = 1;
  // The default job's 256 x 192 cells of 1 m: 3 px per cell, 768 x 576 of map.
  const DecodedPng png = render_labelled(dir, dunes(256, 192), labels);
  const PreviewLayout l = preview_layout(256, 192, 1.0);
  EXPECT_EQ(png.width, 768u);
  EXPECT_EQ(png.height, 576u + 72u);
  EXPECT_EQ(l.map_w, 768);
  EXPECT_EQ(l.map_h, 576);
  EXPECT_EQ(png.height, static_cast<unsigned>(l.height));
  // A fifth of 256 m is 51.2 m: the bar is 50 m, 150 px at 1/3 m a pixel.
  EXPECT_DOUBLE_EQ(l.bar_m, 50.0);
  EXPECT_EQ(l.bar_px, 150);
  // Found by its pixels: the longest white run of the panel is the bar.
  int best = 0, best_x = -1, best_y = -1;
  for (int y = l.map_h; y < l.height; ++y)
    for (int x = 0, run = 0; x < l.width; ++x) {
      run = is(pixel(png, x, y), 255, 255, 255) ? run + 1 : 0;
      if (run > best) best = run, best_x = x - run + 1, best_y = y;
    }
  EXPECT_EQ(best, 150);
  EXPECT_EQ(best_x, l.bar_x);
  EXPECT_GE(best_y, l.bar_y);
  EXPECT_LT(best_y, l.bar_y + 6);
  // Its label ("50 m") is white text above it.
  int label_px = 0;
  for (int y = l.map_h; y < l.bar_y; ++y)
    for (int x = l.bar_x; x < l.bar_x + 60; ++x) label_px += is(pixel(png, x, y), 255, 255, 255);
  EXPECT_GT(label_px, 40);
  // The map above is terrain, never pure white.
  for (int y = 0; y < l.map_h; y += 7)
    for (int x = 0; x < l.map_w; x += 5) ASSERT_FALSE(is(pixel(png, x, y), 255, 255, 255));
}

TEST(LabelledPreview, LegendShowsTheSandColoursOfLevelGround) {
  TempDir dir;
  PreviewLabels labels;
  const DecodedPng png = render_labelled(dir, dunes(256, 192), labels);
  const PreviewLayout l = preview_layout(256, 192, 1.0);
  const int y = l.legend_y + l.legend_h / 2;
  // Flat ground is lit by 0.35 + 0.65 sin(45 deg) = 0.8096: no sand is
  // bedrock grey (150, 140, 130), 10 m of sand deep ochre (205, 140, 70).
  const Pixel none = pixel(png, l.legend_x, y), thick = pixel(png, l.legend_x + l.legend_w - 1, y);
  EXPECT_TRUE(is(none, 121, 113, 105, 1)) << none.r << "," << none.g << "," << none.b;
  EXPECT_TRUE(is(thick, 166, 113, 57, 1)) << thick.r << "," << thick.g << "," << thick.b;
  // Thicker to the right: yellowness grows from the pale sand on.
  const Pixel pale = pixel(png, l.legend_x + l.legend_w / 4, y);
  EXPECT_GT(pale.yellowness(), none.yellowness());
  EXPECT_GT(thick.yellowness(), pale.yellowness());
  // One column of the gradient is one colour from top to bottom.
  for (int k = 0; k < l.legend_h; ++k)
    EXPECT_TRUE(
        is(pixel(png, l.legend_x + 90, l.legend_y + k), pixel(png, l.legend_x + 90, l.legend_y).r,
           pixel(png, l.legend_x + 90, l.legend_y).g, pixel(png, l.legend_x + 90, l.legend_y).b));
}

TEST(LabelledPreview, StepAndTimeAreWritten) {
  TempDir dir;
  PreviewLabels a, b;
  a.step = 5;
  b.step = 2500;
  b.time_days = 800;
  const Terrain t = dunes(64, 64);
  const DecodedPng pa = render_labelled(dir, t, a, "a.png"),
                   pb = render_labelled(dir, t, b, "b.png");
  const PreviewLayout l = preview_layout(64, 64, 1.0);
  // "step 2500" is four glyphs wider than "step 5": more white pixels, and
  // the second line ("0 d" against "2.2 yr") differs too.
  const auto white = [&](const DecodedPng& p, int y0, int y1) {
    int n = 0;
    for (int y = y0; y < y1; ++y)
      for (int x = l.label_x; x < l.wind_cx - l.wind_r - 8; ++x)
        n += is(pixel(p, x, y), 255, 255, 255);
    return n;
  };
  EXPECT_GT(white(pa, l.map_h + 10, l.map_h + 24), 60);
  EXPECT_GT(white(pb, l.map_h + 10, l.map_h + 24), white(pa, l.map_h + 10, l.map_h + 24) + 40);
  EXPECT_GT(white(pa, l.map_h + 36, l.map_h + 50), 20);
  EXPECT_NE(white(pa, l.map_h + 36, l.map_h + 50), white(pb, l.map_h + 36, l.map_h + 50));
}

TEST(LabelledPreview, TheArrowPointsWhereTheWindBlows) {
  TempDir dir;
  const Terrain t = dunes(128, 96);
  const PreviewLayout l = preview_layout(128, 96, 1.0);
  const auto arrow = [&](double wx, double wy, const std::string& name) {
    PreviewLabels labels;
    labels.wind_x = wx;
    labels.wind_y = wy;
    return centroid(render_labelled(dir, t, labels, name), l.wind_cx, l.wind_cy, l.wind_r, 230, 60,
                    40);
  };
  // The arrowhead pulls the centroid towards where the wind goes.
  const Centroid east = arrow(3, 0, "e.png"), west = arrow(-3, 0, "w.png");
  const Centroid north = arrow(0, 2, "n.png");
  ASSERT_GT(east.n, 50);
  EXPECT_EQ(east.n, west.n);  // the same arrow, turned
  EXPECT_GT(east.x, l.wind_cx + 3);
  EXPECT_LT(west.x, l.wind_cx - 3);
  EXPECT_NEAR(east.y, l.wind_cy, 0.5);
  EXPECT_NEAR(east.x - l.wind_cx, l.wind_cx - west.x, 0.5);
  EXPECT_LT(north.y, l.wind_cy - 3);  // north is up
  EXPECT_NEAR(north.x, l.wind_cx, 0.5);
  // No wind, no arrow.
  EXPECT_EQ(arrow(0, 0, "calm.png").n, 0);
}

TEST(LabelledPreview, AMultiDirectionalRegimeHasARose) {
  TempDir dir;
  const Terrain t = dunes(128, 96);
  const PreviewLayout l = preview_layout(128, 96, 1.0);
  PreviewLabels labels;
  labels.wind_x = 1;
  const DecodedPng single = render_labelled(dir, t, labels, "single.png");
  labels.rose = {{90, 0.5}, {210, 0.25}, {330, 0.25}};
  const DecodedPng rose = render_labelled(dir, t, labels, "rose.png");
  EXPECT_EQ(centroid(single, l.wind_cx, l.wind_cy, l.wind_r, 110, 160, 210).n, 0);
  const Centroid spokes = centroid(rose, l.wind_cx, l.wind_cy, l.wind_r, 110, 160, 210);
  EXPECT_GT(spokes.n, 20);
  // The longest spoke (half the wind, towards north) is up.
  EXPECT_LT(spokes.y, l.wind_cy - 2);
}

TEST(LabelledPreview, UpscalingShadesEachPixelNotBlocks) {
  TempDir dir;
  const DecodedPng png = render_labelled(dir, dunes(64, 48), PreviewLabels{});
  const PreviewLayout l = preview_layout(64, 48, 1.0);
  ASSERT_EQ(l.map_w, 768);  // 12 px per cell
  ASSERT_EQ(l.map_h, 576);
  // Within a cell's 12 x 12 block the slope-lit colour varies smoothly: the
  // pixels of one block are not all one colour (nearest-neighbour blocks).
  int varied = 0, blocks = 0;
  for (int by = 0; by < 48; by += 5)
    for (int bx = 0; bx < 64; bx += 3) {
      const Pixel a = pixel(png, bx * 12 + 1, by * 12 + 1);
      const Pixel b = pixel(png, bx * 12 + 10, by * 12 + 1);
      ++blocks;
      varied += a.brightness() != b.brightness() || a.yellowness() != b.yellowness();
    }
  EXPECT_GT(varied, blocks * 3 / 4) << varied << " of " << blocks;
  // And neighbouring pixels differ by little: no seams at cell edges (away
  // from the domain's edge, where 64 cells are not a whole number of ridges).
  int worst = 0;
  for (int x = 24; x + 24 < l.map_w; ++x)
    worst = std::max(
        worst, std::abs(pixel(png, x, 300).brightness() - pixel(png, x + 1, 300).brightness()));
  EXPECT_LT(worst, 12);
}

TEST(LabelledPreview, BigGridsKeepOnePixelPerCellAndAreCheap) {
  TempDir dir;
  const auto time_one = [&](int nx, int ny) {
    const Terrain t = dunes(nx, ny);
    const auto t0 = std::chrono::steady_clock::now();
    const DecodedPng png = render_labelled(dir, t, PreviewLabels{}, "big.png");
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::cout << "labelled preview " << nx << " x " << ny << ": " << png.width << " x "
              << png.height << " px, " << s * 1000 << " ms (write + decode)\n";
    return png;
  };
  DecodedPng png = time_one(256, 192);
  EXPECT_EQ(png.width, 768u);
  png = time_one(1024, 1024);
  EXPECT_EQ(png.width, 1024u);
  EXPECT_EQ(png.height, 1024u + 72u);
  // Narrow and tall: the panel keeps its 768 px.
  png = render_labelled(dir, Terrain(100, 3000), PreviewLabels{}, "tall.png");
  EXPECT_EQ(png.width, 768u);  // the map (50 px after halving) and the panel's width
  EXPECT_EQ(png.height, 1500u + 72u);
}

}  // namespace
}  // namespace erg::io

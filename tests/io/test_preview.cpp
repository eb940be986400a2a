// SPDX-License-Identifier: Apache-2.0
// Hillshaded previews: size and reduction, north-up orientation, lighting
// from the north-west, periodic slopes at the edges, and the ground colours.
#include <gtest/gtest.h>
#include <png.h>

#include <cmath>
#include <cstdint>
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

}  // namespace
}  // namespace erg::io

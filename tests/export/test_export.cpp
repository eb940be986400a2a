// SPDX-License-Identifier: Apache-2.0
// erg_export and the map-fitting helpers of erg_io: EXR files read back with
// the OpenEXR C++ API (not erg's code), the samples of heights_for_export,
// and the seam test, border cross-fade and periodic resampling of input maps.
#include <ImathBox.h>
#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfStringAttribute.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "../common/temp_dir.h"
#include "export/export.h"
#include "io/io.h"

namespace {

using erg::exporting::Format;
using erg::exporting::Layer;
using erg::exporting::Request;
using erg::test_support::TempDir;

constexpr int kNx = 40, kNy = 24;

// A run directory with one snapshot at step 7: bedrock + sand is exact in float32.
std::string make_run(const TempDir& dir) {
  std::filesystem::create_directories(dir.file("run/snapshots"));
  erg::io::SnapshotMeta meta;
  meta.step = 7;
  meta.time_days = 1.5;
  meta.cell_size_m = 0.5;
  meta.nx = kNx;
  meta.ny = kNy;
  meta.job_spec_json = "{\"name\": \"exr\"}";
  meta.erg_version = "test";
  meta.unit_m = 1.0 / 4294967296.0;
  meta.sand_units_total = meta.bedrock_units_total = meta.airborne_units_total = "0";
  meta.backend = "cpu";
  std::vector<float> b, s, v, w;
  for (int y = 0; y < kNy; ++y)
    for (int x = 0; x < kNx; ++x) {
      b.push_back(static_cast<float>(y * 64 + x) * 0.25f);
      s.push_back(static_cast<float>((x * 5 + y) % 9) * 0.125f);
      v.push_back(0);
      w.push_back(0);
      w.push_back(0);
    }
  erg::io::SnapshotFields f;
  f[erg::fields::kBedrock].data = b.data();
  f[erg::fields::kSand].data = s.data();
  f[erg::fields::kVegetation].data = v.data();
  f[erg::fields::kWindX] = {w.data(), 2, 0};
  f[erg::fields::kWindY] = {w.data(), 2, 1};
  erg::io::write_snapshot(dir.file("run/snapshots/step_00000007.h5"), meta, f);
  return dir.file("run");
}

float height(int x, int y) {
  x = ((x % kNx) + kNx) % kNx;
  y = ((y % kNy) + kNy) % kNy;
  return static_cast<float>(y * 64 + x) * 0.25f + static_cast<float>((x * 5 + y) % 9) * 0.125f;
}

// Reads channel `name` with the OpenEXR API; rows north first.
std::vector<float> read_exr(const std::string& path, const char* name, int* w, int* h,
                            Imf::Header* header) {
  Imf::InputFile file(path.c_str());
  *header = file.header();
  const Imath::Box2i dw = file.header().dataWindow();
  *w = dw.max.x - dw.min.x + 1;
  *h = dw.max.y - dw.min.y + 1;
  std::vector<float> px(static_cast<std::size_t>(*w) * *h);
  Imf::FrameBuffer fb;
  fb.insert(name, Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(px.data()), sizeof(float),
                             sizeof(float) * static_cast<std::size_t>(*w)));
  file.setFrameBuffer(fb);
  file.readPixels(dw.min.y, dw.max.y);
  return px;
}

TEST(ExportExr, ReadBackByOpenExrEqualsTheSnapshot) {
  TempDir dir;
  Request r;
  r.dir = make_run(dir);
  r.format = Format::kExr;
  r.out = dir.file("h.exr");
  const auto files = erg::exporting::run_export(r);
  ASSERT_EQ(files, std::vector<std::string>{r.out});
  int w = 0, h = 0;
  Imf::Header header;
  const auto px = read_exr(r.out, "Y", &w, &h, &header);
  ASSERT_EQ(w, kNx);
  ASSERT_EQ(h, kNy);
  EXPECT_EQ(header.compression(), Imf::ZIP_COMPRESSION);
  ASSERT_NE(header.channels().findChannel("Y"), nullptr);
  EXPECT_EQ(header.channels().findChannel("Y")->type, Imf::FLOAT);
  EXPECT_EQ(header.typedAttribute<Imf::StringAttribute>("ergStep").value(), "7");
  EXPECT_EQ(header.typedAttribute<Imf::StringAttribute>("ergJobSpec").value(),
            "{\"name\": \"exr\"}");
  for (int r0 = 0; r0 < h; ++r0)
    for (int x = 0; x < w; ++x)
      ASSERT_EQ(px[static_cast<std::size_t>(r0) * w + x], height(x, kNy - 1 - r0))
          << x << "," << r0;
  // And erg's own EXR map reader agrees (row 0 = south).
  const erg::io::Map m = erg::io::read_exr_map(r.out);
  ASSERT_EQ(m.nx, kNx);
  for (int y = 0; y < kNy; ++y)
    for (int x = 0; x < kNx; ++x)
      ASSERT_EQ(m.values[static_cast<std::size_t>(y) * kNx + x], height(x, y));
}

TEST(ExportExr, TilesShareBordersAndWrap) {
  TempDir dir;
  Request r;
  r.dir = make_run(dir);
  r.format = Format::kExr;
  r.out = dir.file("t.exr");
  r.tiles_x = 4;
  r.tiles_y = 2;
  ASSERT_EQ(erg::exporting::run_export(r).size(), 8u);
  int w = 0, h = 0;
  Imf::Header hd;
  // Tile x3_y0: the north-east tile; its extra column wraps to x = 0 and its
  // top row is the world's north row... plus one (y = 0, wrapped).
  const auto px = read_exr(erg::exporting::tile_path(r.out, 3, 0), "Y", &w, &h, &hd);
  ASSERT_EQ(w, kNx / 4 + 1);
  ASSERT_EQ(h, kNy / 2 + 1);
  for (int r0 = 0; r0 < h; ++r0)
    for (int x = 0; x < w; ++x)
      ASSERT_EQ(px[static_cast<std::size_t>(r0) * w + x], height(30 + x, kNy - r0))
          << x << "," << r0;
}

TEST(HeightsForExport, ExactCopyThenBilinearUpsample) {
  TempDir dir;
  const auto snap = erg::io::read_snapshot(make_run(dir) + "/snapshots/step_00000007.h5", true);
  int nx = 0, ny = 0;
  const auto a =
      erg::exporting::heights_for_export(snap, Layer::kHeight, {38, 20, 5, 6}, 1, &nx, &ny);
  ASSERT_EQ(nx, 6);
  ASSERT_EQ(ny, 7);
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i)
      ASSERT_EQ(a[static_cast<std::size_t>(j) * nx + i], height(38 + i, 20 + j));
  const auto b =
      erg::exporting::heights_for_export(snap, Layer::kHeight, {4, 4, 3, 3}, 4, &nx, &ny);
  ASSERT_EQ(nx, 13);
  // Sample (2, 2) at cell-centre coordinate 4 + 2.5 / 4 - 0.5 = 4.125.
  const double t = 0.125;
  const double want = (1 - t) * ((1 - t) * height(4, 4) + t * height(5, 4)) +
                      t * ((1 - t) * height(4, 5) + t * height(5, 5));
  EXPECT_NEAR(b[2 * 13 + 2], want, 1e-5);
}

TEST(ExportErrors, MissingStepNamesTheStepsThereAre) {
  TempDir dir;
  Request r;
  r.dir = make_run(dir);
  r.step = 8;
  r.out = dir.file("x.tif");
  try {
    erg::exporting::run_export(r);
    FAIL() << "no error";
  } catch (const erg::exporting::ExportError& e) {
    EXPECT_NE(std::string(e.what()).find("no snapshot of that step; steps: 7"), std::string::npos)
        << e.what();
  }
  EXPECT_FALSE(std::filesystem::exists(r.out));
}

// ---- map fitting ---------------------------------------------------------------------

erg::io::Map ramp(int nx, int ny) {
  erg::io::Map m;
  m.nx = nx;
  m.ny = ny;
  for (int y = 0; y < ny; ++y)
    for (int x = 0; x < nx; ++x) m.values.push_back(x);
  return m;
}

TEST(MapFit, SeamOfARampAndBlendClosesIt) {
  erg::io::Map m = ramp(20, 10);
  const auto s = erg::io::seam_of(m, 0);
  EXPECT_DOUBLE_EQ(s.jump, 19);
  EXPECT_DOUBLE_EQ(s.interior, 1);
  EXPECT_DOUBLE_EQ(erg::io::seam_of(m, 1).jump, 0);
  erg::io::blend_borders(m, 4, 0);
  EXPECT_DOUBLE_EQ(erg::io::seam_of(m, 0).jump, 0);
  EXPECT_DOUBLE_EQ(m.values[0], 9.5);  // both sides meet at their mean
  EXPECT_DOUBLE_EQ(m.values[19], 9.5);
  EXPECT_DOUBLE_EQ(m.values[4], 4);  // outside the band: untouched
  EXPECT_DOUBLE_EQ(m.values[1], 0.625 * 1 + 0.375 * 18);
}

TEST(MapFit, PeriodicResampleKeepsAWaveAndWraps) {
  erg::io::Map m;
  m.nx = 16;
  m.ny = 4;
  for (int y = 0; y < 4; ++y)
    for (int x = 0; x < 16; ++x) m.values.push_back(x == 0 ? 1.0 : 0.0);
  const auto r = erg::io::resample_periodic(m, 32, 8);
  ASSERT_EQ(r.values.size(), 32u * 8u);
  // Cell 0's centre is at map coordinate -0.25: 3/4 of pixel 0, 1/4 of pixel 15.
  EXPECT_DOUBLE_EQ(r.values[0], 0.75);
  EXPECT_DOUBLE_EQ(r.values[31], 0.25);  // wraps: the east edge sees pixel 0
  EXPECT_DOUBLE_EQ(r.values[1], 0.75);
  EXPECT_DOUBLE_EQ(r.values[2], 0.25);
  EXPECT_DOUBLE_EQ(r.values[10], 0);
}

}  // namespace

// SPDX-License-Identifier: Apache-2.0
// Input maps: HDF5 datasets of any numeric type, 8/16-bit greyscale and RGB
// PNGs (first image row = north), the 16-bit PNG writer, and clear errors.
#include <gtest/gtest.h>
#include <hdf5.h>
#include <png.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <functional>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "io/io.h"
#include "test_util.h"

namespace erg::io {
namespace {

using testing::decode_png;
using testing::TempDir;

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const IoError& e) {
    return e.what();
  }
  return "no IoError";
}

// Writes `data` as dataset `name` (creating intermediate groups) of the given
// HDF5 type and shape, into a new file.
void make_h5(const std::string& path, const std::string& name, hid_t type,
             const std::vector<hsize_t>& dims, const void* data) {
  hid_t f = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
  ASSERT_GE(f, 0);
  hid_t lcpl = H5Pcreate(H5P_LINK_CREATE);
  H5Pset_create_intermediate_group(lcpl, 1);
  hid_t space = H5Screate_simple(static_cast<int>(dims.size()), dims.data(), nullptr);
  hid_t d = H5Dcreate2(f, name.c_str(), type, space, lcpl, H5P_DEFAULT, H5P_DEFAULT);
  ASSERT_GE(d, 0);
  ASSERT_GE(H5Dwrite(d, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data), 0);
  H5Dclose(d);
  H5Sclose(space);
  H5Pclose(lcpl);
  H5Fclose(f);
}

// ---- HDF5 maps ----------------------------------------------------------------

TEST(Hdf5Map, ReadsInt16) {
  TempDir dir;
  const int nx = 7, ny = 3;
  std::vector<std::int16_t> v;
  for (int i = 0; i < nx * ny; ++i) v.push_back(static_cast<std::int16_t>(i * 1000 - 10000));
  v[5] = std::numeric_limits<std::int16_t>::min();
  v[6] = std::numeric_limits<std::int16_t>::max();
  const std::string path = dir.file("m.h5");
  make_h5(path, "/maps/bedrock", H5T_NATIVE_INT16, {ny, nx}, v.data());
  const Map m = read_hdf5_map(path, "/maps/bedrock");
  EXPECT_EQ(m.nx, nx);
  EXPECT_EQ(m.ny, ny);
  ASSERT_EQ(m.values.size(), v.size());
  for (std::size_t i = 0; i < v.size(); ++i) EXPECT_EQ(m.values[i], v[i]) << i;
  // The same dataset by a relative name.
  EXPECT_EQ(read_hdf5_map(path, "maps/bedrock").values, m.values);
}

TEST(Hdf5Map, ReadsFloat64Exactly) {
  TempDir dir;
  const int nx = 4, ny = 5;
  std::vector<double> v;
  for (int i = 0; i < nx * ny; ++i) v.push_back(std::ldexp(1.0, -40) * i + 0.1 * i - 3.0);
  v[0] = -0.0;
  const std::string path = dir.file("m.h5");
  make_h5(path, "h", H5T_NATIVE_DOUBLE, {ny, nx}, v.data());
  const Map m = read_hdf5_map(path, "h");
  EXPECT_EQ(m.nx, nx);
  EXPECT_EQ(m.ny, ny);
  EXPECT_EQ(m.values, v);
  // Row-major [ny][nx] as stored: row 0 is y = 0.
  EXPECT_EQ(m.values[1 * nx + 2], v[6]);
}

TEST(Hdf5Map, ReadsUint8AndFloat32) {
  TempDir dir;
  std::vector<std::uint8_t> u = {0, 1, 254, 255};
  make_h5(dir.file("u.h5"), "u", H5T_NATIVE_UINT8, {2, 2}, u.data());
  EXPECT_EQ(read_hdf5_map(dir.file("u.h5"), "u").values, (std::vector<double>{0, 1, 254, 255}));
  std::vector<float> f = {0.5f, -1.25f, 3.0f};
  make_h5(dir.file("f.h5"), "f", H5T_NATIVE_FLOAT, {1, 3}, f.data());
  EXPECT_EQ(read_hdf5_map(dir.file("f.h5"), "f").values, (std::vector<double>{0.5, -1.25, 3.0}));
}

TEST(Hdf5Map, ErrorsNameFileAndDataset) {
  TempDir dir;
  const std::string missing = dir.file("missing.h5");
  std::string m = error_of([&] { read_hdf5_map(missing, "h"); });
  EXPECT_NE(m.find(missing), std::string::npos) << m;
  EXPECT_NE(m.find("No such file"), std::string::npos) << m;

  const std::string path = dir.file("m.h5");
  std::vector<float> cube(2 * 3 * 4, 1.0f);
  make_h5(path, "/a/cube", H5T_NATIVE_FLOAT, {2, 3, 4}, cube.data());

  m = error_of([&] { read_hdf5_map(path, "/a/height"); });
  EXPECT_NE(m.find(path), std::string::npos) << m;
  EXPECT_NE(m.find("'/a/height' not found"), std::string::npos) << m;
  m = error_of([&] { read_hdf5_map(path, "/nogroup/height"); });
  EXPECT_NE(m.find("'/nogroup/height' not found"), std::string::npos) << m;

  m = error_of([&] { read_hdf5_map(path, "/a/cube"); });
  EXPECT_NE(m.find(path), std::string::npos) << m;
  EXPECT_NE(m.find("'/a/cube'"), std::string::npos) << m;
  EXPECT_NE(m.find("rank 3"), std::string::npos) << m;

  m = error_of([&] { read_hdf5_map(path, "/a"); });
  EXPECT_NE(m.find("'/a'"), std::string::npos) << m;

  const std::string line = dir.file("line.h5");
  make_h5(line, "v", H5T_NATIVE_FLOAT, {4}, cube.data());
  m = error_of([&] { read_hdf5_map(line, "v"); });
  EXPECT_NE(m.find("rank 1"), std::string::npos) << m;

  const std::string text = dir.file("text.h5");
  testing::write_bytes(text, "plain text");
  m = error_of([&] { read_hdf5_map(text, "v"); });
  EXPECT_NE(m.find("not an HDF5 file"), std::string::npos) << m;
}

// ---- PNG maps -----------------------------------------------------------------

// Writes an 8-bit PNG of the given simplified-API format; rows top first.
void write_png8(const std::string& path, int w, int h, std::uint32_t format,
                const std::vector<std::uint8_t>& bytes) {
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  image.width = static_cast<png_uint_32>(w);
  image.height = static_cast<png_uint_32>(h);
  image.format = format;
  ASSERT_TRUE(png_image_write_to_file(&image, path.c_str(), 0, bytes.data(), 0, nullptr))
      << image.message;
}

TEST(PngMap, Png16RoundTripsWithinOneStep) {
  TempDir dir;
  const int nx = 33, ny = 17;
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<double> v(nx * ny);
  for (double& x : v) x = u(rng);
  v[0] = 0.0;
  v[1] = 1.0;
  const std::string path = dir.file("h.png");
  write_png16(path, nx, ny, v);
  EXPECT_EQ(dir.entries(), std::set<std::string>{"h.png"});

  const Map m = read_png_map(path);
  EXPECT_EQ(m.nx, nx);
  EXPECT_EQ(m.ny, ny);
  ASSERT_EQ(m.values.size(), v.size());
  for (std::size_t i = 0; i < v.size(); ++i) {
    EXPECT_NEAR(m.values[i], v[i], 0.5 / 65535 + 1e-12) << i;
  }
  EXPECT_EQ(m.values[0], 0.0);
  EXPECT_EQ(m.values[1], 1.0);
}

TEST(PngMap, Png16IsGrey16WithNorthAtTheTop) {
  // Check the written file with an independent decoder: 16-bit grey, and the
  // first image row holds y = ny - 1.
  TempDir dir;
  const int nx = 3, ny = 2;
  const std::vector<double> v = {0.0, 0.25, 0.5,     // y = 0 (south)
                                 1.0, 0.75, 0.125};  // y = 1 (north)
  const std::string path = dir.file("h.png");
  write_png16(path, nx, ny, v);
  auto png = decode_png(path);
  ASSERT_TRUE(png.ok);
  EXPECT_EQ(png.format, static_cast<std::uint32_t>(PNG_FORMAT_LINEAR_Y));  // 16-bit grey
  auto sample = [&](int x, int row) {
    std::uint16_t s = 0;
    std::memcpy(&s, png.bytes.data() + 2 * (row * nx + x), 2);  // host order from libpng
    return s;
  };
  EXPECT_EQ(sample(0, 0), 65535);  // top-left = (x 0, y 1)
  EXPECT_EQ(sample(2, 0), 8192);   // 0.125 * 65535 = 8191.9
  EXPECT_EQ(sample(0, 1), 0);
  EXPECT_EQ(sample(2, 1), 32768);  // 0.5 * 65535 = 32767.5, rounded half away
}

TEST(PngMap, Reads8BitGreyWithNorthAtTheTop) {
  TempDir dir;
  const std::string path = dir.file("g.png");
  write_png8(path, 2, 3, PNG_FORMAT_GRAY,
             {255, 128,  // top row: y = 2
              10, 20,    // y = 1
              0, 1});    // bottom row: y = 0
  const Map m = read_png_map(path);
  EXPECT_EQ(m.nx, 2);
  EXPECT_EQ(m.ny, 3);
  EXPECT_EQ(m.values,
            (std::vector<double>{0.0, 1 / 255.0, 10 / 255.0, 20 / 255.0, 1.0, 128 / 255.0}));
}

TEST(PngMap, RgbAndRgbaReadAsLuminance) {
  TempDir dir;
  // Grey pixels stored as RGB read exactly as grey; pure primaries give their
  // Rec. 709 weights; alpha is ignored.
  write_png8(dir.file("rgb.png"), 2, 1, PNG_FORMAT_RGB, {51, 51, 51, 0, 255, 0});
  Map m = read_png_map(dir.file("rgb.png"));
  ASSERT_EQ(m.values.size(), 2u);
  EXPECT_NEAR(m.values[0], 0.2, 1e-12);
  EXPECT_NEAR(m.values[1], 0.7152, 1e-12);
  write_png8(dir.file("rgba.png"), 1, 1, PNG_FORMAT_RGBA, {255, 255, 255, 0});
  m = read_png_map(dir.file("rgba.png"));
  ASSERT_EQ(m.values.size(), 1u);
  EXPECT_NEAR(m.values[0], 1.0, 1e-12);
}

TEST(PngMap, Errors) {
  TempDir dir;
  const std::string missing = dir.file("missing.png");
  std::string m = error_of([&] { read_png_map(missing); });
  EXPECT_NE(m.find(missing), std::string::npos) << m;
  EXPECT_NE(m.find("No such file"), std::string::npos) << m;

  const std::string text = dir.file("t.png");
  testing::write_bytes(text, "GIF89a not a png at all");
  m = error_of([&] { read_png_map(text); });
  EXPECT_NE(m.find("not a PNG"), std::string::npos) << m;

  // A PNG cut short: header fine, data missing.
  std::vector<double> v(64 * 64, 0.5);
  for (std::size_t i = 0; i < v.size(); ++i) v[i] = (i * 7919 % 65536) / 65535.0;
  write_png16(dir.file("ok.png"), 64, 64, v);
  const std::string bytes = testing::read_bytes(dir.file("ok.png"));
  const std::string cut = dir.file("cut.png");
  testing::write_bytes(cut, bytes.substr(0, bytes.size() / 2));
  m = error_of([&] { read_png_map(cut); });
  EXPECT_NE(m.find(cut), std::string::npos) << m;

  EXPECT_THROW(write_png16(dir.file("x.png"), 2, 2, {0.0, 1.0, 0.5}), IoError);
  EXPECT_THROW(write_png16(dir.file("x.png"), 2, 1, {0.0, std::nan("")}), IoError);
  EXPECT_THROW(write_png16(dir.file("x.png"), 0, 1, {}), IoError);
  EXPECT_EQ(dir.entries().count("x.png"), 0u);
}

}  // namespace
}  // namespace erg::io

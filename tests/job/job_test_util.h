// SPDX-License-Identifier: Apache-2.0
// Helpers shared by the job tests: a scratch directory per test, a minimal
// valid job, spec parsing with defaults, and writers of map files that do not
// go through erg's own io code (raw HDF5 C API, a hand-made 16-bit PNG).
#pragma once

#include <gtest/gtest.h>
#include <hdf5.h>
#include <unistd.h>
#include <zlib.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "../common/temp_dir.h"
#include "erg/v1/job.pb.h"
#include "job/spec.h"

namespace erg::job::testing {

namespace fs = std::filesystem;

struct TempDir : erg::test_support::TempDir {
  TempDir() : erg::test_support::TempDir("erg_job_test") {}
};

inline void write_text(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out << text;
}

// The smallest valid job: a 64 x 48 domain of 1 m cells and a constant wind.
inline const char* kMinimalJob = R"({
  "domain": {"nx": 64, "ny": 48, "cell_size_m": 1},
  "wind": {"constant": {"speed_mps": 10}}
})";

inline JobSpec minimal_spec() {
  JobSpec s = parse_json(kMinimalJob, "minimal");
  apply_defaults(s);
  return s;
}

// Parses JSON and fills defaults (as load_job_file does, without validating).
inline JobSpec parse_with_defaults(const std::string& json) {
  JobSpec s = parse_json(json, "test");
  apply_defaults(s);
  return s;
}

inline std::string join(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& p : v) s += p + "\n";
  return s;
}

// A 2-D dataset [ny][nx] of doubles, written with the HDF5 C API.
inline void write_h5_doubles(const std::string& path, const std::string& dataset, int nx, int ny,
                             const std::vector<double>& values) {
  ASSERT_EQ(values.size(), static_cast<size_t>(nx) * ny);
  hid_t f = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
  ASSERT_GE(f, 0);
  hid_t lcpl = H5Pcreate(H5P_LINK_CREATE);
  H5Pset_create_intermediate_group(lcpl, 1);
  const hsize_t dims[2] = {static_cast<hsize_t>(ny), static_cast<hsize_t>(nx)};
  hid_t space = H5Screate_simple(2, dims, nullptr);
  hid_t d =
      H5Dcreate2(f, dataset.c_str(), H5T_NATIVE_DOUBLE, space, lcpl, H5P_DEFAULT, H5P_DEFAULT);
  ASSERT_GE(d, 0);
  ASSERT_GE(H5Dwrite(d, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data()), 0);
  H5Dclose(d);
  H5Sclose(space);
  H5Pclose(lcpl);
  H5Fclose(f);
}

// A 16-bit greyscale PNG built byte by byte (zlib only): `rows` holds the
// samples in file order, the first image row first.
inline void write_png16_raw(const std::string& path, int width, int height,
                            const std::vector<std::uint16_t>& rows) {
  ASSERT_EQ(rows.size(), static_cast<size_t>(width) * height);
  auto be32 = [](std::string& s, std::uint32_t v) {
    for (int k = 3; k >= 0; --k) s.push_back(static_cast<char>((v >> (8 * k)) & 0xFF));
  };
  auto chunk = [&](std::string& out, const char* type, const std::string& data) {
    be32(out, static_cast<std::uint32_t>(data.size()));
    std::string td = std::string(type, 4) + data;
    out += td;
    be32(out, static_cast<std::uint32_t>(crc32(0, reinterpret_cast<const Bytef*>(td.data()),
                                               static_cast<uInt>(td.size()))));
  };
  std::string ihdr;
  be32(ihdr, static_cast<std::uint32_t>(width));
  be32(ihdr, static_cast<std::uint32_t>(height));
  ihdr +=
      std::string("\x10\x00\x00\x00\x00", 5);  // depth 16, grey, deflate, filter 0, no interlace
  std::string raw;
  for (int r = 0; r < height; ++r) {
    raw.push_back('\0');  // filter type None
    for (int c = 0; c < width; ++c) {
      const std::uint16_t v = rows[static_cast<size_t>(r) * width + c];
      raw.push_back(static_cast<char>(v >> 8));
      raw.push_back(static_cast<char>(v & 0xFF));
    }
  }
  uLongf zlen = compressBound(static_cast<uLong>(raw.size()));
  std::string z(zlen, '\0');
  ASSERT_EQ(compress(reinterpret_cast<Bytef*>(z.data()), &zlen,
                     reinterpret_cast<const Bytef*>(raw.data()), static_cast<uLong>(raw.size())),
            Z_OK);
  z.resize(zlen);
  std::string png("\x89PNG\r\n\x1a\n", 8);
  chunk(png, "IHDR", ihdr);
  chunk(png, "IDAT", z);
  chunk(png, "IEND", "");
  write_text(path, png);
}

}  // namespace erg::job::testing

// SPDX-License-Identifier: Apache-2.0
// Checkpoints prove their integrity: every dataset, the stored spec and the
// other root attributes are covered by the "checksums" attribute, and a
// reader refuses any file whose content differs from it, naming what differs.
// Each corruption is made for real in the file: a bit flipped in a value (the
// file stays valid HDF5, so only the checksum can tell), a bit flipped in the
// raw bytes of the spec (ASCII and non-UTF-8), in an attribute, in a ledger,
// a truncation, and a file with its checksums removed.
#include <gtest/gtest.h>
#include <hdf5.h>

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "../common/temp_dir.h"
#include "io/io.h"

namespace erg::io {
namespace {

using erg::test_support::TempDir;

Checkpoint sample(int nx, int ny, bool obstacles = false) {
  Checkpoint c;
  c.step = 120;
  c.nx = nx;
  c.ny = ny;
  c.job_spec_json = R"({"name":"integrity","model":{"warp_small_radius_m":50}})";
  const std::size_t n = static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny);
  for (std::size_t i = 0; i < n; ++i) {
    c.units[erg::fields::kBedrock].push_back(static_cast<std::int64_t>(i * 7919 % 1000) << 20);
    c.units[erg::fields::kSand].push_back(static_cast<std::int64_t>(i * 104729 % 5000) << 18);
    c.units[erg::fields::kAirborne].push_back(static_cast<std::int64_t>(i % 3));
    c.reals[erg::fields::kVegetation].push_back(static_cast<float>(i % 11) / 10.0f);
    c.reals[erg::fields::kResistance].push_back(static_cast<float>(i % 5) / 4.0f);
    if (obstacles) c.reals[erg::fields::kObstacles].push_back(i % 17 == 0 ? 2.5f : 0.0f);
  }
  c.ledger = {{"sand_added", "123456789012345678901234567890"}};
  return c;
}

std::string read_error(const std::string& path) {
  try {
    (void)read_checkpoint(path);
  } catch (const IoError& e) {
    return e.what();
  }
  return "no IoError";
}

std::string bytes_of(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

void put_bytes(const std::string& path, const std::string& b) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(b.data(), static_cast<std::streamsize>(b.size()));
}

// Flips `mask` in the byte at offset `at` of the first occurrence of `text`.
void flip_in_file(const std::string& path, const std::string& text, std::size_t at,
                  unsigned char mask) {
  std::string b = bytes_of(path);
  const auto pos = b.find(text);
  ASSERT_NE(pos, std::string::npos) << "'" << text << "' is not in " << path;
  ASSERT_EQ(b.find(text, pos + 1), std::string::npos) << "'" << text << "' twice in " << path;
  b[pos + at] = static_cast<char>(static_cast<unsigned char>(b[pos + at]) ^ mask);
  put_bytes(path, b);
}

// Rewrites one element of a dataset with one bit flipped, through HDF5: the
// file stays well-formed (its chunks decompress), only the value differs.
void flip_cell(const std::string& path, const char* dataset, hsize_t y, hsize_t x, int bit) {
  hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
  ASSERT_GE(f, 0);
  hid_t d = H5Dopen2(f, dataset, H5P_DEFAULT);
  ASSERT_GE(d, 0);
  hid_t fs = H5Dget_space(d);
  const hsize_t start[2] = {y, x}, count[2] = {1, 1};
  ASSERT_GE(H5Sselect_hyperslab(fs, H5S_SELECT_SET, start, nullptr, count, nullptr), 0);
  hid_t ms = H5Screate_simple(2, count, nullptr);
  std::uint64_t v = 0;
  hid_t t = H5Dget_type(d);
  const std::size_t size = H5Tget_size(t);
  hid_t mt = size == 8 ? H5T_NATIVE_UINT64 : H5T_NATIVE_UINT32;
  ASSERT_GE(H5Dread(d, mt, ms, fs, H5P_DEFAULT, &v), 0);
  v ^= std::uint64_t{1} << bit;
  ASSERT_GE(H5Dwrite(d, mt, ms, fs, H5P_DEFAULT, &v), 0);
  H5Tclose(t);
  H5Sclose(ms);
  H5Sclose(fs);
  H5Dclose(d);
  ASSERT_GE(H5Fclose(f), 0);
}

void set_step(const std::string& path, std::int64_t step) {
  hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
  ASSERT_GE(f, 0);
  hid_t a = H5Aopen(f, "step", H5P_DEFAULT);
  ASSERT_GE(a, 0);
  ASSERT_GE(H5Awrite(a, H5T_NATIVE_INT64, &step), 0);
  H5Aclose(a);
  ASSERT_GE(H5Fclose(f), 0);
}

bool has(const std::string& s, const std::string& part) {
  return s.find(part) != std::string::npos;
}

class CheckpointIntegrity : public ::testing::Test {
 protected:
  TempDir dir{"erg_integrity"};
  std::string path = dir.file("step_00000120.h5");
  void SetUp() override { write_checkpoint(path, sample(70, 40, true)); }
};

TEST_F(CheckpointIntegrity, AnIntactFileReadsBackAndCarriesChecksumsOfEverything) {
  const Checkpoint c = read_checkpoint(path);
  EXPECT_EQ(c.step, 120);
  hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  ASSERT_GE(f, 0);
  ASSERT_GT(H5Aexists(f, "checksums"), 0);
  H5Fclose(f);
  const std::string b = bytes_of(path);
  for (const char* name : {"erg-sum64", "bedrock_units ", "sand_units ", "airborne_units ",
                           "vegetation ", "resistance ", "obstacles ", "job_spec ", "attributes "})
    EXPECT_TRUE(has(b, name)) << name;
}

TEST_F(CheckpointIntegrity, ABitFlippedInAnyDatasetIsDetected) {
  const std::string clean = bytes_of(path);
  for (const char* ds :
       {"bedrock_units", "sand_units", "airborne_units", "vegetation", "resistance", "obstacles"}) {
    for (int bit : {0, 31}) {
      put_bytes(path, clean);
      flip_cell(path, ds, 17, 33, bit);
      const std::string m = read_error(path);
      EXPECT_TRUE(has(m, std::string("checksum of dataset '") + ds + "' does not match")) << m;
      EXPECT_TRUE(has(m, path)) << m;
    }
  }
}

TEST_F(CheckpointIntegrity, ABitFlippedInTheStoredSpecIsDetected) {
  const std::string clean = bytes_of(path);
  // 50 -> 54: the corruption that once resumed silently wrong.
  flip_in_file(path, "\"warp_small_radius_m\":50", 23, 0x04);
  std::string m = read_error(path);
  EXPECT_TRUE(has(m, "checksum of the stored job spec does not match")) << m;
  // A byte that is no longer UTF-8 is the same error, not a crash.
  put_bytes(path, clean);
  flip_in_file(path, "\"warp_small_radius_m\":50", 3, 0x80);
  m = read_error(path);
  EXPECT_TRUE(has(m, "checksum of the stored job spec does not match")) << m;
}

TEST_F(CheckpointIntegrity, ABitFlippedInAnAttributeOrALedgerIsDetected) {
  const std::string clean = bytes_of(path);
  set_step(path, 120 ^ 8);
  std::string m = read_error(path);
  EXPECT_TRUE(has(m, "checksum of the root attributes")) << m;
  put_bytes(path, clean);
  flip_in_file(path, "123456789012345678901234567890", 5, 0x01);
  m = read_error(path);
  EXPECT_TRUE(has(m, "checksum of the root attributes")) << m;
  // And a flipped bit in the checksums themselves.
  put_bytes(path, clean);
  flip_in_file(path, "erg-sum64\nbedrock_units ", 25, 0x01);
  m = read_error(path);
  EXPECT_TRUE(has(m, "checkpoint is corrupt") || has(m, "checksums attribute is damaged")) << m;
}

TEST_F(CheckpointIntegrity, ATruncatedFileIsRefused) {
  const std::string clean = bytes_of(path);
  for (std::size_t keep : {clean.size() / 2, clean.size() - 100, std::size_t{600}}) {
    put_bytes(path, clean.substr(0, keep));
    const std::string m = read_error(path);
    EXPECT_NE(m, "no IoError") << keep;
    EXPECT_TRUE(has(m, path)) << m;
  }
}

TEST_F(CheckpointIntegrity, AFileWithoutChecksumsCannotProveItsIntegrity) {
  hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
  ASSERT_GE(f, 0);
  ASSERT_GE(H5Adelete(f, "checksums"), 0);
  H5Fclose(f);
  const std::string m = read_error(path);
  EXPECT_TRUE(has(m, "carries no checksums")) << m;
}

TEST_F(CheckpointIntegrity, DatasetsMovedBetweenCellsOrNamesAreDetected) {
  // Two cells swapped keep every value: the checksum depends on the position.
  hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
  ASSERT_GE(f, 0);
  hid_t d = H5Dopen2(f, "sand_units", H5P_DEFAULT);
  std::vector<std::int64_t> v(70 * 40);
  ASSERT_GE(H5Dread(d, H5T_NATIVE_INT64, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data()), 0);
  ASSERT_NE(v[5], v[6]);
  std::swap(v[5], v[6]);
  ASSERT_GE(H5Dwrite(d, H5T_NATIVE_INT64, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data()), 0);
  H5Dclose(d);
  H5Fclose(f);
  EXPECT_TRUE(has(read_error(path), "checksum of dataset 'sand_units'"));
}

}  // namespace
}  // namespace erg::io

// SPDX-License-Identifier: Apache-2.0
// Checkpoints: bitwise round trip of the exact integer state (including the
// extremes of int64), ledger order, and clear errors for missing, corrupt,
// foreign or malformed files.
#include <gtest/gtest.h>
#include <hdf5.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "checkpoint_sample.h"
#include "io/io.h"
#include "test_util.h"

namespace erg::io {
namespace {

using testing::kP62;
using testing::read_bytes;
using testing::sample_checkpoint;
using testing::TempDir;

template <class T>
void expect_same_bits(const std::vector<T>& got, const std::vector<T>& want, const char* name) {
  ASSERT_EQ(got.size(), want.size()) << name;
  EXPECT_EQ(0, std::memcmp(got.data(), want.data(), want.size() * sizeof(T))) << name;
}

std::string read_error(const std::string& path) {
  try {
    read_checkpoint(path);
  } catch (const IoError& e) {
    return e.what();
  }
  return "no IoError";
}

TEST(Checkpoint, RoundTripsBitwise) {
  TempDir dir;
  // 300 x 270: several chunks, partial ones at both edges.
  const Checkpoint c = sample_checkpoint(300, 270);
  const std::string path = dir.file("ckpt.h5");
  write_checkpoint(path, c);
  const Checkpoint r = read_checkpoint(path);
  EXPECT_EQ(r.step, c.step);
  EXPECT_EQ(r.nx, c.nx);
  EXPECT_EQ(r.ny, c.ny);
  EXPECT_EQ(r.job_spec_json, c.job_spec_json);
  expect_same_bits(r.units[erg::fields::kBedrock], c.units[erg::fields::kBedrock], "bedrock_units");
  expect_same_bits(r.units[erg::fields::kSand], c.units[erg::fields::kSand], "sand_units");
  expect_same_bits(r.units[erg::fields::kAirborne], c.units[erg::fields::kAirborne],
                   "airborne_units");
  expect_same_bits(r.reals[erg::fields::kVegetation], c.reals[erg::fields::kVegetation],
                   "vegetation");
  expect_same_bits(r.reals[erg::fields::kResistance], c.reals[erg::fields::kResistance],
                   "resistance");
  EXPECT_EQ(r.ledger, c.ledger);
  EXPECT_EQ(r.units[erg::fields::kBedrock][0], kP62);
  EXPECT_EQ(r.units[erg::fields::kBedrock][1], -kP62);
  EXPECT_EQ(dir.entries(), std::set<std::string>{"ckpt.h5"});
}

TEST(Checkpoint, StoresInt64DatasetsAndLedgerAttributes) {
  TempDir dir;
  const std::string path = dir.file("ckpt.h5");
  write_checkpoint(path, sample_checkpoint(5, 4));
  hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  ASSERT_GE(f, 0);
  for (const char* name : {"bedrock_units", "sand_units", "airborne_units"}) {
    hid_t d = H5Dopen2(f, name, H5P_DEFAULT);
    ASSERT_GE(d, 0) << name;
    hid_t t = H5Dget_type(d);
    EXPECT_GT(H5Tequal(t, H5T_STD_I64LE), 0) << name;
    H5Tclose(t);
    H5Dclose(d);
  }
  EXPECT_GT(H5Aexists(f, "ledger_sand_added"), 0);
  EXPECT_GT(H5Aexists(f, "ledger_airborne_lost"), 0);
  H5Fclose(f);
}

TEST(Checkpoint, MissingFileIsReportedWithPath) {
  TempDir dir;
  const std::string path = dir.file("nope.h5");
  const std::string m = read_error(path);
  EXPECT_NE(m.find(path), std::string::npos) << m;
  EXPECT_NE(m.find("No such file"), std::string::npos) << m;
}

TEST(Checkpoint, CorruptFilesAreReported) {
  TempDir dir;
  const std::string junk = dir.file("junk.h5");
  testing::write_bytes(junk, std::string(4096, '\x5a'));
  std::string m = read_error(junk);
  EXPECT_NE(m.find(junk), std::string::npos) << m;
  EXPECT_NE(m.find("not an HDF5 file"), std::string::npos) << m;

  // A truncated checkpoint: right signature, missing data.
  const std::string good = dir.file("good.h5");
  write_checkpoint(good, sample_checkpoint(64, 64));
  const std::string bytes = read_bytes(good);
  for (std::size_t keep : {bytes.size() / 2, std::size_t{600}}) {
    const std::string cut = dir.file("cut.h5");
    testing::write_bytes(cut, bytes.substr(0, keep));
    m = read_error(cut);
    EXPECT_NE(m.find(cut), std::string::npos) << keep << ": " << m;
  }
}

TEST(Checkpoint, SnapshotIsNotACheckpoint) {
  TempDir dir;
  SnapshotMeta meta;
  meta.nx = 2;
  meta.ny = 2;
  std::vector<float> z(8, 0.0f);
  SnapshotFields f;
  for (const auto id : {erg::fields::kBedrock, erg::fields::kSand, erg::fields::kVegetation,
                        erg::fields::kWindX, erg::fields::kWindY})
    f[id].data = z.data();
  write_snapshot(dir.file("snap.h5"), meta, f);
  const std::string m = read_error(dir.file("snap.h5"));
  EXPECT_NE(m.find("not an erg checkpoint"), std::string::npos) << m;
}

TEST(Checkpoint, WrongShapeIsReported) {
  TempDir dir;
  const std::string path = dir.file("ckpt.h5");
  write_checkpoint(path, sample_checkpoint(6, 5));
  // Replace /sand_units by a [5][7] dataset.
  hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
  ASSERT_GE(f, 0);
  ASSERT_GE(H5Ldelete(f, "sand_units", H5P_DEFAULT), 0);
  const hsize_t dims[2] = {5, 7};
  hid_t space = H5Screate_simple(2, dims, nullptr);
  hid_t d =
      H5Dcreate2(f, "sand_units", H5T_STD_I64LE, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  ASSERT_GE(d, 0);
  H5Dclose(d);
  H5Sclose(space);
  H5Fclose(f);
  const std::string m = read_error(path);
  EXPECT_NE(m.find("'sand_units'"), std::string::npos) << m;
  EXPECT_NE(m.find("[5][7]"), std::string::npos) << m;
  EXPECT_NE(m.find("expected [5][6]"), std::string::npos) << m;
}

TEST(Checkpoint, InvalidInputIsRejectedBeforeWriting) {
  TempDir dir;
  Checkpoint c = sample_checkpoint(4, 3);
  c.units[erg::fields::kSand].pop_back();
  EXPECT_THROW(write_checkpoint(dir.file("a.h5"), c), IoError);
  c = sample_checkpoint(4, 3);
  c.ledger.push_back({"bad", "12x"});
  EXPECT_THROW(write_checkpoint(dir.file("a.h5"), c), IoError);
  c = sample_checkpoint(4, 3);
  c.ledger.push_back(c.ledger.front());
  EXPECT_THROW(write_checkpoint(dir.file("a.h5"), c), IoError);
  EXPECT_TRUE(dir.entries().empty());
}

}  // namespace
}  // namespace erg::io

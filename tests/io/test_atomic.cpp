// SPDX-License-Identifier: Apache-2.0
// Atomic writes, for every writer: a failed write throws IoError naming the
// path, leaves no temporary behind, and never damages the file already at
// the destination; a successful one leaves exactly the destination.
#include <gtest/gtest.h>
#include <unistd.h>

#include <functional>
#include <random>
#include <string>
#include <vector>

#include "io/io.h"
#include "test_util.h"

namespace erg::io {
namespace {

using testing::FileSizeLimit;
using testing::read_bytes;
using testing::TempDir;

// Data big and random enough that compression cannot shrink the output
// below the file-size limit used to make writes fail midway.
struct Payload {
  static constexpr int kN = 256;
  std::vector<float> a, b, c, wind;
  std::vector<double> unit;
  Payload() {
    std::mt19937 rng(11);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    for (int i = 0; i < kN * kN; ++i) {
      a.push_back(u(rng) * 100.0f);
      b.push_back(u(rng) * 10.0f);
      c.push_back(u(rng));
      wind.push_back(u(rng));
      wind.push_back(u(rng));
      unit.push_back(u(rng));
    }
  }
};

// One writer under test: writes `path` with the payload (n x n cells).
struct Writer {
  const char* name;
  std::function<void(const std::string& path, const Payload& p, int n)> write;
};

std::vector<Writer> writers() {
  return {
      {"snapshot",
       [](const std::string& path, const Payload& p, int n) {
         SnapshotMeta meta;
         meta.nx = n;
         meta.ny = n;
         SnapshotFields f;
         f[erg::fields::kBedrock].data = p.a.data();
         f[erg::fields::kSand].data = p.b.data();
         f[erg::fields::kVegetation].data = p.c.data();
         f[erg::fields::kWindX] = {p.wind.data(), 2, 0};
         f[erg::fields::kWindY] = {p.wind.data(), 2, 1};
         write_snapshot(path, meta, f);
       }},
      {"xdmf",
       [](const std::string& path, const Payload&, int n) {
         SnapshotMeta meta;
         meta.nx = n;
         meta.ny = n;
         write_xdmf(path, "s.h5", meta,
                    std::vector<erg::fields::Id>{erg::fields::kBedrock, erg::fields::kSand,
                                                 erg::fields::kVegetation, erg::fields::kWindX,
                                                 erg::fields::kWindY, erg::fields::kAirborne,
                                                 erg::fields::kShadow});
       }},
      {"checkpoint",
       [](const std::string& path, const Payload& p, int n) {
         Checkpoint c;
         c.nx = n;
         c.ny = n;
         const std::size_t cells = static_cast<std::size_t>(n) * n;
         for (std::size_t i = 0; i < cells; ++i) {
           c.units[erg::fields::kBedrock].push_back(
               static_cast<std::int64_t>(p.a[i] * 4294967296.0));
           c.units[erg::fields::kSand].push_back(static_cast<std::int64_t>(p.b[i] * 4294967296.0));
           c.units[erg::fields::kAirborne].push_back(
               static_cast<std::int64_t>(p.c[i] * 4294967296.0));
         }
         c.reals[erg::fields::kVegetation].assign(p.c.begin(),
                                                  p.c.begin() + static_cast<std::ptrdiff_t>(cells));
         c.reals[erg::fields::kResistance].assign(p.b.begin(),
                                                  p.b.begin() + static_cast<std::ptrdiff_t>(cells));
         write_checkpoint(path, c);
       }},
      {"preview",
       [](const std::string& path, const Payload& p, int n) {
         write_preview_png(path, n, n, 1.0, p.a.data(), p.b.data(), p.c.data());
       }},
      {"png16",
       [](const std::string& path, const Payload& p, int n) {
         write_png16(path, n, n,
                     std::vector<double>(p.unit.begin(),
                                         p.unit.begin() + static_cast<std::ptrdiff_t>(n) * n));
       }},
  };
}

TEST(Atomic, SuccessLeavesOnlyTheDestination) {
  const Payload p;
  for (const Writer& w : writers()) {
    TempDir dir;
    w.write(dir.file("out"), p, 16);
    EXPECT_EQ(dir.entries(), std::set<std::string>{"out"}) << w.name;
    // Overwriting an existing file works too and still leaves nothing else.
    w.write(dir.file("out"), p, 8);
    EXPECT_EQ(dir.entries(), std::set<std::string>{"out"}) << w.name;
  }
}

TEST(Atomic, MissingDirectoryThrowsAndCreatesNothing) {
  const Payload p;
  for (const Writer& w : writers()) {
    TempDir dir;
    const std::string path = dir.file("no/such/dir/out");
    try {
      w.write(path, p, 8);
      ADD_FAILURE() << w.name << ": expected IoError";
    } catch (const IoError& e) {
      EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << w.name << ": " << e.what();
    }
    EXPECT_TRUE(dir.entries().empty()) << w.name;
  }
}

TEST(Atomic, InvalidArgumentsLeaveTheOldFileIntact) {
  // nx = 0 fails before anything is written.
  const Payload p;
  for (const Writer& w : writers()) {
    TempDir dir;
    const std::string path = dir.file("out");
    w.write(path, p, 8);
    const std::string before = read_bytes(path);
    EXPECT_THROW(w.write(path, p, 0), IoError) << w.name;
    EXPECT_EQ(read_bytes(path), before) << w.name;
    EXPECT_FALSE(dir.has_temporaries()) << w.name;
  }
}

TEST(Atomic, FailureMidwayLeavesTheOldFileIntactAndNoTemporary) {
  // The file-size limit lets the writer create its temporary and start
  // writing, then makes a write fail (EFBIG): a real mid-write failure.
  const Payload p;
  for (const Writer& w : writers()) {
    if (std::string(w.name) == "xdmf") continue;  // too small to cut; covered below
    TempDir dir;
    const std::string path = dir.file("out");
    w.write(path, p, 8);
    const std::string before = read_bytes(path);
    {
      FileSizeLimit limit(16 * 1024);
      try {
        w.write(path, p, Payload::kN);
        ADD_FAILURE() << w.name << ": expected IoError";
      } catch (const IoError& e) {
        EXPECT_NE(std::string(e.what()).find(path), std::string::npos)
            << w.name << ": " << e.what();
      }
    }
    EXPECT_EQ(read_bytes(path), before) << w.name;
    EXPECT_FALSE(dir.has_temporaries()) << w.name;
  }
}

TEST(Atomic, UnwritableTemporaryLeavesTheOldFileAndWhatBlocksIt) {
  // Something that is not ours (a directory) sits at the temporary name: the
  // write fails, the old file survives, and the directory is not deleted.
  const Payload p;
  for (const Writer& w : writers()) {
    TempDir dir;
    const std::string path = dir.file("out");
    w.write(path, p, 8);
    const std::string before = read_bytes(path);
    const std::string tmp = path + ".tmp-" + std::to_string(::getpid());
    std::filesystem::create_directory(tmp);
    EXPECT_THROW(w.write(path, p, 16), IoError) << w.name;
    EXPECT_EQ(read_bytes(path), before) << w.name;
    EXPECT_TRUE(std::filesystem::is_directory(tmp)) << w.name;
  }
}

}  // namespace
}  // namespace erg::io

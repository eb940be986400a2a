// SPDX-License-Identifier: Apache-2.0
// ergd's job store on a full disk, for real: a 12 MiB tmpfs mounted by the
// test (root; skipped otherwise), filled up with a file. Writes that fail
// throw StoreError (full) and change nothing; the first one spends the
// 4 MiB reserve file so that the write that records a failure still
// succeeds; reads keep working; once space is freed, writes work again and
// the reserve is made again.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/mount.h>
#include <sys/statvfs.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>

#include "store/job_store.h"

namespace fs = std::filesystem;
using erg::server::JobStore;
using erg::server::StoreError;

namespace {

std::int64_t free_bytes(const fs::path& p) {
  struct statvfs v {};
  if (::statvfs(p.c_str(), &v) != 0) return -1;
  return static_cast<std::int64_t>(v.f_bavail) * static_cast<std::int64_t>(v.f_frsize);
}

// Writes `path` until the file system is full.
void fill(const fs::path& path) {
  std::FILE* f = std::fopen(path.c_str(), "wb");
  ASSERT_NE(f, nullptr);
  std::string block(64 * 1024, 'x');
  while (std::fwrite(block.data(), 1, block.size(), f) == block.size() && std::fflush(f) == 0) {
  }
  std::fclose(f);
  // What a buffered write left: a byte at a time.
  int fd = ::open(path.c_str(), O_WRONLY | O_APPEND);
  while (fd >= 0 && ::write(fd, "x", 1) == 1) {
  }
  if (fd >= 0) ::close(fd);
}

erg::v1::Job job(const std::string& id, int payload) {
  erg::v1::Job j;
  j.set_id(id);
  j.set_tenant("alice");
  j.set_state(erg::v1::RUNNING);
  j.set_log_tail(std::string(static_cast<std::size_t>(payload), 'L'));
  return j;
}

class StoreOnFullDisk : public ::testing::Test {
 protected:
  fs::path dir = fs::temp_directory_path() / ("erg-storefull-" + std::to_string(::getpid()));
  bool mounted = false;
  void SetUp() override {
    if (::geteuid() != 0) GTEST_SKIP() << "mounting a tmpfs needs root";
    fs::create_directories(dir);
    ASSERT_EQ(::mount("tmpfs", dir.c_str(), "tmpfs", 0, "size=12m,mode=0700"), 0)
        << std::strerror(errno);
    mounted = true;
  }
  void TearDown() override {
    if (mounted && ::umount(dir.c_str()) != 0) ::umount2(dir.c_str(), MNT_DETACH);
    std::error_code ec;
    fs::remove_all(dir, ec);
  }
};

TEST_F(StoreOnFullDisk, WritesFailCleanlyReadsGoOnAndTheReserveRecordsTheFailure) {
  JobStore store((dir / "ergd.sqlite").string(), (dir / "ergd.reserve").string());
  ASSERT_TRUE(fs::exists(dir / "ergd.reserve"));
  EXPECT_GE(fs::file_size(dir / "ergd.reserve"), 4u << 20);
  store.insert(job("j-1", 100));
  erg::v1::JobEvent ev;
  ev.set_message("started");
  store.append_event("j-1", ev);

  fill(dir / "filler");
  ASSERT_LT(free_bytes(dir), 8192);
  // The failure is recorded: the reserve is spent for it.
  erg::v1::Job failed = job("j-1", 100);
  failed.set_state(erg::v1::FAILED);
  failed.set_failure_reason("No space left on device");
  EXPECT_NO_THROW(store.update(failed));
  EXPECT_FALSE(fs::exists(dir / "ergd.reserve"));
  EXPECT_FALSE(store.restore_reserve());  // no room to make it again

  // Without the reserve, writes that need space fail as full, and change nothing.
  bool threw_full = false;
  int written = 0;
  for (int k = 0; k < 2000 && !threw_full; ++k) {
    try {
      store.append_event("j-1", ev);
      store.insert(job("j-big-" + std::to_string(k), 64 * 1024));
      ++written;
    } catch (const StoreError& e) {
      threw_full = e.full();
      EXPECT_NE(std::string(e.what()).find("ENOSPC"), std::string::npos) << e.what();
    }
  }
  EXPECT_TRUE(threw_full) << written << " writes went through on a full disk";
  // Reads go on, and see the recorded failure.
  const auto j = store.get("j-1");
  ASSERT_TRUE(j);
  EXPECT_EQ(j->state(), erg::v1::FAILED);
  EXPECT_FALSE(store.events_after("j-1", 0, 10).empty());

  // Space again: writes work, the reserve comes back.
  fs::remove(dir / "filler");
  EXPECT_NO_THROW(store.insert(job("j-after", 100)));
  EXPECT_TRUE(store.restore_reserve());
  EXPECT_TRUE(fs::exists(dir / "ergd.reserve"));
  EXPECT_TRUE(store.get("j-after"));
}

}  // namespace

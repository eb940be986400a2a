// SPDX-License-Identifier: Apache-2.0
// ergd's building blocks without the network: the SQLite job store
// (persistence across reopen, idempotency keys, event log order, paging).
// The tokens file: tests/security/test_tokens.cpp.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <thread>

#include "store/job_store.h"
#include "util/sha256.h"

namespace fs = std::filesystem;
using erg::server::JobStore;

namespace {

fs::path temp_dir() {
  fs::path d =
      fs::temp_directory_path() / ("erg-store-" + std::to_string(::getpid()) + "-" +
                                   ::testing::UnitTest::GetInstance()->current_test_info()->name());
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

erg::v1::Job job(const std::string& id, const std::string& tenant, const std::string& key = "") {
  erg::v1::Job j;
  j.set_id(id);
  j.set_tenant(tenant);
  j.set_state(erg::v1::QUEUED);
  j.set_idempotency_key(key);
  j.mutable_spec()->set_name("job " + id);
  return j;
}

}  // namespace

TEST(JobStore, JobsAndEventsSurviveReopening) {
  const fs::path d = temp_dir();
  {
    JobStore s((d / "db.sqlite").string());
    s.insert(job("j-1", "alice"));
    auto j = job("j-1", "alice");
    j.set_state(erg::v1::RUNNING);
    j.mutable_progress()->set_step(42);
    s.update(j);
    erg::v1::JobEvent ev;
    ev.set_message("hello");
    EXPECT_EQ(s.append_event("j-1", ev).id(), 1);
    EXPECT_EQ(s.append_event("j-1", ev).id(), 2);
  }
  JobStore s((d / "db.sqlite").string());
  auto j = s.get("j-1");
  ASSERT_TRUE(j);
  EXPECT_EQ(j->state(), erg::v1::RUNNING);
  EXPECT_EQ(j->progress().step(), 42);
  EXPECT_EQ(j->spec().name(), "job j-1");
  auto evs = s.events_after("j-1", 0, 100);
  ASSERT_EQ(evs.size(), 2u);
  EXPECT_EQ(evs[0].id(), 1);
  EXPECT_EQ(evs[1].message(), "hello");
  EXPECT_EQ(s.events_after("j-1", 1, 100).size(), 1u);
  EXPECT_FALSE(s.get("j-nope"));
  fs::remove_all(d);
}

TEST(JobStore, IdempotencyKeysArePerTenant) {
  const fs::path d = temp_dir();
  JobStore s((d / "db.sqlite").string());
  auto [a, created_a] = s.insert(job("j-a", "alice", "k"));
  EXPECT_TRUE(created_a);
  auto [b, created_b] = s.insert(job("j-b", "alice", "k"));
  EXPECT_FALSE(created_b);
  EXPECT_EQ(b.id(), "j-a");
  auto [c, created_c] = s.insert(job("j-c", "bob", "k"));
  EXPECT_TRUE(created_c);
  // Jobs without a key never collide.
  EXPECT_TRUE(s.insert(job("j-d", "alice")).second);
  EXPECT_TRUE(s.insert(job("j-e", "alice")).second);
  ASSERT_TRUE(s.by_key("alice", "k"));
  EXPECT_EQ(s.by_key("alice", "k")->id(), "j-a");
  EXPECT_FALSE(s.by_key("carol", "k"));
  fs::remove_all(d);
}

TEST(JobStore, ListsNewestFirstByPageAndState) {
  const fs::path d = temp_dir();
  JobStore s((d / "db.sqlite").string());
  for (int i = 0; i < 5; ++i) s.insert(job("j-" + std::to_string(i), "alice"));
  s.insert(job("j-bob", "bob"));
  auto j3 = job("j-3", "alice");
  j3.set_state(erg::v1::SUCCEEDED);
  s.update(j3);
  std::int64_t last = 0;
  auto page1 = s.list("alice", 0, 0, 2, &last);
  ASSERT_EQ(page1.size(), 2u);
  EXPECT_EQ(page1[0].id(), "j-4");
  EXPECT_EQ(page1[1].id(), "j-3");
  auto page2 = s.list("alice", 0, last, 10, &last);
  ASSERT_EQ(page2.size(), 3u);
  EXPECT_EQ(page2[0].id(), "j-2");
  auto done = s.list("alice", erg::v1::SUCCEEDED, 0, 10, &last);
  ASSERT_EQ(done.size(), 1u);
  EXPECT_EQ(done[0].id(), "j-3");
  EXPECT_EQ(s.in_states({erg::v1::QUEUED}).size(), 5u);  // 4 of alice's + bob's
}

TEST(JobStore, WaitersWakeOnNewEvents) {
  const fs::path d = temp_dir();
  JobStore s((d / "db.sqlite").string());
  const auto gen = s.generation();
  std::thread t([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    s.append_event("j-1", erg::v1::JobEvent());
  });
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_NE(s.wait_events(gen, 10000), gen);
  EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(5));
  t.join();
  fs::remove_all(d);
}

TEST(Sha256, KnownDigests) {
  EXPECT_EQ(erg::server::sha256_hex(""),
            "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
  EXPECT_EQ(erg::server::sha256_hex("abc"),
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
}

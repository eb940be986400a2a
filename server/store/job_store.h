// SPDX-License-Identifier: Apache-2.0
// The persistent job store of ergd: one SQLite database (DATA/ergd.sqlite,
// WAL journal, synchronous=FULL) holding every job and its event log. A job
// is written before ergd answers the call that changed it, so killing ergd
// (even with SIGKILL) loses nothing it acknowledged.
//
//   jobs(id, tenant, state, seq, idem_key, job)   job: a serialized erg.v1.Job
//   events(id, job_id, job)                       event: a serialized JobEvent
//
// Thread-safe: one connection behind a mutex (calls are short; SQLite would
// serialise writers anyway).
//
// A full disk. Every failed write throws StoreError (full() when the file
// system is out of space), never leaves a half-done change (each write is one
// SQLite transaction) and never breaks the reads. So that the writes that
// record a failure (a job FAILED because the disk filled up) still succeed on
// a full disk, the store keeps a reserve file, DATA/ergd.reserve (4 MiB, made
// when there is room): a write that fails for lack of space deletes it and
// tries once more. restore_reserve() makes it again once there is room.
#pragma once

#include <sqlite3.h>

#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "erg/v1/service.pb.h"

namespace erg::server {

// A write the store could not make. full(): the file system had no space
// (SQLITE_FULL, or an I/O error with ENOSPC/EDQUOT).
struct StoreError : std::runtime_error {
  StoreError(const std::string& m, bool full) : std::runtime_error(m), full_(full) {}
  bool full() const { return full_; }

 private:
  bool full_;
};

class JobStore {
 public:
  // `reserve_path`: the reserve file ("" : none).
  explicit JobStore(const std::string& path, std::string reserve_path = "");
  ~JobStore();
  JobStore(const JobStore&) = delete;
  JobStore& operator=(const JobStore&) = delete;

  // Inserts a new job. With an idempotency key already used by the tenant,
  // inserts nothing and returns the existing job instead (second = false).
  std::pair<erg::v1::Job, bool> insert(const erg::v1::Job& job);
  void update(const erg::v1::Job& job);
  std::optional<erg::v1::Job> get(const std::string& id);
  // The tenant's jobs newest first; state 0: all. `after_seq` pages (0: first page).
  std::vector<erg::v1::Job> list(const std::string& tenant, int state, std::int64_t before_seq,
                                 int limit, std::int64_t* last_seq);
  // Every job in one of the states, oldest first (the scheduler's view).
  std::vector<erg::v1::Job> in_states(const std::vector<int>& states);
  std::optional<erg::v1::Job> by_key(const std::string& tenant, const std::string& key);
  std::int64_t seq_of(const std::string& id);
  std::vector<std::pair<int, std::int64_t>> count_by_state();

  // Appends an event (its id and time are set here) and wakes watchers.
  erg::v1::JobEvent append_event(const std::string& job_id, erg::v1::JobEvent ev);
  std::vector<erg::v1::JobEvent> events_after(const std::string& job_id, std::int64_t after,
                                              int limit);
  // Blocks until an event newer than `seen_generation` exists or the timeout;
  // returns the current generation.
  std::uint64_t wait_events(std::uint64_t seen_generation, int timeout_ms);
  std::uint64_t generation();

  // Makes the reserve file again if it is missing and the space is there
  // (cheap when it exists). Returns whether it exists.
  bool restore_reserve();

 private:
  void exec(const char* sql);
  // Runs one write (under mu_); on a full disk, frees the reserve and retries once.
  template <class F>
  auto write(F&& f) -> decltype(f());
  bool release_reserve();
  std::string reserve_path_;
  sqlite3* db_ = nullptr;
  std::mutex mu_;
  std::condition_variable cv_;
  std::uint64_t generation_ = 0;
};

}  // namespace erg::server

// SPDX-License-Identifier: Apache-2.0
#include "scheduler/job_manager.h"

#include <google/protobuf/util/json_util.h>
#include <sys/statvfs.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <deque>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <random>
#include <sstream>
#include <system_error>

#include "auth/request_checks.h"
#include "io/atomic_file.h"
#include "io/run_files.h"
#include "job/spec.h"
#include "sim/resolution.h"
#include "sim/tile_plan.h"

namespace erg::server {

namespace fs = std::filesystem;
using erg::v1::Job;
using erg::v1::JobEvent;
using erg::v1::JobState;

namespace {

double mono_s() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

std::int64_t now_ms() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

// The memory this machine lets ergd's workers have: physical memory, or the
// cgroup's limit when lower (a container, a systemd MemoryMax=).
std::int64_t machine_memory_bytes() {
  const long pages = ::sysconf(_SC_PHYS_PAGES), page = ::sysconf(_SC_PAGESIZE);
  std::int64_t mem = pages > 0 && page > 0 ? static_cast<std::int64_t>(pages) * page : 0;
  for (const char* path :
       {"/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory/memory.limit_in_bytes"}) {
    std::ifstream f(path);
    std::string v;
    if (f >> v && !v.empty() && v != "max") {
      try {
        const std::int64_t lim = std::stoll(v);
        if (lim > 0 && (mem == 0 || lim < mem)) mem = lim;
      } catch (...) {
      }
    }
  }
  return mem;
}

// "exited with code 3", "was killed by signal 9 (exit code 137)".
std::string exit_text(int code) {
  if (code > 128 && code < 128 + 65)
    return "was killed by signal " + std::to_string(code - 128) + " (exit code " +
           std::to_string(code) + ")";
  return "exited with code " + std::to_string(code);
}

std::string gib(double bytes) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.3g GiB", bytes / double(1ull << 30));
  return buf;
}

std::string new_job_id() {
  static std::mutex mu;
  static std::mt19937_64 rng{std::random_device{}()};
  std::lock_guard lock(mu);
  char buf[24];
  std::snprintf(buf, sizeof buf, "j-%016llx", static_cast<unsigned long long>(rng()));
  return buf;
}

// Whether an error message says the disk is full.
bool says_full(const std::string& m) {
  return m.find("No space left on device") != std::string::npos ||
         m.find("ENOSPC") != std::string::npos || m.find("disk is full") != std::string::npos ||
         m.find("Disk quota exceeded") != std::string::npos;
}

// A failure reason that names ENOSPC when the cause was a full disk.
std::string with_enospc(const std::string& reason) {
  if (!says_full(reason) || reason.find("ENOSPC") != std::string::npos) return reason;
  return reason + " (ENOSPC: the data directory's file system is full)";
}

std::int64_t dir_bytes(const fs::path& dir) {
  std::int64_t total = 0;
  std::error_code ec;
  for (auto it = fs::recursive_directory_iterator(dir, ec); !ec && it != fs::end(it);
       it.increment(ec)) {
    std::error_code e2;
    if (it->is_regular_file(e2)) total += static_cast<std::int64_t>(it->file_size(e2));
  }
  return total;
}

}  // namespace

JobManager::JobManager(JobStore& store, Launcher& launcher, Metrics& metrics, ManagerConfig cfg)
    : store_(store), launcher_(launcher), metrics_(metrics), cfg_(std::move(cfg)) {
  if (cfg_.max_ranks <= 0)
    cfg_.max_ranks = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  if (cfg_.max_threads <= 0)
    cfg_.max_threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  if (cfg_.max_job_memory_bytes <= 0) cfg_.max_job_memory_bytes = machine_memory_bytes();
  fs::create_directories(fs::path(cfg_.data_dir) / "jobs");
}

JobManager::~JobManager() {
  stopping_ = true;
  cv_.notify_all();
  if (scheduler_.joinable()) scheduler_.join();
}

std::string JobManager::job_dir(const std::string& id) const {
  return (fs::path(cfg_.data_dir) / "jobs" / id).string();
}

std::string JobManager::snapshot_path(const std::string& id, std::int64_t step) const {
  return job_dir(id) + "/run/snapshots/" + step_name(step) + ".h5";
}

std::string JobManager::preview_path(const std::string& id, std::int64_t step) const {
  return job_dir(id) + "/run/previews/" + step_name(step) + ".png";
}

double JobManager::cell_steps_of(const Job& job) const {
  const auto& d = job.spec().domain();
  const double left = static_cast<double>(job.spec().run().steps() - job.progress().step());
  return static_cast<double>(d.nx()) * static_cast<double>(d.ny()) * std::max(0.0, left);
}

std::string JobManager::log_tail(const std::string& id, int lines) const {
  std::ifstream f(job_dir(id) + "/worker.log");
  std::deque<std::string> tail;
  std::string line;
  while (std::getline(f, line)) {
    tail.push_back(line);
    if (static_cast<int>(tail.size()) > lines) tail.pop_front();
  }
  std::string out;
  for (auto& l : tail) out += l + "\n";
  return out;
}

namespace {

std::string host_name() {
  char buf[256] = "";
  if (::gethostname(buf, sizeof buf - 1) != 0) return "this machine";
  return buf;
}

// What ergd's log says of an event, or "" for the events that are no
// transition (progress, steering, notes).
std::string transition_text(const Job& job, const JobEvent& ev) {
  const std::string at = " at step " + std::to_string(job.progress().step());
  if (ev.kind_case() == JobEvent::kSnapshotStep)
    return "snapshot at step " + std::to_string(ev.snapshot_step());
  if (ev.kind_case() != JobEvent::kStateChanged) return "";
  switch (ev.state_changed()) {
    case erg::v1::QUEUED:
      return job.started_unix_ms() == 0 ? "submitted (queued)" : "queued again" + at;
    case erg::v1::RUNNING:
      return job.attempts() > 1 ? "started (attempt " + std::to_string(job.attempts()) + ")"
                                : "started";
    case erg::v1::SUCCEEDED:
      return "succeeded" + at;
    case erg::v1::FAILED: {
      std::string why = job.failure_reason();
      std::replace(why.begin(), why.end(), '\n', ' ');
      return "failed" + at + ": " + (why.empty() ? "no reason given" : why);
    }
    case erg::v1::CANCELLED:
      return "cancelled" + at;
    default:
      return "";
  }
}

}  // namespace

void JobManager::event_locked(const Job& job, JobEvent ev) {
  // One line per transition, with the job and its tenant.
  if (const std::string what = transition_text(job, ev); !what.empty())
    std::cerr << "ergd: job " << job.id() << " (tenant " << job.tenant() << "): " << what
              << std::endl;
  ev.set_state(job.state());
  store_.append_event(job.id(), std::move(ev));
}

void JobManager::set_state_locked(Job& job, JobState s, const std::string& note) {
  job.set_state(s);
  store_.update(job);
  JobEvent ev;
  ev.set_state_changed(s);
  event_locked(job, ev);
  if (!note.empty()) {
    JobEvent m;
    m.set_message(note);
    event_locked(job, m);
  }
}

// ---- calls ----------------------------------------------------------------

Job JobManager::submit(const std::string& tenant, const erg::v1::SubmitJobRequest& req) {
  refuse_map_files(req.spec());  // before anything reads the spec
  // Size limits are RESOURCE_EXHAUSTED, as gRPC's own message size limit is.
  if (req.idempotency_key().size() > 128)
    throw ApiError(grpc::StatusCode::RESOURCE_EXHAUSTED,
                   "idempotency_key: " + std::to_string(req.idempotency_key().size()) +
                       " characters; at most 128");
  if (!req.idempotency_key().empty())
    if (auto existing = store_.by_key(tenant, req.idempotency_key()))
      return get(tenant, existing->id());

  erg::v1::JobSpec spec = req.spec();
  const auto bytes = static_cast<std::int64_t>(spec.ByteSizeLong());
  if (bytes > cfg_.max_spec_bytes)
    throw ApiError(grpc::StatusCode::RESOURCE_EXHAUSTED, "spec: " + std::to_string(bytes) +
                                                             " bytes; at most " +
                                                             std::to_string(cfg_.max_spec_bytes));
  std::vector<std::string> problems;
  job::apply_defaults(spec);
  problems = job::validate(spec, "/nonexistent");
  const auto& res = req.resources();
  if (res.ranks() < 0 || res.ranks() > cfg_.max_ranks)
    problems.push_back("resources.ranks: " + std::to_string(res.ranks()) + " is out of range [0, " +
                       std::to_string(cfg_.max_ranks) + "] (ergd --max-ranks)");
  if (res.threads_per_rank() < 0 || res.threads_per_rank() > cfg_.max_threads)
    problems.push_back("resources.threads_per_rank: " + std::to_string(res.threads_per_rank()) +
                       " is out of range [0, " + std::to_string(cfg_.max_threads) +
                       "] (this machine's cores, ergd --max-threads)");
  auto slurm_name = [&](const char* field, const std::string& v) {
    const bool ok = v.size() <= 64 && v.find_first_not_of(
                                          "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmn"
                                          "opqrstuvwxyz0123456789_.-") == std::string::npos;
    if (!ok)
      problems.push_back(std::string("resources.") + field + ": '" + v.substr(0, 64) +
                         "' is not a Slurm name (at most 64 of A-Z a-z 0-9 _ . -)");
  };
  slurm_name("partition", res.partition());
  slurm_name("account", res.account());
  auto in_range = [&](const char* field, long long v, long long hi) {
    if (v < 0 || v > hi)
      problems.push_back(std::string("resources.") + field + ": " + std::to_string(v) +
                         " is out of range [0, " + std::to_string(hi) + "]");
  };
  if (problems.empty() && res.ranks() > 1) {
    try {
      (void)plan_tiles(spec, res.ranks());  // as the worker will tile it
    } catch (const std::invalid_argument& e) {
      problems.push_back(std::string("resources.ranks: ") + e.what());
    }
  }
  in_range("nodes", res.nodes(), 4096);
  in_range("gpus_per_node", res.gpus_per_node(), 64);
  in_range("time_limit_minutes", res.time_limit_minutes(), cfg_.max_time_limit_minutes);
  if (!problems.empty()) {
    std::string msg;
    for (const auto& p : problems) msg += (msg.empty() ? "" : "\n") + p;
    throw ApiError(grpc::StatusCode::INVALID_ARGUMENT, msg);
  }
  {
    // A job that cannot fit is refused now, not left to die of bad_alloc.
    const double cells =
        static_cast<double>(spec.domain().nx()) * static_cast<double>(spec.domain().ny());
    const double estimate = cells * static_cast<double>(kJobBytesPerCell);
    if (cfg_.max_job_memory_bytes > 0 &&
        estimate > static_cast<double>(cfg_.max_job_memory_bytes)) {
      char msg[400];
      std::snprintf(msg, sizeof msg,
                    "domain: the job's memory estimate is %s (%lld bytes per cell x %.0f cells), "
                    "more than the %s a job may use here (ergd --max-job-memory)",
                    gib(estimate).c_str(), static_cast<long long>(kJobBytesPerCell), cells,
                    gib(static_cast<double>(cfg_.max_job_memory_bytes)).c_str());
      throw ApiError(grpc::StatusCode::RESOURCE_EXHAUSTED, msg);
    }
  }

  Job job;
  job.set_id(new_job_id());
  job.set_tenant(tenant);
  job.set_state(erg::v1::QUEUED);
  *job.mutable_spec() = spec;
  *job.mutable_resources() = res;
  if (job.resources().ranks() == 0) job.mutable_resources()->set_ranks(1);
  job.mutable_progress()->set_total_steps(spec.run().steps());
  job.mutable_progress()->set_latest_snapshot_step(-1);
  job.set_created_unix_ms(now_ms());
  job.set_idempotency_key(req.idempotency_key());
  for (auto& w : erg::resolution_warnings(spec)) job.add_warnings(std::move(w));

  std::lock_guard lock(mu_);
  if (cfg_.tenant_cell_steps > 0) {
    double queued = cell_steps_of(job);
    for (const auto& j : store_.in_states({erg::v1::QUEUED, erg::v1::RUNNING}))
      if (j.tenant() == tenant) queued += cell_steps_of(j);
    if (queued > cfg_.tenant_cell_steps) {
      char msg[256];
      std::snprintf(msg, sizeof msg,
                    "tenant %s: queued and running work would be %.3g cells x steps; the limit "
                    "is %.3g (ergd --tenant-cell-steps)",
                    tenant.c_str(), queued, cfg_.tenant_cell_steps);
      throw ApiError(grpc::StatusCode::RESOURCE_EXHAUSTED, msg);
    }
  }
  if (disk_low_locked()) {
    throw ApiError(grpc::StatusCode::RESOURCE_EXHAUSTED,
                   "the data directory has " + std::to_string(free_disk_bytes()) +
                       " bytes free, less than the reserve of " +
                       std::to_string(cfg_.min_free_disk_bytes) +
                       " (ergd --min-free-disk): no new job until space is freed");
  }
  const std::string dir = job_dir(job.id());
  // All or nothing: a job is in the store with its directory, or neither.
  Job stored;
  try {
    fs::create_directories(dir + "/steer");
    io::write_file_atomic(dir + "/job.json", job::to_json(spec));
    auto [s, created] = store_.insert(job);
    if (!created) {
      fs::remove_all(dir);  // a concurrent submit with the same key won
      return s;
    }
    stored = s;
  } catch (const std::exception& e) {
    std::error_code ec;
    fs::remove_all(dir, ec);
    const std::string m = e.what();
    if (says_full(m))
      throw ApiError(grpc::StatusCode::RESOURCE_EXHAUSTED,
                     "the data directory is full: " + with_enospc(m));
    throw;
  }
  try {
    JobEvent ev;
    ev.set_state_changed(erg::v1::QUEUED);
    event_locked(stored, ev);
  } catch (const std::exception& e) {
    // The job is stored (QUEUED); only its first event is missing.
    std::cerr << "ergd: job " << stored.id() << ": cannot record its QUEUED event: " << e.what()
              << std::endl;
  }
  dirty_ = true;
  cv_.notify_all();
  return stored;
}

Job JobManager::get(const std::string& tenant, const std::string& id) {
  std::lock_guard lock(mu_);
  if (auto it = running_.find(id); it != running_.end() && it->second.job.tenant() == tenant)
    return it->second.job;
  if (auto it = unsaved_.find(id); it != unsaved_.end() && it->second.tenant() == tenant)
    return it->second;
  auto job = store_.get(id);
  // Another tenant's job is reported exactly like a job that does not exist.
  if (!job || job->tenant() != tenant)
    throw ApiError(grpc::StatusCode::NOT_FOUND, "job " + id + " not found");
  return *job;
}

std::vector<Job> JobManager::list(const std::string& tenant, int state, std::int64_t before_seq,
                                  int limit, std::int64_t* last_seq) {
  auto jobs = store_.list(tenant, state, before_seq, limit, last_seq);
  std::lock_guard lock(mu_);
  for (auto& j : jobs) {
    if (auto it = running_.find(j.id()); it != running_.end())
      j = it->second.job;
    else if (auto u = unsaved_.find(j.id()); u != unsaved_.end())
      j = u->second;
  }
  return jobs;
}

Job JobManager::cancel(const std::string& tenant, const std::string& id) {
  Job job = get(tenant, id);
  std::lock_guard lock(mu_);
  if (auto it = running_.find(id); it != running_.end()) {
    Running& r = it->second;
    if (!r.cancel_requested) {
      r.cancel_requested = true;
      r.stop_sent_at = mono_s();
      launcher_.stop(r.launcher_id, false);
      JobEvent m;
      m.set_message("cancel requested: the worker checkpoints and stops");
      event_locked(r.job, m);
    }
    return r.job;
  }
  auto fresh = store_.get(id);
  if (fresh && fresh->state() == erg::v1::QUEUED) {
    fresh->set_finished_unix_ms(now_ms());
    set_state_locked(*fresh, erg::v1::CANCELLED);
    return *fresh;
  }
  return fresh ? *fresh : job;
}

Job JobManager::resume(const std::string& tenant, const std::string& id) {
  (void)get(tenant, id);  // NOT_FOUND for another tenant's
  std::lock_guard lock(mu_);
  if (running_.count(id) || unsaved_.count(id))
    throw ApiError(grpc::StatusCode::FAILED_PRECONDITION,
                   "job " + id + " is not FAILED; only a FAILED job can be resumed");
  auto job = store_.get(id);
  if (!job || job->tenant() != tenant)
    throw ApiError(grpc::StatusCode::NOT_FOUND, "job " + id + " not found");
  if (job->state() != erg::v1::FAILED)
    throw ApiError(grpc::StatusCode::FAILED_PRECONDITION, "job " + id + " is " +
                                                              erg::v1::JobState_Name(job->state()) +
                                                              "; only a FAILED job can be resumed");
  bool has_checkpoint = false;
  std::error_code ec;
  for (auto it = fs::directory_iterator(fs::path(job_dir(id)) / "run" / "checkpoints", ec);
       !ec && it != fs::end(it); it.increment(ec))
    if (it->path().extension() == ".h5") has_checkpoint = true;
  if (!has_checkpoint)
    throw ApiError(grpc::StatusCode::FAILED_PRECONDITION,
                   "job " + id +
                       " has no checkpoint to resume from (it failed before its first; "
                       "submit it again)");
  const std::string was = job->failure_reason();
  job->clear_failure_reason();
  job->clear_log_tail();
  job->set_finished_unix_ms(0);
  job->set_worker_retries(0);
  job->clear_launcher_id();
  set_state_locked(
      *job, erg::v1::QUEUED,
      "resumed by its tenant (erg resume): queued again; the worker continues from its "
      "newest intact checkpoint (it had failed: " +
          was.substr(0, 300) + ")");
  dirty_ = true;
  cv_.notify_all();
  return *job;
}

erg::v1::SteerJobResponse JobManager::steer(const std::string& tenant, const std::string& id,
                                            const std::vector<erg::v1::Event>& events) {
  (void)get(tenant, id);
  for (size_t k = 0; k < events.size(); ++k)
    refuse_map_files(events[k], "events[" + std::to_string(k) + "]");
  if (events.empty())
    throw ApiError(grpc::StatusCode::INVALID_ARGUMENT, "events: at least one event is needed");
  if (events.size() > 1000)
    throw ApiError(grpc::StatusCode::RESOURCE_EXHAUSTED, "events: at most 1000 per call");
  std::unique_lock lock(mu_);
  auto it = running_.find(id);
  if (it == running_.end() || it->second.cancel_requested || it->second.stop_for_shutdown)
    throw ApiError(grpc::StatusCode::FAILED_PRECONDITION,
                   "job " + id + " is not running; only a RUNNING job can be steered");
  // Validate as the worker will: the recorded spec with the events appended.
  erg::v1::JobSpec trial = it->second.job.spec();
  const std::int64_t step = it->second.job.progress().step();
  for (auto e : events) {
    e.set_step(step);
    *trial.add_events() = e;
  }
  job::apply_defaults(trial);
  auto problems = job::validate(trial, "/nonexistent");
  if (!problems.empty()) {
    std::string msg;
    for (const auto& p : problems) msg += (msg.empty() ? "" : "\n") + p;
    throw ApiError(grpc::StatusCode::INVALID_ARGUMENT, msg);
  }
  std::vector<std::string> files;
  std::vector<std::pair<std::string, std::string>> contents;
  const std::uint64_t seq = ++steer_seq_;
  for (size_t k = 0; k < events.size(); ++k) {
    char name[64];
    std::snprintf(name, sizeof name, "%013lld-%06llu-%04zu.json", static_cast<long long>(now_ms()),
                  static_cast<unsigned long long>(seq), k);
    std::string json;
    google::protobuf::util::JsonPrintOptions opt;
    opt.preserve_proto_field_names = true;
    (void)google::protobuf::util::MessageToJsonString(events[k], &json, opt);
    contents.emplace_back(job_dir(id) + "/steer/" + name, std::move(json));
    files.push_back(name);
  }
  // Together: the worker applies the events of one call at one step.
  io::write_files_atomic(contents);
  // The worker applies them at its next step boundary and says so.
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(120);
  erg::v1::SteerJobResponse out;
  for (;;) {
    auto r = running_.find(id);
    if (r == running_.end())
      throw ApiError(grpc::StatusCode::FAILED_PRECONDITION,
                     "job " + id + " ended before the steering events were applied");
    size_t done = 0;
    std::string rejected;
    for (const auto& f : files) {
      if (r->second.steered.count(f)) ++done;
      if (auto rj = r->second.steer_rejected.find(f); rj != r->second.steer_rejected.end()) {
        ++done;
        rejected += (rejected.empty() ? "" : "\n") + rj->second;
      }
    }
    if (done == files.size()) {
      if (!rejected.empty()) throw ApiError(grpc::StatusCode::INVALID_ARGUMENT, rejected);
      for (const auto& f : files) *out.add_applied() = r->second.steered.at(f);
      *out.mutable_job() = r->second.job;
      return out;
    }
    if (cv_.wait_until(lock, deadline) == std::cv_status::timeout)
      throw ApiError(grpc::StatusCode::DEADLINE_EXCEEDED,
                     "the worker did not apply the steering events within 120 s");
  }
}

// ---- running jobs -----------------------------------------------------------

LaunchRequest JobManager::request_for(const Job& job) const {
  const std::string dir = job_dir(job.id());
  LaunchRequest req;
  req.job_id = job.id();
  req.job_file = dir + "/job.json";
  req.out_dir = dir + "/run";
  req.steer_dir = dir + "/steer";
  req.log_path = dir + "/worker.log";
  req.ranks = std::max(1, job.resources().ranks());
  req.threads = job.resources().threads_per_rank();
  req.attempt = std::max(1, job.attempts());
  req.partition = job.resources().partition();
  req.account = job.resources().account();
  req.nodes = job.resources().nodes();
  req.gpus_per_node = job.resources().gpus_per_node();
  req.time_limit_minutes = job.resources().time_limit_minutes();
  return req;
}

LaunchCallbacks JobManager::callbacks(const std::string& id) {
  return {[this, id](const erg::v1::WorkerEvent& ev, std::int64_t offset) {
            guarded(id, "a worker event", [&] { on_event(id, ev, offset); });
          },
          [this, id](int code) { guarded(id, "the worker's exit", [&] { on_exit(id, code); }); },
          [this, id](const std::string& state) {
            guarded(id, "a scheduler state", [&] { on_state(id, state); });
          }};
}

template <class F>
void JobManager::guarded(const std::string& id, const char* what, F&& f) {
  try {
    f();
  } catch (const std::exception& e) {
    std::cerr << "ergd: job " << id << ": cannot record " << what << ": " << e.what() << std::endl;
    try {
      std::lock_guard lock(mu_);
      store_failed_locked(id, e.what());
    } catch (...) {
    }
  } catch (...) {
    std::cerr << "ergd: job " << id << ": cannot record " << what << std::endl;
  }
}

// The store refused a write for a running job: the job fails (its record
// would otherwise fall behind its worker) and its worker is stopped.
void JobManager::store_failed_locked(const std::string& id, const std::string& why) {
  auto it = running_.find(id);
  if (it == running_.end()) return;
  Running& r = it->second;
  if (r.failure.empty()) r.failure = with_enospc("ergd cannot record the job: " + why);
  if (r.stop_sent_at == 0) {
    r.stop_sent_at = mono_s();
    launcher_.stop(r.launcher_id, false);
  }
}

std::int64_t JobManager::free_disk_bytes() const {
  struct statvfs v {};
  if (::statvfs(cfg_.data_dir.c_str(), &v) != 0) return -1;
  return static_cast<std::int64_t>(v.f_bavail) * static_cast<std::int64_t>(v.f_frsize);
}

bool JobManager::disk_low_locked() {
  const double now = mono_s();
  if (now - last_disk_probe_ >= 2.0) {
    last_disk_probe_ = now;
    const std::int64_t free = free_disk_bytes();
    const bool low = free >= 0 && free < cfg_.min_free_disk_bytes;
    if (low != disk_low_)
      std::cerr << "ergd: the data directory has " << free
                << " bytes free: " << (low ? "below" : "back above") << " the reserve of "
                << cfg_.min_free_disk_bytes << " bytes (--min-free-disk); "
                << (low ? "refusing new jobs, queued jobs wait" : "accepting jobs again")
                << std::endl;
    disk_low_ = low;
    if (!low) store_.restore_reserve();
  }
  return disk_low_;
}

void JobManager::flush_unsaved_locked() {
  for (auto it = unsaved_.begin(); it != unsaved_.end();) {
    try {
      store_.update(it->second);
      JobEvent ev;
      ev.set_state_changed(it->second.state());
      event_locked(it->second, ev);
      std::cerr << "ergd: job " << it->first << ": its state is stored again" << std::endl;
      it = unsaved_.erase(it);
    } catch (const std::exception&) {
      ++it;  // still no room; the job is served from memory meanwhile
    }
  }
}

void JobManager::launch_locked(Job job) {
  const std::string dir = job_dir(job.id());
  const fs::path run = fs::path(dir) / "run";
  bool has_checkpoint = false;
  std::error_code ec;
  for (auto it = fs::directory_iterator(run / "checkpoints", ec); !ec && it != fs::end(it);
       it.increment(ec))
    if (it->path().extension() == ".h5") has_checkpoint = true;
  if (!has_checkpoint) fs::remove_all(run, ec);  // a start that wrote no checkpoint: start over
  fs::create_directories(fs::path(dir) / "steer");
  job.set_attempts(job.attempts() + 1);
  LaunchRequest req = request_for(job);
  req.resume = has_checkpoint;
  const std::string id = job.id();
  Running& r = running_[id];
  try {
    r.launcher_id = launcher_.start(req, callbacks(id));
  } catch (const std::exception& e) {
    running_.erase(id);
    job.set_failure_reason(std::string("cannot start the worker: ") + e.what());
    job.set_finished_unix_ms(now_ms());
    set_state_locked(job, erg::v1::FAILED);
    return;
  }
  r.resumed = has_checkpoint;
  job.set_launcher_id(r.launcher_id);
  job.set_launcher_host(launcher_.reattachable() ? "" : host_name());
  job.set_launcher(launcher_.name());
  job.set_launcher_offset(0);
  job.set_launcher_state("");
  if (job.started_unix_ms() == 0) job.set_started_unix_ms(now_ms());
  r.job = job;
  r.last_saved = mono_s();
  // A batch scheduler may keep the job waiting: it is RUNNING once it runs.
  const bool batch = launcher_.reattachable();
  std::string note = has_checkpoint ? "resumed from the last checkpoint (attempt " +
                                          std::to_string(job.attempts()) + ")"
                                    : "";
  if (batch)
    note += (note.empty() ? "" : "; ") + std::string("submitted to ") + launcher_.name() +
            " as job " + r.launcher_id;
  set_state_locked(r.job, batch ? erg::v1::QUEUED : erg::v1::RUNNING, note);
}

void JobManager::on_state(const std::string& id, const std::string& state) {
  std::lock_guard lock(mu_);
  auto it = running_.find(id);
  if (it == running_.end()) return;
  Job& job = it->second.job;
  job.set_launcher_state(state);
  const bool running = state == "RUNNING" || state == "COMPLETING" || state == "STAGE_OUT";
  const bool waiting = state == "PENDING" || state == "REQUEUED" || state == "CONFIGURING" ||
                       state == "REQUEUE_HOLD" || state == "REQUEUE_FED" || state == "SUSPENDED";
  const auto want = running ? erg::v1::RUNNING : waiting ? erg::v1::QUEUED : job.state();
  JobEvent m;
  m.set_message(launcher_.name() + " job " + it->second.launcher_id + ": " + state);
  event_locked(job, m);
  if (want != job.state())
    set_state_locked(job, want);
  else
    store_.update(job);
}

void JobManager::on_event(const std::string& id, const erg::v1::WorkerEvent& ev,
                          std::int64_t offset) {
  using Kind = erg::v1::WorkerEvent::KindCase;
  std::lock_guard lock(mu_);
  auto it = running_.find(id);
  if (it == running_.end()) return;
  Running& r = it->second;
  if (offset > 0) r.job.set_launcher_offset(offset);  // saved with the next update
  auto& p = *r.job.mutable_progress();
  const double now = mono_s();
  switch (ev.kind_case()) {
    case Kind::kStart:
      // The worker runs (a batch job may start before squeue says so).
      if (r.job.state() == erg::v1::QUEUED) set_state_locked(r.job, erg::v1::RUNNING);
      p.set_step(ev.step());
      p.set_total_steps(ev.start().steps());
      if (r.resumed) {
        // Which checkpoint the worker took (the newest intact one): its step.
        JobEvent m;
        m.set_message("attempt " + std::to_string(r.job.attempts()) +
                      ": the worker resumed from its checkpoint of step " +
                      std::to_string(p.step()));
        event_locked(r.job, m);
      }
      break;
    case Kind::kProgress:
    case Kind::kDone: {
      const bool done = ev.kind_case() == Kind::kDone;
      p.set_step(ev.step());
      const erg::v1::WorkerEvent::Totals& totals =
          done ? ev.done().totals() : ev.progress().totals();
      if (!done) {
        const auto& q = ev.progress();
        p.set_total_steps(q.steps());
        p.set_steps_per_s(q.steps_per_s());
        p.set_eta_s(q.eta_s());
        p.set_time_days(q.time_days());
        p.set_time_years(q.time_years());
        metrics_.set_rate(id, r.job.tenant(), p.steps_per_s());
      } else {
        p.set_eta_s(0);
      }
      if (!totals.sand_units_total().empty()) p.set_sand_units_total(totals.sand_units_total());
      if (!totals.airborne_units_total().empty())
        p.set_airborne_units_total(totals.airborne_units_total());
      if (done || now - r.last_saved >= 1.0) {
        r.last_saved = now;
        store_.update(r.job);
      }
      if (done || now - r.last_progress_event >= 1.0) {
        r.last_progress_event = now;
        JobEvent e;
        *e.mutable_progress() = p;
        event_locked(r.job, e);
      }
      break;
    }
    case Kind::kSnapshot: {
      const std::int64_t step = ev.step();
      auto* steps = r.job.mutable_snapshot_steps();
      if (std::find(steps->begin(), steps->end(), step) == steps->end()) steps->Add(step);
      p.set_latest_snapshot_step(step);
      store_.update(r.job);
      JobEvent e;
      e.set_snapshot_step(step);
      event_locked(r.job, e);
      break;
    }
    case Kind::kSteered: {
      erg::v1::Event applied = ev.steered().event();
      applied.set_step(ev.step());
      *r.job.mutable_spec()->add_events() = applied;  // the recorded spec
      r.steered[ev.steered().file()] = applied;
      store_.update(r.job);
      JobEvent e;
      *e.mutable_steered() = applied;
      event_locked(r.job, e);
      cv_.notify_all();
      break;
    }
    case Kind::kSteerRejected:
      r.steer_rejected[ev.steer_rejected().file()] = ev.steer_rejected().reason();
      cv_.notify_all();
      break;
    case Kind::kStopped:
      // Stopped on a signal after a checkpoint: where the job really is.
      r.stopped_by_signal = true;
      if (ev.step() >= 0) p.set_step(ev.step());
      p.set_steps_per_s(0);
      store_.update(r.job);
      break;
    case Kind::kFailed:
      r.failure = ev.failed().reason();
      break;
    case Kind::KIND_NOT_SET:  // an event kind newer than this ergd
      break;
  }
}

void JobManager::finish_locked(Running& r, JobState state, const std::string& reason) {
  Job& job = r.job;
  job.set_finished_unix_ms(now_ms());
  job.set_disk_bytes(dir_bytes(job_dir(job.id())));
  if (state == erg::v1::FAILED) {
    job.set_failure_reason(with_enospc(reason));
    job.set_log_tail(log_tail(job.id(), 20));
  }
  metrics_.remove_rate(job.id(), job.tenant());
  set_state_locked(job, state);
}

void JobManager::on_exit(const std::string& id, int code) {
  std::lock_guard lock(mu_);
  auto it = running_.find(id);
  if (it == running_.end()) return;
  Running& r = it->second;
  // The final state is served from memory when the store cannot take it
  // (a full disk), and stored as soon as it can (flush_unsaved_locked).
  const auto finish = [&](JobState state, const std::string& reason) {
    try {
      finish_locked(r, state, reason);
    } catch (const std::exception& e) {
      std::cerr << "ergd: job " << id << ": cannot store its end (" << e.what()
                << "); serving it from memory until the store takes it" << std::endl;
      r.job.set_state(state);
      if (state == erg::v1::FAILED && r.job.failure_reason().empty())
        r.job.set_failure_reason(with_enospc(reason));
      unsaved_[id] = r.job;
    }
  };
  try {
    if (code == 0 && r.failure.empty()) {
      finish(erg::v1::SUCCEEDED, "");
    } else if (r.cancel_requested) {
      finish(erg::v1::CANCELLED, "");
    } else if (r.stop_for_shutdown) {
      store_.update(r.job);  // stays RUNNING: the next ergd resumes it
      metrics_.remove_rate(id, r.job.tenant());
    } else if (r.stopped_by_signal && r.failure.empty() && r.job.attempts() < cfg_.max_attempts) {
      // Stopped from outside after writing a checkpoint (the batch system's
      // walltime warning, preemption): queue it again; it resumes.
      metrics_.remove_rate(id, r.job.tenant());
      r.job.clear_launcher_id();
      set_state_locked(r.job, erg::v1::QUEUED,
                       "the worker was stopped by a signal at step " +
                           std::to_string(r.job.progress().step()) +
                           " after writing a checkpoint (walltime or preemption): it resumes");
    } else if (r.stopped_by_signal && r.failure.empty()) {
      finish(erg::v1::FAILED, "stopped by a signal " + std::to_string(r.job.attempts()) +
                                  " times; ergd gives up after --max-attempts " +
                                  std::to_string(cfg_.max_attempts));
    } else if (r.failure.empty() && code != 2 && r.job.worker_retries() < cfg_.worker_retries) {
      // The worker died without saying why (killed, crashed, a rank lost):
      // not the job's fault, so it runs again from its newest intact
      // checkpoint (the worker verifies it and names the one it takes). Exit
      // code 2 is a bad job or no usable checkpoint: retrying cannot help.
      metrics_.remove_rate(id, r.job.tenant());
      r.job.set_worker_retries(r.job.worker_retries() + 1);
      r.job.clear_launcher_id();
      set_state_locked(r.job, erg::v1::QUEUED,
                       "the worker died at step " + std::to_string(r.job.progress().step()) + " (" +
                           exit_text(code) + "): retry " + std::to_string(r.job.worker_retries()) +
                           " of " + std::to_string(cfg_.worker_retries) +
                           " (ergd --worker-retries), from its newest intact checkpoint");
    } else {
      std::string why = !r.failure.empty() ? r.failure : "the worker " + exit_text(code);
      if (r.failure.empty() && code != 2)
        why += " (" +
               (cfg_.worker_retries > 0 ? "after " + std::to_string(r.job.worker_retries()) +
                                              " retries, ergd --worker-retries; "
                                        : std::string()) +
               "erg resume " + id + " continues it from its checkpoint)";
      finish(erg::v1::FAILED, why);
    }
  } catch (const std::exception& e) {
    // A requeue that could not be stored: the job stays as the store has it
    // (RUNNING), and the next ergd start resumes it.
    std::cerr << "ergd: job " << id << ": cannot store its next state: " << e.what() << std::endl;
  }
  running_.erase(it);
  dirty_ = true;
  cv_.notify_all();
}

void JobManager::start_next_locked() {
  if (stopping_ || static_cast<int>(running_.size()) >= cfg_.max_running) return;
  std::vector<Job> queued;
  for (auto& j : store_.in_states({erg::v1::QUEUED}))
    if (!running_.count(j.id())) queued.push_back(std::move(j));  // not waiting in Slurm
  while (!queued.empty() && static_cast<int>(running_.size()) < cfg_.max_running) {
    std::map<std::string, int> per_tenant;
    for (const auto& [id, r] : running_) ++per_tenant[r.job.tenant()];
    // The tenant with the fewest running jobs; among those, the one whose
    // last start is oldest (round robin); its oldest job (FIFO).
    auto rank = [&](const Job& j) {
      auto it = last_start_.find(j.tenant());
      return std::pair(per_tenant[j.tenant()], it == last_start_.end() ? 0u : it->second);
    };
    size_t best = 0;
    for (size_t i = 1; i < queued.size(); ++i)
      if (rank(queued[i]) < rank(queued[best])) best = i;
    last_start_[queued[best].tenant()] = ++start_counter_;
    Job job = queued[best];
    queued.erase(queued.begin() + static_cast<long>(best));
    launch_locked(std::move(job));
  }
}

void JobManager::refresh_metrics() {
  const char* names[] = {"", "QUEUED", "RUNNING", "SUCCEEDED", "FAILED", "CANCELLED"};
  std::map<int, std::int64_t> counts;
  for (auto [state, n] : store_.count_by_state()) counts[state] = n;
  for (int s = 1; s <= 5; ++s) metrics_.set_jobs(names[s], static_cast<double>(counts[s]));
}

void JobManager::scheduler_loop() {
  double last_metrics = 0;
  std::unique_lock lock(mu_);
  while (!stopping_) {
    cv_.wait_for(lock, std::chrono::milliseconds(200));
    if (stopping_) break;
    const double now = mono_s();
    for (auto& [id, r] : running_) {
      // Forced stop after the grace period (cancel, or a limit).
      if (r.stop_sent_at > 0 && now - r.stop_sent_at > cfg_.cancel_grace_s) {
        launcher_.stop(r.launcher_id, true);
        r.stop_sent_at = now;  // again after another grace period if need be
      }
      if (now - r.last_disk_check >= 2.0) {
        r.last_disk_check = now;
        r.job.set_disk_bytes(dir_bytes(job_dir(id)));
        if (cfg_.max_job_disk_bytes > 0 && r.job.disk_bytes() > cfg_.max_job_disk_bytes &&
            r.failure.empty()) {
          r.failure = "the job's output is " + std::to_string(r.job.disk_bytes()) +
                      " bytes, over the per-job disk limit of " +
                      std::to_string(cfg_.max_job_disk_bytes) +
                      " (ergd --max-job-disk); write fewer snapshots (run.snapshot_every)";
          r.stop_sent_at = now;
          launcher_.stop(r.launcher_id, false);
        }
      }
    }
    // Nothing thrown here may end the scheduler (or ergd): a store that
    // cannot write leaves the queue as it is, and the next round tries again.
    try {
      if (!unsaved_.empty() && now - last_metrics >= 1.0) flush_unsaved_locked();
      if (dirty_ && !disk_low_locked()) {
        dirty_ = false;
        start_next_locked();
      } else if (dirty_ || now - last_disk_probe_ >= 2.0) {
        (void)disk_low_locked();  // notices when space comes back
      }
      if (now - last_metrics >= 1.0) {
        last_metrics = now;
        refresh_metrics();
      }
    } catch (const std::exception& e) {
      std::cerr << "ergd: scheduler: " << e.what() << std::endl;
      dirty_ = true;
      last_metrics = now;
    }
  }
}

void JobManager::recover(Job job) {
  if (job.launcher_id().empty()) return;  // never launched: the queue takes it
  std::lock_guard lock(mu_);
  if (launcher_.reattachable()) {
    // Slurm jobs outlive ergd: follow them again from where we left off.
    Running& r = running_[job.id()];
    r.job = job;
    r.launcher_id = job.launcher_id();
    r.last_saved = mono_s();
    launcher_.attach(job.launcher_id(), request_for(job), job.launcher_offset(),
                     callbacks(job.id()));
    JobEvent m;
    m.set_message("ergd restarted: following " + launcher_.name() + " job " + job.launcher_id() +
                  " again");
    event_locked(job, m);
    return;
  }
  // Local workers got SIGTERM when the old ergd died (or were stopped at
  // its shutdown) and checkpointed. Wait for any still writing, then
  // queue the job again ahead of newer jobs (same seq); it resumes.
  if (launcher_.alive(job.launcher_id())) {
    launcher_.stop(job.launcher_id(), false);
    const double t0 = mono_s();
    while (launcher_.alive(job.launcher_id())) {
      if (mono_s() - t0 > cfg_.cancel_grace_s) launcher_.stop(job.launcher_id(), true);
      ::usleep(100 * 1000);
    }
  }
  job.clear_launcher_id();
  set_state_locked(job, erg::v1::QUEUED,
                   "ergd restarted while the job ran: it resumes from its last checkpoint");
}

void JobManager::start() {
  // Jobs a previous ergd had launched (a launcher id, not final). A store
  // that cannot write (ergd started on a full disk) fails none of this:
  // each job is retried by the queue, and ergd serves reads meanwhile.
  std::vector<Job> left;
  try {
    left = store_.in_states({erg::v1::QUEUED, erg::v1::RUNNING});
  } catch (const std::exception& e) {
    std::cerr << "ergd: cannot list the jobs to resume: " << e.what() << std::endl;
  }
  for (Job job : left) {
    try {
      recover(job);
    } catch (const std::exception& e) {
      std::cerr << "ergd: job " << job.id() << ": cannot resume it now (" << e.what()
                << "); it resumes at the next start of ergd" << std::endl;
    }
  }
  {
    std::lock_guard lock(mu_);
    dirty_ = true;
    refresh_metrics();
  }
  scheduler_ = std::thread([this] { scheduler_loop(); });
}

void JobManager::shutdown() {
  if (launcher_.reattachable()) {
    // Batch jobs run on without ergd; the next ergd follows them again.
    stopping_ = true;
    launcher_.detach_all();
    {
      std::lock_guard lock(mu_);
      for (auto& [id, r] : running_) store_.update(r.job);
      running_.clear();
    }
    cv_.notify_all();
    if (scheduler_.joinable()) scheduler_.join();
    return;
  }
  {
    std::unique_lock lock(mu_);
    stopping_ = true;
    for (auto& [id, r] : running_) {
      r.stop_for_shutdown = true;
      r.stop_sent_at = mono_s();
      launcher_.stop(r.launcher_id, false);
    }
    const double t0 = mono_s();
    bool forced = false;
    while (!running_.empty()) {
      cv_.wait_for(lock, std::chrono::milliseconds(100));
      if (!forced && mono_s() - t0 > cfg_.cancel_grace_s) {
        forced = true;
        for (auto& [id, r] : running_) launcher_.stop(r.launcher_id, true);
      }
      if (mono_s() - t0 > cfg_.cancel_grace_s + 10) break;
    }
  }
  cv_.notify_all();
  if (scheduler_.joinable()) scheduler_.join();
}

}  // namespace erg::server

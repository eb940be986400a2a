// SPDX-License-Identifier: Apache-2.0
// The heart of ergd: accepts jobs, keeps them in the store, runs a bounded
// number at once through a Launcher, turns the workers' progress lines into
// job state and events, cancels, steers, and after a restart resumes the
// jobs whose workers died meanwhile from their checkpoints.
//
// Queue: FIFO within a tenant; across tenants, the next job comes from the
// tenant with the fewest running jobs, ties broken round robin (the tenant
// that started a job least recently), so one tenant's hundred jobs do not
// starve another tenant's one.
//
// Per job on disk, under DATA/jobs/ID/:
//   job.json    the spec as submitted (defaults filled)
//   run/        the worker's output directory (README "Outputs")
//   steer/      steering files for the worker (--steer-dir)
//   worker.log  the worker's stderr (the tail of it explains a failure)
#pragma once

#include <grpcpp/support/status.h>

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <map>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "erg/v1/service.pb.h"
#include "launch/launcher.h"
#include "metrics/metrics.h"
#include "store/job_store.h"

namespace erg::server {

// A call that cannot be done, with the gRPC status it maps to.
struct ApiError : std::runtime_error {
  ApiError(grpc::StatusCode c, const std::string& m) : std::runtime_error(m), code(c) {}
  grpc::StatusCode code;
};

struct ManagerConfig {
  std::string data_dir;
  int max_running = 2;                  // jobs running at once
  int max_ranks = 0;                    // per job; 0: this machine's cores
  double cancel_grace_s = 30;           // SIGTERM, then SIGKILL after this
  std::int64_t max_job_disk_bytes = 0;  // per job output; 0: no limit
  double tenant_cell_steps = 0;         // queued + running cells x steps per tenant; 0: none
  std::int64_t max_spec_bytes = 256 * 1024;
  // A worker stopped by a signal after a checkpoint (Slurm's walltime
  // warning, preemption) is started again, at most this many times in all.
  int max_attempts = 10;
  // A worker that dies (killed by a signal it was not sent by ergd, or a
  // crash: no "failed" event) is started again from its newest intact
  // checkpoint, at most this many times until the job ends or is resumed
  // (ResumeJob resets the count; 0: never).
  int worker_retries = 3;
  int max_time_limit_minutes = 7 * 24 * 60;  // Resources.time_limit_minutes
  // Submissions are refused (RESOURCE_EXHAUSTED), and queued jobs wait,
  // while the data directory's file system has less free space than this.
  std::int64_t min_free_disk_bytes = std::int64_t{256} << 20;
  // A job whose memory estimate (kJobBytesPerCell x cells) is above this is
  // refused at submission; 0: this machine's memory (or its cgroup's limit).
  std::int64_t max_job_memory_bytes = 0;
  int max_threads = 0;  // Resources.threads_per_rank at most; 0: this machine's cores
};

// What a running worker holds per cell of its domain, all ranks together:
// the largest peak measured at 4096² and beyond, the part that does not
// grow with the domain included (README "Memory": 92 bytes per cell at
// 4096² and 74 at 16384² on 2 ranks; CPU backend, snapshots and checkpoints
// included), rounded up.
inline constexpr std::int64_t kJobBytesPerCell = 100;

class JobManager {
 public:
  JobManager(JobStore& store, Launcher& launcher, Metrics& metrics, ManagerConfig cfg);
  ~JobManager();

  // Resumes what a previous ergd left running, then starts the scheduler.
  void start();
  // Asks every running worker to checkpoint and stop, waits for them (up to
  // the grace period), and leaves their jobs RUNNING in the store: the next
  // ergd resumes them.
  void shutdown();

  erg::v1::Job submit(const std::string& tenant, const erg::v1::SubmitJobRequest& req);
  erg::v1::Job get(const std::string& tenant, const std::string& id);  // NOT_FOUND
  erg::v1::Job cancel(const std::string& tenant, const std::string& id);
  // A FAILED job with a checkpoint is queued again and resumes from it
  // (FAILED_PRECONDITION otherwise).
  erg::v1::Job resume(const std::string& tenant, const std::string& id);
  erg::v1::SteerJobResponse steer(const std::string& tenant, const std::string& id,
                                  const std::vector<erg::v1::Event>& events);
  std::vector<erg::v1::Job> list(const std::string& tenant, int state, std::int64_t before_seq,
                                 int limit, std::int64_t* last_seq);

  std::string job_dir(const std::string& id) const;
  std::string snapshot_path(const std::string& id, std::int64_t step) const;
  std::string preview_path(const std::string& id, std::int64_t step) const;
  JobStore& store() { return store_; }

 private:
  struct Running {
    erg::v1::Job job;  // fresher than the store: progress is saved once a second
    std::string launcher_id;
    bool cancel_requested = false;
    bool stop_for_shutdown = false;
    bool stopped_by_signal = false;  // the worker said "stopped" (checkpoint written)
    bool resumed = false;            // started with --resume (a checkpoint existed)
    double stop_sent_at = 0;         // monotonic seconds; 0: not asked to stop
    double last_saved = 0;
    double last_progress_event = 0;
    double last_disk_check = 0;
    std::string failure;                                // from a "failed" line or a limit
    std::map<std::string, erg::v1::Event> steered;      // steering file -> applied event
    std::map<std::string, std::string> steer_rejected;  // steering file -> reason
  };

  void scheduler_loop();
  void recover(erg::v1::Job job);  // start(): one job a previous ergd had launched
  void start_next_locked();
  void launch_locked(erg::v1::Job job);
  void on_event(const std::string& id, const erg::v1::WorkerEvent& ev, std::int64_t offset);
  void on_state(const std::string& id, const std::string& state);
  LaunchCallbacks callbacks(const std::string& id);
  LaunchRequest request_for(const erg::v1::Job& job) const;
  void on_exit(const std::string& id, int code);
  void finish_locked(Running& r, erg::v1::JobState state, const std::string& reason);
  void event_locked(const erg::v1::Job& job, erg::v1::JobEvent ev);
  void set_state_locked(erg::v1::Job& job, erg::v1::JobState s, const std::string& note = "");
  void refresh_metrics();
  // A callback of the launcher, run so that nothing escapes to its thread: a
  // store write that fails fails the job (and stops its worker), never ergd.
  template <class F>
  void guarded(const std::string& id, const char* what, F&& f);
  void store_failed_locked(const std::string& id, const std::string& why);
  // Free bytes of the data directory's file system (statvfs; -1: unknown).
  std::int64_t free_disk_bytes() const;
  bool disk_low_locked();  // below cfg_.min_free_disk_bytes (checked every 2 s)
  void flush_unsaved_locked();
  double cell_steps_of(const erg::v1::Job& job) const;
  std::string log_tail(const std::string& id, int lines) const;

  JobStore& store_;
  Launcher& launcher_;
  Metrics& metrics_;
  ManagerConfig cfg_;
  std::mutex mu_;
  std::condition_variable cv_;  // scheduler wake-ups, steering replies
  std::map<std::string, Running> running_;
  // Jobs whose last change could not be stored (a full disk): served from
  // here and written again every 2 s until the store takes them.
  std::map<std::string, erg::v1::Job> unsaved_;
  double last_disk_probe_ = -1e9;
  bool disk_low_ = false;
  std::atomic<bool> stopping_{false};
  bool dirty_ = true;  // the queue or the running set changed: try to start jobs
  std::thread scheduler_;
  std::uint64_t steer_seq_ = 0;
  std::map<std::string, std::uint64_t> last_start_;  // tenant -> start_counter_ at its last start
  std::uint64_t start_counter_ = 0;
};

}  // namespace erg::server

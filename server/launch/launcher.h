// SPDX-License-Identifier: Apache-2.0
// How ergd starts and stops workers: the local launcher (this machine,
// mpirun or erg-worker directly, the default) and Slurm (sbatch).
#pragma once

#include <cstdint>
#include <functional>
#include <iostream>
#include <string>

#include "job/worker_event.h"

namespace erg::server {

struct LaunchRequest {
  std::string job_id;
  std::string job_file;   // DATA/jobs/ID/job.json: the recorded spec at submission
  std::string out_dir;    // DATA/jobs/ID/run: snapshots, previews, checkpoints
  std::string steer_dir;  // DATA/jobs/ID/steer: steering files for the worker
  std::string log_path;   // DATA/jobs/ID/worker.log: the worker's stderr
  bool resume = false;    // --resume out_dir (a checkpoint exists)
  int ranks = 1;
  int threads = 0;  // per rank; 0: the launcher decides
  int attempt = 1;  // 1 for the first start, 2 after one resume, ...
  // Slurm only (validated by ergd; empty or 0: the launcher's defaults).
  std::string partition, account;
  int nodes = 0, gpus_per_node = 0, time_limit_minutes = 0;
};

struct LaunchCallbacks {
  // One event of the worker (proto/erg/v1/worker.proto), and where the line
  // after it starts in the worker's progress file (0: a pipe).
  std::function<void(const erg::v1::WorkerEvent& event, std::int64_t offset)> on_event;
  // The worker ended: its exit code (128 + signal when killed).
  std::function<void(int exit_code)> on_exit;
  // The scheduler's state of the job changed (Slurm: PENDING, RUNNING, ...).
  std::function<void(const std::string& state)> on_state;
};

// One line the worker wrote on its progress descriptor: parsed as a
// WorkerEvent and passed on. Lines that are not JSON objects (an MPI
// launcher's own notes) are skipped; a broken event is logged and skipped.
inline void deliver_line(const LaunchCallbacks& cb, const std::string& line, std::int64_t offset) {
  if (line.empty() || line[0] != '{') return;
  std::string error;
  if (const auto event = job::parse_worker_event(line, &error))
    cb.on_event(*event, offset);
  else
    std::cerr << "ergd: skipping a worker line that is not an erg.v1.WorkerEvent (" << error
              << "): " << line.substr(0, 200) << "\n";
}

class Launcher {
 public:
  virtual ~Launcher() = default;
  // Starts a worker; returns its launcher id (a process id, a Slurm job id).
  // Throws std::runtime_error when it cannot start.
  virtual std::string start(const LaunchRequest& req, LaunchCallbacks cb) = 0;
  // Asks the worker to stop (it checkpoints and exits), or kills it.
  virtual void stop(const std::string& launcher_id, bool force) = 0;
  // Whether a worker started by an earlier ergd still runs (recovery).
  virtual bool alive(const std::string& launcher_id) = 0;
  virtual std::string name() const = 0;
  // Whether workers outlive ergd (Slurm jobs do; local ones die with it),
  // and attaching to one after a restart, reading its progress from offset.
  virtual bool reattachable() const { return false; }
  virtual void attach(const std::string& launcher_id, const LaunchRequest& req, std::int64_t offset,
                      LaunchCallbacks cb) {
    (void)launcher_id, (void)req, (void)offset, (void)cb;
  }
  // Stops following workers (ergd is exiting); no callback runs afterwards.
  virtual void detach_all() {}
};

}  // namespace erg::server

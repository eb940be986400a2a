// How ergd starts and stops workers. The local launcher (this machine,
// mpirun or erg-worker directly) is the default; issue 5 adds Slurm.
#pragma once

#include <functional>
#include <string>

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
};

struct LaunchCallbacks {
  // One progress-event line of the worker (worker/job/progress_line.h).
  std::function<void(const std::string& line)> on_line;
  // The worker ended: its exit code (128 + signal when killed).
  std::function<void(int exit_code)> on_exit;
};

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
};

}  // namespace erg::server

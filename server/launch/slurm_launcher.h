// SPDX-License-Identifier: Apache-2.0
// Runs workers as Slurm batch jobs (`ergd --launcher slurm`): renders
// deploy/slurm/ergd-job.sbatch into DATA/jobs/ID/job.sbatch and submits it
// with sbatch; follows the job with squeue and the worker's progress file;
// stops it with scancel. Slurm jobs outlive ergd: a restarted ergd attaches
// to them again (reattachable()). Snapshots and the progress file live in
// ergd's data directory, which must be on a file system every node sees.
#pragma once

#include <atomic>
#include <map>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "launch/launcher.h"

namespace erg::server {

struct SlurmConfig {
  std::string template_path;       // --slurm-template
  std::string worker, mpirun;      // paths as the compute nodes see them
  std::string partition, account;  // defaults; "" leaves them to Slurm
  int time_limit_minutes = 60;
  int gpus_per_node = 0;
  int signal_s = 120;  // SIGTERM this long before the walltime: checkpoint and resubmit
  std::string sbatch = "sbatch", squeue = "squeue", scancel = "scancel";
  double poll_s = 0.5;
};

class SlurmLauncher : public Launcher {
 public:
  explicit SlurmLauncher(SlurmConfig cfg);
  ~SlurmLauncher() override;
  std::string start(const LaunchRequest& req, LaunchCallbacks cb) override;
  void stop(const std::string& launcher_id, bool force) override;
  bool alive(const std::string& launcher_id) override;
  std::string name() const override { return "slurm"; }
  bool reattachable() const override { return true; }
  void attach(const std::string& launcher_id, const LaunchRequest& req, std::int64_t offset,
              LaunchCallbacks cb) override;
  void detach_all() override;

  // The batch script for a request (exposed for tests).
  std::string render(const LaunchRequest& req) const;
  // The Slurm state of a job ("" when Slurm no longer knows it).
  std::string state_of(const std::string& launcher_id);

 private:
  void monitor(std::string id, LaunchRequest req, std::int64_t offset, LaunchCallbacks cb);
  SlurmConfig cfg_;
  std::string template_;
  std::mutex mu_;
  std::vector<std::thread> monitors_;
  std::atomic<bool> detaching_{false};
};

}  // namespace erg::server

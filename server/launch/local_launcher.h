// SPDX-License-Identifier: Apache-2.0
// Runs workers on this machine: `erg-worker` for one rank, `mpirun -n P
// erg-worker` for several (as root and oversubscribed where this machine
// needs it, like `erg run --ranks`). Each worker gets its own process group
// (so stop() reaches every rank) and dies with ergd (PR_SET_PDEATHSIG:
// SIGTERM, which makes it checkpoint and exit; the next ergd resumes it).
#pragma once

#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "launch/launcher.h"

namespace erg::server {

class LocalLauncher : public Launcher {
 public:
  LocalLauncher(std::string worker_path, std::string mpirun);
  ~LocalLauncher() override;
  std::string start(const LaunchRequest& req, LaunchCallbacks cb) override;
  void stop(const std::string& launcher_id, bool force) override;
  bool alive(const std::string& launcher_id) override;
  std::string name() const override { return "local"; }

 private:
  std::string worker_, mpirun_;
  std::mutex mu_;
  std::vector<std::thread> readers_;
};

}  // namespace erg::server

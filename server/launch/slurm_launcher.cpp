// SPDX-License-Identifier: Apache-2.0
#include "launch/slurm_launcher.h"

#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "io/atomic_file.h"
#include "util/subprocess.h"

namespace erg::server {

namespace fs = std::filesystem;

namespace {

// Slurm states after which the job will not run again (squeue %T).
bool final_state(const std::string& s) {
  return s.empty() || s == "COMPLETED" || s == "FAILED" || s == "CANCELLED" || s == "TIMEOUT" ||
         s == "NODE_FAIL" || s == "OUT_OF_MEMORY" || s == "BOOT_FAIL" || s == "DEADLINE" ||
         s == "PREEMPTED" || s == "SPECIAL_EXIT" || s == "REVOKED";
}

std::string progress_path(const LaunchRequest& req) {
  return fs::path(req.job_file).parent_path().string() + "/progress-" +
         std::to_string(req.attempt) + ".jsonl";
}

std::string exit_path(const LaunchRequest& req) {
  return fs::path(req.job_file).parent_path().string() + "/exit-" + std::to_string(req.attempt);
}

std::string read_all(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

}  // namespace

SlurmLauncher::SlurmLauncher(SlurmConfig cfg) : cfg_(std::move(cfg)) {
  template_ = read_all(cfg_.template_path);
  if (template_.empty())
    throw std::runtime_error("cannot read the Slurm script template " + cfg_.template_path +
                             " (--slurm-template)");
}

SlurmLauncher::~SlurmLauncher() {
  detach_all();
}

void SlurmLauncher::detach_all() {
  detaching_ = true;
  std::vector<std::thread> ts;
  {
    std::lock_guard lock(mu_);
    ts.swap(monitors_);
  }
  for (auto& t : ts)
    if (t.joinable()) t.join();
}

std::string SlurmLauncher::render(const LaunchRequest& req) const {
  const int threads = req.threads > 0 ? req.threads : 1;
  const std::map<std::string, std::string> values = {
      {"JOB_ID", req.job_id},
      {"PARTITION", req.partition.empty() ? cfg_.partition : req.partition},
      {"ACCOUNT", req.account.empty() ? cfg_.account : req.account},
      {"NODES", req.nodes > 0 ? std::to_string(req.nodes) : ""},
      {"RANKS", std::to_string(std::max(1, req.ranks))},
      {"THREADS", std::to_string(threads)},
      {"GPUS_PER_NODE",
       std::to_string(req.gpus_per_node > 0 ? req.gpus_per_node : cfg_.gpus_per_node)},
      {"TIME_LIMIT_MINUTES", std::to_string(req.time_limit_minutes > 0 ? req.time_limit_minutes
                                                                       : cfg_.time_limit_minutes)},
      {"SIGNAL_S", std::to_string(cfg_.signal_s)},
      {"JOB_DIR", fs::path(req.job_file).parent_path().string()},
      {"PROGRESS", progress_path(req)},
      {"EXIT_FILE", exit_path(req)},
      {"WORKER", cfg_.worker},
      {"MPIRUN", cfg_.mpirun},
  };
  std::istringstream in(template_);
  std::ostringstream out;
  std::string line;
  while (std::getline(in, line)) {
    bool drop = false;
    size_t p = 0;
    while ((p = line.find("{{", p)) != std::string::npos) {
      const size_t q = line.find("}}", p);
      if (q == std::string::npos) break;
      const std::string key = line.substr(p + 2, q - p - 2);
      auto it = values.find(key);
      if (it == values.end())
        throw std::runtime_error(cfg_.template_path + ": unknown placeholder {{" + key + "}}");
      std::string v = it->second;
      if (v.empty() || (key == "GPUS_PER_NODE" && v == "0")) drop = true;
      line.replace(p, q + 2 - p, v);
      p += v.size();
    }
    if (!drop) out << line << "\n";
  }
  return out.str();
}

std::string SlurmLauncher::start(const LaunchRequest& req, LaunchCallbacks cb) {
  const std::string dir = fs::path(req.job_file).parent_path().string();
  const std::string script = dir + "/job.sbatch";
  const std::string text = render(req);  // throws before anything is written
  io::write_file_atomic(script, text);
  std::error_code ec;
  fs::remove(progress_path(req), ec);
  fs::remove(exit_path(req), ec);
  const CommandResult r = run_command({cfg_.sbatch, "--parsable", script}, 60);
  if (r.exit_code != 0)
    throw std::runtime_error("sbatch failed (exit " + std::to_string(r.exit_code) +
                             "): " + r.err.substr(0, 500));
  std::string id = r.out.substr(0, r.out.find_first_of(";\n"));
  if (id.empty() || id.find_first_not_of("0123456789_") != std::string::npos)
    throw std::runtime_error("sbatch printed no job id: " + r.out.substr(0, 200));
  std::lock_guard lock(mu_);
  monitors_.emplace_back(&SlurmLauncher::monitor, this, id, req, 0, std::move(cb));
  return id;
}

void SlurmLauncher::attach(const std::string& launcher_id, const LaunchRequest& req,
                           std::int64_t offset, LaunchCallbacks cb) {
  std::lock_guard lock(mu_);
  monitors_.emplace_back(&SlurmLauncher::monitor, this, launcher_id, req, offset, std::move(cb));
}

std::string SlurmLauncher::state_of(const std::string& id) {
  const CommandResult r = run_command({cfg_.squeue, "-h", "-t", "all", "-j", id, "-o", "%T"}, 30);
  std::string s = r.out.substr(0, r.out.find('\n'));
  if (r.exit_code != 0) {
    // "Invalid job id specified": Slurm has forgotten the job (MinJobAge).
    if (r.err.find("Invalid job id") != std::string::npos) return "";
    return "UNKNOWN";  // squeue could not answer: try again later
  }
  return s;
}

void SlurmLauncher::monitor(std::string id, LaunchRequest req, std::int64_t offset,
                            LaunchCallbacks cb) {
  const std::string progress = progress_path(req);
  std::string last_state;
  auto last_query = std::chrono::steady_clock::time_point{};
  auto drain = [&] {
    std::ifstream f(progress, std::ios::binary);
    if (!f) return;
    f.seekg(offset);
    std::string line;
    while (std::getline(f, line)) {
      if (f.eof()) break;  // a line still being written: read it next time
      offset += static_cast<std::int64_t>(line.size()) + 1;
      deliver_line(cb, line, offset);
    }
  };
  while (!detaching_) {
    drain();
    const auto now = std::chrono::steady_clock::now();
    if (now - last_query >= std::chrono::seconds(1)) {
      last_query = now;
      const std::string state = state_of(id);
      if (state != "UNKNOWN") {
        if (state != last_state && !state.empty()) {
          last_state = state;
          if (cb.on_state) cb.on_state(state);
        }
        if (final_state(state)) {
          drain();
          const std::string code_text = read_all(exit_path(req));
          int code = 1;
          if (!code_text.empty()) {
            code = std::atoi(code_text.c_str());
          } else if (state == "CANCELLED") {
            code = 143;  // scancel before the worker could say anything
          } else if (state == "TIMEOUT" || state == "PREEMPTED") {
            code = 143;
          }
          cb.on_exit(code);
          return;
        }
      }
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(static_cast<int>(cfg_.poll_s * 1e3)));
  }
}

void SlurmLauncher::stop(const std::string& launcher_id, bool force) {
  // Graceful: SIGTERM to the batch script, which passes it to the worker
  // (checkpoint, exit). Forced: Slurm's own cancel (SIGKILL after KillWait).
  // A job still pending has no script to signal: cancel it outright.
  if (force || state_of(launcher_id) == "PENDING" ||
      run_command({cfg_.scancel, "--signal=TERM", "--batch", launcher_id}, 60).exit_code != 0)
    run_command({cfg_.scancel, launcher_id}, 60);
}

bool SlurmLauncher::alive(const std::string& launcher_id) {
  const std::string s = state_of(launcher_id);
  return s == "UNKNOWN" || !final_state(s);
}

}  // namespace erg::server

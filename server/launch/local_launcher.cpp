// SPDX-License-Identifier: Apache-2.0
#include "launch/local_launcher.h"

#include <fcntl.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace erg::server {

LocalLauncher::LocalLauncher(std::string worker_path, std::string mpirun)
    : worker_(std::move(worker_path)), mpirun_(std::move(mpirun)) {}

LocalLauncher::~LocalLauncher() {
  for (auto& t : readers_)
    if (t.joinable()) t.detach();  // ergd is exiting; the workers outlive no one
}

std::string LocalLauncher::start(const LaunchRequest& req, LaunchCallbacks cb) {
  const unsigned cores = std::max(1u, std::thread::hardware_concurrency());
  std::vector<std::string> args;
  const int ranks = std::max(1, req.ranks);
  if (ranks > 1) {
    args = {mpirun_, "-n", std::to_string(ranks), "--bind-to", "none"};
    if (static_cast<unsigned>(ranks) > cores) args.push_back("--oversubscribe");
  }
  args.push_back(worker_);
  if (req.resume) {
    args.insert(args.end(), {"--resume", req.out_dir});
  } else {
    args.insert(args.end(), {req.job_file, "--out", req.out_dir});
  }
  const int threads =
      req.threads > 0 ? req.threads : static_cast<int>(std::max(1u, cores / unsigned(ranks)));
  args.insert(args.end(), {"--threads", std::to_string(threads), "--progress-fd", "1",
                           "--steer-dir", req.steer_dir, "--quiet"});

  int fds[2];
  if (::pipe2(fds, O_CLOEXEC) != 0)
    throw std::runtime_error(std::string("pipe: ") + strerror(errno));
  const int log = ::open(req.log_path.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
  if (log < 0) {
    ::close(fds[0]);
    ::close(fds[1]);
    throw std::runtime_error("cannot open " + req.log_path + ": " + strerror(errno));
  }
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  const pid_t parent = ::getpid();
  const pid_t pid = ::fork();
  if (pid < 0) {
    ::close(fds[0]);
    ::close(fds[1]);
    ::close(log);
    throw std::runtime_error(std::string("fork: ") + strerror(errno));
  }
  if (pid == 0) {
    // Child: only async-signal-safe calls until exec.
    ::setpgid(0, 0);
    ::prctl(PR_SET_PDEATHSIG, SIGTERM);
    if (::getppid() != parent) ::_exit(143);  // ergd died before prctl
    ::dup2(fds[1], STDOUT_FILENO);
    ::dup2(log, STDERR_FILENO);
    const int devnull = ::open("/dev/null", O_RDONLY);
    if (devnull >= 0) ::dup2(devnull, STDIN_FILENO);
    sigset_t none;
    sigemptyset(&none);
    ::sigprocmask(SIG_SETMASK, &none, nullptr);
    ::signal(SIGPIPE, SIG_DFL);
    if (::geteuid() == 0) {
      ::setenv("OMPI_ALLOW_RUN_AS_ROOT", "1", 1);
      ::setenv("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1", 1);
    }
    ::execvp(argv[0], argv.data());
    const char* msg = "ergd: cannot start the worker\n";
    (void)!::write(STDERR_FILENO, msg, strlen(msg));
    ::_exit(127);
  }
  ::setpgid(pid, pid);  // also from the parent: no race with stop()
  ::close(fds[1]);
  ::close(log);
  const int rd = fds[0];
  std::lock_guard lock(mu_);
  readers_.emplace_back([rd, pid, cb = std::move(cb)] {
    std::string pending;
    char buf[8192];
    for (;;) {
      const ssize_t n = ::read(rd, buf, sizeof buf);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) break;
      pending.append(buf, static_cast<size_t>(n));
      size_t nl;
      while ((nl = pending.find('\n')) != std::string::npos) {
        const std::string line = pending.substr(0, nl);
        pending.erase(0, nl + 1);
        deliver_line(cb, line, 0);
      }
    }
    ::close(rd);
    int status = 0;
    while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
    }
    const int code = WIFEXITED(status)     ? WEXITSTATUS(status)
                     : WIFSIGNALED(status) ? 128 + WTERMSIG(status)
                                           : 1;
    cb.on_exit(code);
  });
  return std::to_string(pid);
}

void LocalLauncher::stop(const std::string& launcher_id, bool force) {
  const pid_t pid = static_cast<pid_t>(std::stol(launcher_id));
  if (pid <= 1) return;
  // The group: mpirun and its ranks, or the single worker.
  if (::kill(-pid, force ? SIGKILL : SIGTERM) != 0) ::kill(pid, force ? SIGKILL : SIGTERM);
}

bool LocalLauncher::alive(const std::string& launcher_id) {
  pid_t pid = 0;
  try {
    pid = static_cast<pid_t>(std::stol(launcher_id));
  } catch (...) {
    return false;
  }
  if (pid <= 1 || ::kill(pid, 0) != 0) return false;
  {
    // A zombie (exited, not yet reaped by whoever inherited it) is gone.
    std::ifstream st("/proc/" + std::to_string(pid) + "/stat");
    std::string stat_line;
    std::getline(st, stat_line);
    const auto close_paren = stat_line.rfind(')');
    if (close_paren != std::string::npos && close_paren + 2 < stat_line.size() &&
        stat_line[close_paren + 2] == 'Z')
      return false;
  }
  // A recycled pid is someone else's process: look at what it runs.
  std::ifstream f("/proc/" + std::to_string(pid) + "/cmdline");
  std::stringstream ss;
  ss << f.rdbuf();
  const std::string cmd = ss.str();
  return cmd.find("erg-worker") != std::string::npos || cmd.find("mpirun") != std::string::npos;
}

}  // namespace erg::server

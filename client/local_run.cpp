// SPDX-License-Identifier: Apache-2.0
// Local runs: `erg run` starts erg-worker on this machine (under mpirun, or
// $ERG_MPIRUN, with --ranks) and draws a progress bar from the events
// (erg.v1.WorkerEvent, one JSON line each) rank 0 writes to its stdout;
// `erg check` validates a job.
#include <fcntl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iostream>
#include <map>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "commands.h"
#include "io/install_paths.h"
#include "job/map_file.h"
#include "job/run_flags.h"
#include "job/spec.h"
#include "job/worker_event.h"
#include "progress_bar.h"
#include "remote/common.h"
#include "sim/calibration.h"
#include "sim/resolution.h"

namespace erg::client {

std::string worker_path() {
  if (const char* env = std::getenv("ERG_WORKER")) return env;
  return io::sibling_program("erg-worker");
}

namespace {

pid_t g_child = -1;
extern "C" void forward_signal(int sig) {
  if (g_child > 0) ::kill(g_child, sig);
}

// The cell size of the run in out_dir (its job.json), 0 if unreadable.
double cell_size_of_run(const std::string& out_dir) {
  try {
    std::ifstream f(out_dir + "/job.json", std::ios::binary);
    std::stringstream text;
    text << f.rdbuf();
    return erg::job::parse_json(text.str()).domain().cell_size_m();
  } catch (const std::exception&) {
    return 0;
  }
}

// What `erg run` shows of one worker event (proto/erg/v1/worker.proto).
void show_event(const erg::v1::WorkerEvent& ev, ProgressBar& bar, const std::string& out_dir) {
  using Kind = erg::v1::WorkerEvent::KindCase;
  switch (ev.kind_case()) {
    case Kind::kProgress: {
      const auto& p = ev.progress();
      bar.update(ev.step(), p.steps(), p.steps_per_s(), p.eta_s(), p.time_years());
      break;
    }
    case Kind::kSnapshot:
      bar.snapshot();
      break;
    case Kind::kStart: {
      const auto& s = ev.start();
      std::cerr << "erg: " << s.nx() << " x " << s.ny() << " cells on the " << s.backend()
                << " backend, " << s.ranks() << " rank(s) as " << s.tiles_x() << "x" << s.tiles_y()
                << " tiles, steps " << ev.step() << " -> " << s.steps() << ", output in " << out_dir
                << "\n";
      break;
    }
    case Kind::kDone: {
      const auto& d = ev.done();
      bar.finish();
      if (d.halo_messages_per_step() > 0)
        std::cerr << "erg: halo exchange: " << d.halo_messages_per_step() << " messages, "
                  << d.halo_bytes_per_step() << " bytes per step (the most of any rank)\n";
      if (d.host_staged_bytes_per_step() > 0 || d.halo_path() == "cuda-aware-mpi")
        std::cerr << "erg: GPU halos: " << d.halo_path() << ", " << d.host_staged_bytes_per_step()
                  << " bytes per step between device and host (the most of any rank)\n";
      if (d.peak_rss_bytes_per_cell() > 0) {
        char line[160];
        std::snprintf(line, sizeof line,
                      "erg: memory: %.0f bytes per cell (peak resident, all ranks: %.2f GiB)\n",
                      d.peak_rss_bytes_per_cell(),
                      static_cast<double>(d.peak_rss_bytes()) / 1073741824.0);
        std::cerr << line;
      }
      // Avalanching iterates until settled; the cap is a safety net, never
      // silent.
      if (d.avalanche_capped_steps() > 0)
        std::cerr << "erg: " << d.avalanche_capped_steps()
                  << " step(s) reached model.avalanche_iterations with sand still moving (at most "
                  << d.avalanche_most_iterations() << " iterations moved sand in a step)\n";
      erg::v1::Progress totals;
      totals.set_sand_units_total(d.totals().sand_units_total());
      totals.set_airborne_units_total(d.totals().airborne_units_total());
      std::cerr << "erg: done at step " << ev.step() << "; sand "
                << sand_text(totals, cell_size_of_run(out_dir)) << "\n";
      break;
    }
    case Kind::kFailed:
    case Kind::kStopped:
      bar.finish();
      break;
    default:
      break;
  }
}

}  // namespace

int cmd_run(const std::vector<std::string>& args) {
  erg::job::RunFlags flags;
  try {
    flags = erg::job::parse_run_flags(args);
    if (flags.resume_dir.empty()) {
      const auto spec = erg::job::load_job_file(flags.job_path);  // fail fast, one place
      // Say what was read from each map file and how it was fitted to the grid.
      for (const auto& note : erg::job::describe_maps(spec, erg::job::base_dir_of(flags.job_path)))
        std::cerr << "erg: " << note << "\n";
    }
  } catch (const erg::job::SpecError& e) {
    std::cerr << "erg: invalid job:\n" << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "erg run: " << e.what() << "\n";
    return 2;
  }
  int fds[2];
  if (::pipe(fds) != 0) {
    std::perror("erg: pipe");
    return 1;
  }
  // The worker (rank 0, with --ranks) writes its progress events to stdout,
  // which mpirun forwards: erg reads them from a pipe.
  const std::string worker = worker_path();
  std::vector<std::string> wargs;
  if (flags.ranks > 0) {
    const char* mpirun = std::getenv("ERG_MPIRUN");
    wargs = {mpirun ? mpirun : "mpirun", "-n", std::to_string(flags.ranks), "--bind-to", "none"};
    const unsigned cores = std::max(1u, std::thread::hardware_concurrency());
    if (static_cast<unsigned>(flags.ranks) > cores) wargs.push_back("--oversubscribe");
  }
  wargs.push_back(worker);
  for (size_t i = 0; i < args.size(); ++i) {
    if (args[i] == "--ranks") {  // erg's own flag
      ++i;
      continue;
    }
    wargs.push_back(args[i]);
  }
  if (flags.ranks > 0 && flags.threads == 0) {
    // Share the cores between the ranks instead of oversubscribing them.
    const unsigned cores = std::max(1u, std::thread::hardware_concurrency());
    wargs.push_back("--threads");
    wargs.push_back(std::to_string(std::max(1u, cores / static_cast<unsigned>(flags.ranks))));
  }
  wargs.push_back("--progress-fd");
  wargs.push_back("1");
  const pid_t pid = ::fork();
  if (pid < 0) {
    std::perror("erg: fork");
    return 1;
  }
  if (pid == 0) {
    ::close(fds[0]);
    ::dup2(fds[1], STDOUT_FILENO);
    ::close(fds[1]);
    if (::geteuid() == 0) {
      // Open MPI refuses to run as root unless told it is intended.
      ::setenv("OMPI_ALLOW_RUN_AS_ROOT", "1", 1);
      ::setenv("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1", 1);
    }
    std::vector<char*> argv;
    for (auto& a : wargs) argv.push_back(a.data());
    argv.push_back(nullptr);
    ::execvp(argv[0], argv.data());
    std::fprintf(stderr, "erg: cannot start %s: %s\n", argv[0], std::strerror(errno));
    _exit(127);
  }
  g_child = pid;
  std::signal(SIGINT, forward_signal);
  std::signal(SIGTERM, forward_signal);
  ::close(fds[1]);
  ProgressBar bar;
  std::string pending;
  char buf[4096];
  std::string out_dir = flags.out_dir;
  for (;;) {
    const ssize_t n = ::read(fds[0], buf, sizeof buf);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    pending.append(buf, static_cast<size_t>(n));
    size_t nl;
    while ((nl = pending.find('\n')) != std::string::npos) {
      const std::string line = pending.substr(0, nl);
      pending.erase(0, nl + 1);
      if (line.empty() || line[0] != '{') continue;  // not an event (mpirun's notes)
      std::string error;
      const auto ev = erg::job::parse_worker_event(line, &error);
      if (!ev) {
        std::cerr << "erg: skipping a worker line that is not an erg.v1.WorkerEvent (" << error
                  << ")\n";
        continue;
      }
      show_event(*ev, bar, out_dir);
    }
  }
  ::close(fds[0]);
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  bar.finish();
  if (WIFEXITED(status)) {
    const int code = WEXITSTATUS(status);
    if (code == 0)
      std::cerr << "erg: snapshots in " << out_dir << "/snapshots, previews in " << out_dir
                << "/previews\n";
    return code;
  }
  if (WIFSIGNALED(status)) {
    std::cerr << "erg: worker killed by signal " << WTERMSIG(status) << "\n";
    return 128 + WTERMSIG(status);
  }
  return 1;
}

int cmd_check(const std::vector<std::string>& args) {
  if (args.size() != 1) {
    std::cerr << "usage: erg check JOB.json\n";
    return 2;
  }
  try {
    const auto spec = erg::job::load_job_file(args[0]);
    std::cout << erg::job::to_readable_json(spec) << "\n";
    // What each map file holds and what was done to fit it (pixel size,
    // units, resampling, border blending), on stderr to keep stdout JSON.
    for (const auto& note : erg::job::describe_maps(spec, erg::job::base_dir_of(args[0])))
      std::cerr << "erg: " << note << "\n";
    // Model or physical units, and in the physical modes the measured time
    // per step (sim/calibration.h).
    std::istringstream units(erg::describe_units(spec));
    for (std::string line; std::getline(units, line);) std::cerr << "erg: " << line << "\n";
    // Lengths the cells do not resolve: the job runs, but they depend on
    // the grid (sim/resolution.h).
    for (const auto& w : erg::resolution_warnings(spec)) std::cerr << "erg: warning: " << w << "\n";
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "erg: invalid job:\n" << e.what() << "\n";
    return 2;
  }
}

}  // namespace erg::client

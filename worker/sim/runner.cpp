#include "sim/runner.h"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>

namespace erg {

namespace fs = std::filesystem;

namespace {

std::atomic<int> g_signal{0};
extern "C" void on_signal(int sig) {
  g_signal.store(sig);
}

std::string json_escape(const std::string& s) {
  std::string o;
  for (char c : s) {
    if (c == '"' || c == '\\') o += '\\';
    if (c == '\n') {
      o += "\\n";
      continue;
    }
    o += c;
  }
  return o;
}

class Progress {
 public:
  explicit Progress(int fd) : fd_(fd) {}
  void emit(const std::string& json) {
    if (fd_ < 0) return;
    const std::string line = json + "\n";
    const char* p = line.data();
    size_t left = line.size();
    while (left > 0) {
      const ssize_t n = ::write(fd_, p, left);
      if (n <= 0) return;  // the reader went away; keep running
      p += n;
      left -= static_cast<size_t>(n);
    }
  }

 private:
  int fd_;
};

void write_atomic_text(const std::string& path, const std::string& text) {
  const std::string tmp = path + ".tmp-" + std::to_string(::getpid());
  {
    std::ofstream o(tmp, std::ios::binary);
    o << text;
    if (!o) throw io::IoError(path + ": cannot write");
  }
  fs::rename(tmp, path);
}

void write_outputs(Simulation& sim, const std::string& dir, bool previews, Progress& progress) {
  const std::string name = step_name(sim.step_index());
  Simulation::Output o = sim.output();
  io::SnapshotMeta meta = sim.snapshot_meta();
  io::SnapshotFields f;
  f.bedrock = o.bedrock.data();
  f.sand = o.sand.data();
  f.vegetation = o.vegetation.data();
  f.wind = o.wind.data();
  f.airborne = o.airborne.data();
  f.shadow = o.shadow.data();
  const std::string h5 = dir + "/snapshots/" + name + ".h5";
  io::write_snapshot(h5, meta, f);
  io::write_xdmf(dir + "/snapshots/" + name + ".xdmf", name + ".h5", meta, true, true);
  std::string png;
  if (previews) {
    png = dir + "/previews/" + name + ".png";
    io::write_preview_png(png, meta.nx, meta.ny, meta.cell_size_m, o.bedrock.data(), o.sand.data(),
                          o.vegetation.data());
  }
  progress.emit("{\"event\":\"snapshot\",\"step\":" + std::to_string(sim.step_index()) +
                ",\"path\":\"" + json_escape(h5) + "\",\"preview\":\"" + json_escape(png) + "\"}");
}

void write_checkpoint(Simulation& sim, const std::string& dir) {
  const std::string path = dir + "/checkpoints/" + step_name(sim.step_index()) + ".h5";
  io::write_checkpoint(path, sim.checkpoint());
  // Keep the newest two: a crash while writing one still leaves a good one.
  std::vector<std::string> all;
  for (const auto& e : fs::directory_iterator(dir + "/checkpoints"))
    if (e.path().extension() == ".h5" && e.path().filename().string().rfind("step_", 0) == 0)
      all.push_back(e.path().string());
  std::sort(all.begin(), all.end());
  for (size_t i = 0; i + 2 < all.size(); ++i) fs::remove(all[i]);
}

std::string fmt_duration(double s) {
  if (!(s >= 0) || s > 1e8) return "?";
  const long t = static_cast<long>(s + 0.5);
  char buf[32];
  std::snprintf(buf, sizeof buf, "%ld:%02ld:%02ld", t / 3600, (t / 60) % 60, t % 60);
  return buf;
}

}  // namespace

std::string step_name(std::int64_t step) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "step_%08lld", static_cast<long long>(step));
  return buf;
}

std::string latest_checkpoint(const std::string& out_dir) {
  const fs::path d = fs::path(out_dir) / "checkpoints";
  if (!fs::is_directory(d)) return "";
  std::vector<std::string> all;
  for (const auto& e : fs::directory_iterator(d))
    if (e.path().extension() == ".h5" && e.path().filename().string().rfind("step_", 0) == 0)
      all.push_back(e.path().string());
  std::sort(all.rbegin(), all.rend());
  for (const auto& p : all) {
    try {
      (void)io::read_checkpoint(p);
      return p;
    } catch (const std::exception& e) {
      std::cerr << "erg: skipping unreadable checkpoint " << p << ": " << e.what() << "\n";
    }
  }
  return "";
}

int run_job(const RunConfig& cfg) {
  Progress progress(cfg.progress_fd);
  std::unique_ptr<Simulation> sim;
  try {
    if (cfg.resume) {
      const std::string ck = latest_checkpoint(cfg.out_dir);
      if (ck.empty()) {
        std::cerr << "erg: " << cfg.out_dir << " holds no checkpoint to resume from\n";
        return 2;
      }
      io::Checkpoint c = io::read_checkpoint(ck);
      erg::v1::JobSpec spec = job::parse_json(c.job_spec_json, ck);
      job::apply_defaults(spec);
      job::apply_overrides(spec, cfg.overrides);
      c.job_spec_json = job::to_json(spec);
      sim = std::make_unique<Simulation>(c, cfg.options);
      if (!cfg.quiet) std::cerr << "erg: resuming " << cfg.out_dir << " at step " << c.step << "\n";
    } else {
      erg::v1::JobSpec spec = job::load_job_file(cfg.job_path);
      job::apply_overrides(spec, cfg.overrides);
      auto problems = job::validate(spec, job::base_dir_of(cfg.job_path));
      if (!problems.empty()) throw job::SpecError(problems);
      if (!latest_checkpoint(cfg.out_dir).empty()) {
        std::cerr << "erg: " << cfg.out_dir
                  << " already holds a run; continue it with --resume or choose another --out\n";
        return 2;
      }
      for (const char* sub : {"snapshots", "previews", "checkpoints"})
        fs::create_directories(fs::path(cfg.out_dir) / sub);
      write_atomic_text(cfg.out_dir + "/job.json", job::to_json(spec));
      sim = std::make_unique<Simulation>(spec, job::base_dir_of(cfg.job_path), cfg.options);
    }
  } catch (const job::SpecError& e) {
    std::cerr << "erg: invalid job:\n" << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "erg: " << e.what() << "\n";
    return 2;
  }

  const auto& run = sim->spec().run();
  const std::int64_t steps = run.steps();
  const bool previews = run.previews();
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  const auto totals_json = [&]() {
    const Totals t = sim->totals();
    return "\"sand_units_total\":\"" + to_decimal(t.sand) + "\",\"airborne_units_total\":\"" +
           to_decimal(t.airborne) + "\",\"bedrock_units_total\":\"" + to_decimal(t.bedrock) + "\"";
  };

  try {
    fs::create_directories(fs::path(cfg.out_dir) / "snapshots");
    fs::create_directories(fs::path(cfg.out_dir) / "previews");
    fs::create_directories(fs::path(cfg.out_dir) / "checkpoints");
    progress.emit("{\"event\":\"start\",\"step\":" + std::to_string(sim->step_index()) +
                  ",\"steps\":" + std::to_string(steps) + ",\"backend\":\"" +
                  sim->backend().name() + "\",\"nx\":" + std::to_string(sim->model().tile.gnx) +
                  ",\"ny\":" + std::to_string(sim->model().tile.gny) + "}");
    if (!cfg.resume) {
      write_outputs(*sim, cfg.out_dir, previews, progress);
      if (run.checkpoint_every() > 0) write_checkpoint(*sim, cfg.out_dir);
    }
    using Clock = std::chrono::steady_clock;
    const auto t0 = Clock::now();
    auto last_report = t0, last_log = t0;
    const std::int64_t first = sim->step_index();
    while (sim->step_index() < steps) {
      sim->step();
      const std::int64_t s = sim->step_index();
      const bool last = s == steps;
      if (last || (run.snapshot_every() > 0 && s % run.snapshot_every() == 0))
        write_outputs(*sim, cfg.out_dir, previews, progress);
      if (last || (run.checkpoint_every() > 0 && s % run.checkpoint_every() == 0))
        write_checkpoint(*sim, cfg.out_dir);
      const auto now = Clock::now();
      const double elapsed = std::chrono::duration<double>(now - t0).count();
      const double rate = static_cast<double>(s - first) / std::max(elapsed, 1e-9);
      const double eta = static_cast<double>(steps - s) / std::max(rate, 1e-9);
      if (last || std::chrono::duration<double>(now - last_report).count() >= 0.25) {
        last_report = now;
        std::ostringstream o;
        o << "{\"event\":\"progress\",\"step\":" << s << ",\"steps\":" << steps
          << ",\"steps_per_s\":" << rate << ",\"eta_s\":" << eta
          << ",\"time_days\":" << sim->time_days() << "," << totals_json() << "}";
        progress.emit(o.str());
      }
      if (!cfg.quiet && cfg.progress_fd < 0 &&
          (last || std::chrono::duration<double>(now - last_log).count() >= 5.0)) {
        last_log = now;
        std::cerr << "erg: step " << s << "/" << steps << "  " << rate << " steps/s  ETA "
                  << fmt_duration(eta) << "\n";
      }
      if (g_signal.load() != 0 && !last) {
        write_checkpoint(*sim, cfg.out_dir);
        const int sig = g_signal.load();
        std::cerr << "erg: stopped by signal " << sig << " at step " << s
                  << "; checkpoint written, resume with --resume\n";
        progress.emit("{\"event\":\"stopped\",\"step\":" + std::to_string(s) + "}");
        return 128 + sig;
      }
    }
    // Per-stage timing, for the curious and for erg-bench comparisons.
    const StageTimes& t = sim->times();
    std::ostringstream o;
    o << "{\"event\":\"done\",\"step\":" << sim->step_index() << "," << totals_json()
      << ",\"stage_ms\":{";
    for (int k = 0; k < kStageCount; ++k)
      o << (k ? "," : "") << "\"" << kStageNames[k] << "\":" << t.ms[static_cast<size_t>(k)];
    o << "}}";
    progress.emit(o.str());
  } catch (const std::exception& e) {
    std::cerr << "erg: run failed at step " << sim->step_index() << ": " << e.what() << "\n";
    progress.emit("{\"event\":\"failed\",\"step\":" + std::to_string(sim->step_index()) +
                  ",\"reason\":\"" + json_escape(e.what()) + "\"}");
    return 1;
  }
  return 0;
}

}  // namespace erg

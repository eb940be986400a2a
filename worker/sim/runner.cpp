// SPDX-License-Identifier: Apache-2.0
#include "sim/runner.h"

#include <google/protobuf/util/json_util.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <set>
#include <sstream>
#include <stdexcept>

#include "dist/decomposition.h"
#include "io/atomic_file.h"
#include "job/worker_event.h"
#include "sim/moving_rate.h"
#include "sim/overview.h"
#include "sim/resolution.h"
#include "sim/resume_point.h"
#include "sim/tiling.h"
#include "wind/regime.h"

namespace erg {

namespace fs = std::filesystem;

namespace {

std::atomic<int> g_signal{0};
extern "C" void on_signal(int sig) {
  g_signal.store(sig);
}

// A line on stderr in one write. Under mpirun, rank 0's stdout (the
// progress events) and stderr are forwarded apart and merged by whoever
// reads them, so a line written in pieces (std::cerr writes each << at
// once) can be cut by an event line, which then no longer parses.
template <class... Parts>
void log_line(const Parts&... parts) {
  std::ostringstream o;
  (o << ... << parts);
  std::cerr << o.str();
}

// The worker's events (proto/erg/v1/worker.proto), one line each on the
// progress descriptor; rank 0 only (the others hold fd -1).
class Progress {
 public:
  explicit Progress(int fd) : fd_(fd) {}
  void emit(const erg::v1::WorkerEvent& event) {
    if (fd_ < 0) return;
    const std::string line = job::worker_event_line(event);
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

// This rank's place in the run.
struct Context {
  MPI_Comm comm = MPI_COMM_WORLD;  // all ranks
  MPI_Comm cart = MPI_COMM_NULL;   // the periodic Cartesian grid of tiles
  int rank = 0, size = 1;
  dist::Decomposition d;
  io::TileSlab slab;
  // Snapshot chunks: one per tile.
  int chunk_x = 0, chunk_y = 0;
  bool root() const { return rank == 0; }
  bool tiled() const { return size > 1; }
};

// What a preview says besides the terrain: step, simulated time, the wind
// of this step and, for a regime of several directions, its rose (a wind
// rose's probabilities; a bidirectional wind's primary : secondary flux).
io::PreviewLabels preview_labels(const Simulation& sim, const io::SnapshotMeta& meta) {
  io::PreviewLabels l;
  l.step = meta.step;
  l.time_days = meta.time_days;
  const Vec2 w = wind::at_step(sim.spec(), meta.step);
  l.wind_x = w.x;
  l.wind_y = w.y;
  const erg::v1::WindRegime& r = wind::regime_in_effect(sim.spec(), meta.step);
  if (r.has_rose()) {
    for (const auto& e : r.rose().entries())
      if (e.speed_mps() > 0) l.rose.push_back({e.direction_deg(), e.probability()});
  } else if (r.has_bidirectional()) {
    const auto& b = r.bidirectional();
    l.rose.push_back({b.direction_deg(), b.flux_ratio()});
    l.rose.push_back({b.direction_deg() + b.angle_deg(), 1.0});
  }
  return l;
}

void write_outputs(Simulation& sim, const std::string& dir, bool previews, Progress& progress,
                   const Context& ctx) {
  const std::string name = step_name(sim.step_index());
  io::SnapshotMeta meta = sim.snapshot_meta();  // collective: exact totals
  // Every layer of the registry, a band of rows at a time from the backend
  // (one rank or several: the same parallel writer), never a whole field.
  constexpr auto order = fields::snapshot_order();
  const std::vector<fields::Id> layers(order.begin(), order.end());
  const std::string h5 = dir + "/snapshots/" + name + ".h5";
  // The overview pyramid, reduced tile by tile (sim/overview.h), from the
  // tile's terrain read a band of rows at a time.
  const TerrainRows terrain = [&](int layer, int y0, int y1, float* out) {
    constexpr fields::Id ids[3] = {fields::kBedrock, fields::kSand, fields::kVegetation};
    sim.layer_rows(ids[layer], y0, y1, out);
  };
  GroundRange ground;
  const io::OverviewPyramid pyramid = overview_pyramid(ctx.cart, ctx.d, terrain, &ground);
  meta.ground_min_m = ground.min_m;
  meta.ground_max_m = ground.max_m;
  io::write_snapshot_parallel(
      ctx.cart, h5, meta, layers,
      [&](fields::Id id, int y0, int y1, void* out) {
        sim.layer_rows(id, y0, y1, static_cast<float*>(out));
      },
      ctx.slab, ctx.chunk_x, ctx.chunk_y, &pyramid);
  // The preview is drawn from the finest overview level that fits it, which
  // alone meets on rank 0: at most kPreviewMaxPx^2 blocks whatever the domain.
  const int level = io::overview_level_for(meta.nx, meta.ny, io::kPreviewMaxPx);
  io::OverviewLevel view;
  if (previews) view = gather_overview_level(ctx.cart, ctx.d, pyramid, level, terrain);
  if (!ctx.root()) return;
  io::write_xdmf(dir + "/snapshots/" + name + ".xdmf", name + ".h5", meta, layers);
  if (const int l = io::overview_xdmf_level(meta.nx, meta.ny); l > 0)
    io::write_overview_xdmf(dir + "/snapshots/" + name + ".overview.xdmf", name + ".h5", meta, l);
  io::write_run_xdmf(dir);
  std::string png;
  if (previews) {
    png = dir + "/previews/" + name + ".png";
    const io::PreviewLabels labels = preview_labels(sim, meta);
    io::write_preview_png(png, view.nx, view.ny, std::ldexp(meta.cell_size_m, level),
                          view.bedrock.data(), view.sand.data(), view.vegetation.data(),
                          io::kPreviewMaxPx, &labels);
  }
  erg::v1::WorkerEvent e;
  e.set_step(sim.step_index());
  e.mutable_snapshot()->set_path(job::valid_utf8(h5));
  e.mutable_snapshot()->set_preview(job::valid_utf8(png));
  progress.emit(e);
}

void write_checkpoint(Simulation& sim, const std::string& dir, const Context& ctx) {
  const std::string path = dir + "/checkpoints/" + step_name(sim.step_index()) + ".h5";
  // Band by band from the backend, on one rank or several.
  io::write_checkpoint_parallel(
      ctx.cart, path, sim.checkpoint_header(),
      [&](fields::Id id, int y0, int y1, void* out) { sim.state_rows(id, y0, y1, out); }, ctx.slab,
      ctx.chunk_x, ctx.chunk_y);
  if (!ctx.root()) return;
  // Keep the newest two: a crash while writing one still leaves a good one.
  std::vector<std::string> all;
  for (const auto& e : fs::directory_iterator(dir + "/checkpoints"))
    if (e.path().extension() == ".h5" && e.path().filename().string().rfind("step_", 0) == 0)
      all.push_back(e.path().string());
  std::sort(all.begin(), all.end());
  for (size_t i = 0; i + 2 < all.size(); ++i) fs::remove(all[i]);
}

// ---- steering (runner.h) ---------------------------------------------------

constexpr std::uintmax_t kMaxSteerFileBytes = 1 << 20;

struct SteerFile {
  std::string name;  // NAME.json, in the steering directory
  erg::v1::Event event;
};

// NAME.json -> NAME.applied / NAME.rejected, replacing an older one.
void mark_steer_file(const std::string& dir, const std::string& name, const char* ext) {
  std::error_code ec;
  const fs::path from = fs::path(dir) / name;
  fs::rename(from, fs::path(from).replace_extension(ext), ec);
  if (ec) std::cerr << "erg: cannot rename steering file " << from << ": " << ec.message() << "\n";
}

// The problems an event adds to a valid spec, naming its fields as
// "event.FIELD" (the file holds one event).
std::vector<std::string> steer_problems(erg::v1::JobSpec check, const erg::v1::Event& e) {
  const std::vector<std::string> before = job::validate(check);
  *check.add_events() = e;
  const std::string prefix = "events[" + std::to_string(check.events_size() - 1) + "]";
  std::vector<std::string> out;
  for (std::string p : job::validate(check)) {
    if (std::find(before.begin(), before.end(), p) != before.end()) continue;
    for (size_t k = p.find(prefix); k != std::string::npos; k = p.find(prefix, k))
      p.replace(k, prefix.size(), "event");
    out.push_back(p);
  }
  return out;
}

// Rank 0: the good events waiting in `dir`, in name order, to apply at the
// start of `step` after the events of `spec`. Bad ones are renamed
// NAME.rejected and reported here; the good ones are renamed by the caller
// once they are recorded.
// The NAME.json files in `dir` not in `seen`, in name order.
std::vector<std::string> new_steer_files(const std::string& dir, std::set<std::string>& seen) {
  std::vector<std::string> names;
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.size() > 5 && name[0] != '.' && name.compare(name.size() - 5, 5, ".json") == 0 &&
        seen.insert(name).second)
      names.push_back(name);
  }
  std::sort(names.begin(), names.end());
  return names;
}

std::vector<SteerFile> collect_steering(const std::string& dir, const erg::v1::JobSpec& spec,
                                        std::int64_t step, Progress& progress, bool log) {
  std::set<std::string> seen;
  std::vector<std::string> names = new_steer_files(dir, seen);
  std::vector<SteerFile> good;
  if (names.empty()) return good;
  // Validation without the layers: an event cannot change them, they were
  // checked when the run began, and their map files need not be read again.
  erg::v1::JobSpec check = spec;
  check.clear_layers();
  job::apply_defaults(check);
  std::error_code ec;
  // A writer publishing several files at once (ergd's SteerJob) renames
  // them one after the other: once the files found are taken the directory
  // is read again, so that a batch is taken at one step (a few reads at most).
  for (int round = 0; round < 4 && !names.empty(); ++round, names = new_steer_files(dir, seen))
    for (const auto& name : names) {
      const fs::path path = fs::path(dir) / name;
      std::string reason;
      SteerFile f{name, {}};
      const fs::file_status st = fs::status(path, ec);
      if (ec || !fs::exists(st)) continue;  // taken away meanwhile
      if (!fs::is_regular_file(st)) {
        reason = "not a regular file";
      } else if (fs::file_size(path, ec) > kMaxSteerFileBytes) {
        reason = "larger than 1 MiB";
      } else {
        std::ifstream in(path, std::ios::binary);
        if (!in) continue;  // taken away meanwhile
        std::stringstream text;
        text << in.rdbuf();
        google::protobuf::util::JsonParseOptions opt;
        opt.ignore_unknown_fields = false;
        opt.case_insensitive_enum_parsing = true;
        const auto parsed = google::protobuf::util::JsonStringToMessage(text.str(), &f.event, opt);
        if (!parsed.ok()) {
          reason = "not a valid erg.v1.Event: " + std::string(parsed.message());
        } else {
          f.event.set_step(step);
          erg::v1::JobSpec filled;  // the event's defaults
          *filled.add_events() = f.event;
          job::apply_defaults(filled);
          f.event = filled.events(0);
          const auto problems = steer_problems(check, f.event);
          for (const auto& p : problems) reason += (reason.empty() ? "" : "; ") + p;
        }
      }
      if (reason.empty()) {
        *check.add_events() = f.event;
        good.push_back(std::move(f));
        continue;
      }
      mark_steer_file(dir, name, ".rejected");
      if (log) log_line("erg: steering ", name, " rejected at step ", step, ": ", reason, "\n");
      erg::v1::WorkerEvent ev;
      ev.set_step(step);
      ev.mutable_steer_rejected()->set_file(job::valid_utf8(name));
      ev.mutable_steer_rejected()->set_reason(job::valid_utf8(reason));
      progress.emit(ev);
    }
  return good;
}

void bcast(std::string& s, const Context& ctx) {
  long long n = static_cast<long long>(s.size());
  MPI_Bcast(&n, 1, MPI_LONG_LONG, 0, ctx.comm);
  s.resize(static_cast<size_t>(n));
  if (n > 0) MPI_Bcast(s.data(), static_cast<int>(n), MPI_CHAR, 0, ctx.comm);
}
int bcast(int v, const Context& ctx) {
  MPI_Bcast(&v, 1, MPI_INT, 0, ctx.comm);
  return v;
}

std::string fmt_duration(double s) {
  if (!(s >= 0) || s > 1e8) return "?";
  const long t = static_cast<long>(s + 0.5);
  char buf[32];
  std::snprintf(buf, sizeof buf, "%ld:%02ld:%02ld", t / 3600, (t / 60) % 60, t % 60);
  return buf;
}

// ---- the run: setup, loop, reporting -------------------------------------

// What a run starts from, decided by the coordinator and broadcast.
struct StartPoint {
  std::string spec_json;       // the defaults-filled spec, with this run's overrides
  std::string base_dir = ".";  // for the map files the spec names
  std::string checkpoint;      // resume: the checkpoint to read
};

// Rank 0, --resume: the newest checkpoint that proves its integrity and
// agrees with job.json (sim/resume_point.h); each one passed over is named.
// Returns 0, or the exit code of a run that cannot resume.
int resume_point(const RunConfig& cfg, StartPoint& start) {
  ResumePoint point = choose_resume_point(cfg.out_dir);
  for (const std::string& why : point.skipped) std::cerr << "erg: checkpoint " << why << "\n";
  if (point.path.empty()) {
    std::cerr << "erg: " << cfg.out_dir
              << (point.skipped.empty() ? " holds no checkpoint to resume from\n"
                                        : " holds no intact checkpoint to resume from\n");
    return 2;
  }
  start.checkpoint = point.path;
  if (!point.skipped.empty())
    std::cerr << "erg: resuming from " << fs::path(point.path).filename().string() << " (step "
              << point.step << "), the newest intact checkpoint\n";
  erg::v1::JobSpec spec = std::move(point.spec);
  job::apply_overrides(spec, cfg.overrides);
  start.spec_json = job::to_json(spec);
  return 0;
}

// Rank 0, a new run: the job file, validated, into a directory that holds
// no run yet. Returns 0, or the exit code of a run that cannot start.
int new_start_point(const RunConfig& cfg, StartPoint& start) {
  erg::v1::JobSpec spec = job::load_job_file(cfg.job_path);
  job::apply_overrides(spec, cfg.overrides);
  start.base_dir = job::base_dir_of(cfg.job_path);
  auto problems = job::validate(spec, start.base_dir);
  if (!problems.empty()) throw job::SpecError(problems);
  // Any checkpoint file, intact or not, belongs to a run.
  std::error_code ec;
  if (!fs::is_empty(fs::path(cfg.out_dir) / "checkpoints", ec) && !ec) {
    std::cerr << "erg: " << cfg.out_dir
              << " already holds a run; continue it with --resume or choose another --out\n";
    return 2;
  }
  start.spec_json = job::to_json(spec);
  return 0;
}

// Rank 0: where the run starts, with every error of the input reported.
int choose_start_point(const RunConfig& cfg, StartPoint& start) {
  try {
    return cfg.resume ? resume_point(cfg, start) : new_start_point(cfg, start);
  } catch (const job::SpecError& e) {
    std::cerr << "erg: invalid job:\n" << e.what() << "\n";
  } catch (const std::exception& e) {
    std::cerr << "erg: " << e.what() << "\n";
  }
  return 2;
}

// What the coordinator decided after a step, for every rank (a signal
// reaches the ranks at different steps, steering files only rank 0).
struct StepOutcome {
  bool report = false;  // send a progress event
  bool stop = false;    // a signal came: checkpoint and stop
  bool steer = false;   // steering events wait: add them before the next step
};

// One broadcast per step, as before the outcomes had names.
StepOutcome bcast(const StepOutcome& o, const Context& ctx) {
  int v[3] = {o.report, o.stop, o.steer};
  MPI_Bcast(v, 3, MPI_INT, 0, ctx.comm);
  return {v[0] != 0, v[1] != 0, v[2] != 0};
}

using Clock = std::chrono::steady_clock;

double seconds(Clock::duration d) {
  return std::chrono::duration<double>(d).count();
}

// A whole run on this rank (run_job): setup, the loop, the report.
class JobRun {
 public:
  JobRun(const RunConfig& cfg, MPI_Comm world) : cfg_(cfg) {
    ctx_.comm = world;
    MPI_Comm_rank(world, &ctx_.rank);
    MPI_Comm_size(world, &ctx_.size);
    progress_ = Progress(ctx_.root() ? cfg.progress_fd : -1);
  }

  int run() {
    if (const int code = setup(); code != 0) return code;
    try {
      begin();
      if (const int code = loop(); code != 0) return code;
      report_done();
    } catch (const std::exception& e) {
      return fail(e);
    }
    return 0;
  }

 private:
  // ---- setup ----

  // The job, validated once by the coordinator, then on every rank the tile
  // grid, its tile and its simulation. 0, or the exit code.
  int setup() {
    StartPoint start;
    int status = ctx_.root() ? choose_start_point(cfg_, start) : 0;
    status = bcast(status, ctx_);
    if (status != 0) return status;
    bcast(start.spec_json, ctx_);
    bcast(start.base_dir, ctx_);
    bcast(start.checkpoint, ctx_);
    spec_json_ = start.spec_json;
    try {
      build_simulation(start);
    } catch (const std::exception& e) {
      // Every rank decides the same for a bad grid or spec; anything else is
      // this rank's alone, so the job is aborted.
      if (ctx_.root()) std::cerr << "erg: " << e.what() << "\n";
      if (dynamic_cast<const std::invalid_argument*>(&e)) return 2;
      std::cerr << "erg-worker rank " << ctx_.rank << ": " << e.what() << "\n";
      MPI_Abort(ctx_.comm, 1);
    }
    steps_ = sim_->spec().run().steps();
    steering_ = !cfg_.steer_dir.empty();                  // the same on every rank
    log_steering_ = !cfg_.quiet && cfg_.progress_fd < 0;  // else the events say it
    return 0;
  }

  void build_simulation(const StartPoint& start) {
    erg::v1::JobSpec spec = job::parse_json(start.spec_json, "job");
    job::apply_defaults(spec);
    tiling_ = make_tiling(spec, ctx_.comm, cfg_.tiles_x, cfg_.tiles_y);
    ctx_.cart = tiling_->cart;
    ctx_.d = tiling_->d;
    ctx_.slab = tiling_->slab;
    ctx_.chunk_x = ctx_.d.chunk_x;
    ctx_.chunk_y = ctx_.d.chunk_y;
    if (cfg_.resume) {
      // The simulation is made from the header, then its state read into
      // the backend band by band (no copy of the tile's state).
      io::read_checkpoint_parallel(
          ctx_.cart, start.checkpoint, ctx_.slab, [&](const io::Checkpoint& header) {
            io::Checkpoint c = header;
            c.job_spec_json = start.spec_json;  // with this run's overrides
            sim_ = std::make_unique<Simulation>(c, cfg_.options, tiling_->place,
                                                Simulation::Deferred{});
            return io::TileRowsIn([this](fields::Id id, int y0, int y1, const void* in) {
              sim_->load_rows(id, y0, y1, in);
            });
          });
      sim_->loaded();
    } else {
      sim_ = std::make_unique<Simulation>(spec, start.base_dir, cfg_.options, tiling_->place);
    }
  }

  // The directories, job.json, the start event; a new run's first outputs;
  // steering waiting before the first step.
  void begin() {
    if (ctx_.root()) {
      for (const char* sub : {"snapshots", "previews", "checkpoints"})
        fs::create_directories(fs::path(cfg_.out_dir) / sub);
      if (steering_) fs::create_directories(cfg_.steer_dir);
      if (!cfg_.resume) io::write_file_atomic(cfg_.out_dir + "/job.json", spec_json_);
      if (cfg_.resume && !cfg_.quiet)
        std::cerr << "erg: resuming " << cfg_.out_dir << " at step " << sim_->step_index() << "\n";
      if (!cfg_.quiet) log_halo_path();
      // Said even when quiet, as the avalanching cap is (sim/resolution.h).
      for (const auto& w : resolution_warnings(sim_->spec())) log_line("erg: warning: ", w, "\n");
      report_start();
    }
    MPI_Barrier(ctx_.comm);  // the directories exist before any collective write
    if (!cfg_.resume) {
      timed_snapshot();
      if (sim_->spec().run().checkpoint_every() > 0) timed_checkpoint();
    }
    // One broadcast, only when steering.
    if (steering_ && sim_->step_index() < steps_) {
      const int pending = ctx_.root() && take_steering(sim_->step_index()) ? 1 : 0;
      if (bcast(pending, ctx_)) apply_steering();
    }
  }

  // ---- the loop ----

  // Steps to the end; 0, or 128 + the signal that stopped the run.
  int loop() {
    const auto t0 = Clock::now();
    last_report_ = last_log_ = t0;
    first_ = sim_->step_index();
    stats0_ = sim_->exchange().stats();
    double files_s = 0;  // of the loop's time, writing snapshots and checkpoints
    while (sim_->step_index() < steps_) {
      const auto begin = Clock::now();
      sim_->step();
      const std::int64_t s = sim_->step_index();
      warn_if_capped(s);
      const bool last = s == steps_;
      const auto before_files = Clock::now();
      write_due_files(s);
      const auto now = Clock::now();
      files_s += seconds(now - before_files);
      const StepOutcome decided = ctx_.root() ? decide(s, last, now) : StepOutcome{};
      const auto before_bcast = Clock::now();
      const StepOutcome next = bcast(decided, ctx_);
      const auto after_bcast = Clock::now();
      moving_rate_.add(seconds(now - t0) - files_s, s);
      const double rate = moving_rate_.steps_per_s();
      const double eta = eta_s(s);
      if (next.report) report_progress(s, rate, eta, now);
      log_progress(s, last, rate, eta, now);
      busy_s_ += seconds(before_files - begin) + seconds(before_bcast - now) +
                 seconds(Clock::now() - after_bcast);
      if (next.steer) apply_steering();
      if (next.stop) return stop(s);
    }
    return 0;
  }

  // The first step whose avalanching reached its cap with sand still
  // moving is said on stderr (every tile knows it alike; rank 0 says it); the
  // done event counts them all.
  void warn_if_capped(std::int64_t s) {
    // The step that just ran (index s - 1) is the first capped one.
    if (!ctx_.root() || sim_->times().first_capped_step != s - 1) return;
    log_line("erg: step ", s, ": sand avalanching reached model.avalanche_iterations = ",
             sim_->model().avalanche_iterations,
             " with sand still moving; slip faces may stand above the repose angle\n");
  }

  // Snapshots and checkpoints at the job's cadence, and both at the end
  // (sim/moving_rate.h, which the ETA counts by).
  void write_due_files(std::int64_t s) {
    const auto& run = sim_->spec().run();
    if (erg::sim::file_due(s, steps_, run.snapshot_every())) timed_snapshot();
    if (erg::sim::file_due(s, steps_, run.checkpoint_every())) timed_checkpoint();
  }

  void timed_snapshot() {
    const auto t = Clock::now();
    write_outputs(*sim_, cfg_.out_dir, sim_->spec().run().previews(), progress_, ctx_);
    output_costs_.snapshot_took(seconds(Clock::now() - t));
  }

  void timed_checkpoint() {
    const auto t = Clock::now();
    write_checkpoint(*sim_, cfg_.out_dir, ctx_);
    output_costs_.checkpoint_took(seconds(Clock::now() - t));
  }

  // Seconds to the end after step s: the steps left at the window's rate
  // and the files still due at their latest cost (sim/moving_rate.h); -1
  // while the rate is unknown.
  double eta_s(std::int64_t s) const {
    const double stepping = moving_rate_.eta_s(steps_);
    if (stepping < 0) return -1;
    const auto& run = sim_->spec().run();
    return stepping + output_costs_.due_s(s, steps_, run.snapshot_every(), run.checkpoint_every());
  }

  // Rank 0 after step s: report at most every 0.25 s and at the end; stop
  // on a signal; steering follows a step that does not stop (events at step
  // s, which the next step() applies).
  StepOutcome decide(std::int64_t s, bool last, Clock::time_point now) {
    StepOutcome o;
    o.report = last || seconds(now - last_report_) >= 0.25;
    o.stop = g_signal.load() != 0 && !last;
    o.steer = steering_ && !last && !o.stop && take_steering(s);
    return o;
  }

  // Rank 0: the good steering files waiting before step s (the bad ones are
  // rejected now). Whether there are any.
  bool take_steering(std::int64_t s) {
    steered_ = collect_steering(cfg_.steer_dir, sim_->spec(), s, progress_, log_steering_);
    return !steered_.empty();
  }

  // Every rank: the events rank 0 took, appended before the next step; then
  // rank 0 records them in job.json before it marks their files applied.
  void apply_steering() {
    std::string bytes;
    erg::v1::JobSpec carrier;
    if (ctx_.root()) {
      for (const auto& f : steered_) *carrier.add_events() = f.event;
      if (ctx_.tiled()) carrier.SerializeToString(&bytes);
    }
    if (ctx_.tiled()) {
      bcast(bytes, ctx_);
      if (!ctx_.root() && !carrier.ParseFromString(bytes))
        throw std::runtime_error("steering events: bad broadcast");
    }
    sim_->add_events(std::vector<erg::v1::Event>(carrier.events().begin(), carrier.events().end()));
    if (!ctx_.root()) return;
    // Recorded before the files say so: an applied file is in job.json.
    io::write_file_atomic(cfg_.out_dir + "/job.json", job::to_json(sim_->spec()));
    for (const auto& f : steered_) {
      mark_steer_file(cfg_.steer_dir, f.name, ".applied");
      if (log_steering_)
        log_line("erg: steering ", f.name, " applied at step ", sim_->step_index(), "\n");
      erg::v1::WorkerEvent e;
      e.set_step(sim_->step_index());
      e.mutable_steered()->set_file(job::valid_utf8(f.name));
      *e.mutable_steered()->mutable_event() = f.event;
      progress_.emit(e);
    }
    steered_.clear();
  }

  // After a signal: a last checkpoint, the stopped event; 128 + the signal.
  int stop(std::int64_t s) {
    write_checkpoint(*sim_, cfg_.out_dir, ctx_);
    const int sig = bcast(g_signal.load(), ctx_);
    if (ctx_.root()) {
      log_line("erg: stopped by signal ", sig, " at step ", s,
               "; checkpoint written, resume with --resume\n");
      erg::v1::WorkerEvent e;
      e.set_step(s);
      e.mutable_stopped()->set_signal(sig);
      progress_.emit(e);
    }
    return 128 + sig;
  }

  // ---- reporting ----

  // Exact totals (collective).
  erg::v1::WorkerEvent::Totals totals() {
    const Totals t = sim_->totals();
    erg::v1::WorkerEvent::Totals out;
    out.set_sand_units_total(to_decimal(t.sand));
    out.set_airborne_units_total(to_decimal(t.airborne));
    out.set_bedrock_units_total(to_decimal(t.bedrock));
    return out;
  }

  void report_start() {
    erg::v1::WorkerEvent e;
    e.set_step(sim_->step_index());
    auto& start = *e.mutable_start();
    start.set_steps(steps_);
    start.set_backend(sim_->backend().name());
    start.set_nx(sim_->model().tile.gnx);
    start.set_ny(sim_->model().tile.gny);
    start.set_ranks(ctx_.size);
    start.set_tiles_x(ctx_.d.px);
    start.set_tiles_y(ctx_.d.py);
    progress_.emit(e);
  }

  // Collective (the totals).
  void report_progress(std::int64_t s, double rate, double eta, Clock::time_point now) {
    last_report_ = now;
    erg::v1::WorkerEvent e;
    e.set_step(s);
    auto& p = *e.mutable_progress();
    p.set_steps(steps_);
    p.set_steps_per_s(rate);
    p.set_eta_s(eta);
    p.set_time_days(sim_->time_days());
    p.set_time_years(sim_->time_s() / (365.25 * 86400.0));
    *p.mutable_totals() = totals();
    progress_.emit(e);
  }

  // The periodic line on stderr of a run without a progress descriptor.
  void log_progress(std::int64_t s, bool last, double rate, double eta, Clock::time_point now) {
    if (!ctx_.root() || cfg_.quiet || cfg_.progress_fd >= 0) return;
    if (!last && seconds(now - last_log_) < 5.0) return;
    last_log_ = now;
    std::cerr << "erg: step " << s << "/" << steps_ << "  " << rate << " steps/s  ETA "
              << fmt_duration(eta) << "\n";
  }

  // Where a GPU run's ghosts go, and why (the MPI library's answer).
  void log_halo_path() {
    const dist::HaloPath p = sim_->backend().halo_path();
    if (p != dist::HaloPath::kHostStaged && p != dist::HaloPath::kDeviceDirect) return;
    const dist::MpiCudaSupport m = sim_->exchange().cuda_support();
    log_line("erg: halo path: ", dist::halo_path_name(p), " (MPI CUDA-aware: built ",
             m.built ? "yes" : "no", ", at run time ", m.runtime ? "yes" : "no",
             m.allowed ? "" : ", switched off by ERG_CUDA_AWARE_MPI=0", ")\n");
  }

  // Halo traffic per step since the loop began: the most any rank sent
  // (messages, bytes) or staged between device and host, and the fewest
  // messages of a rank. Collective.
  std::array<long long, 4> halo_traffic_per_step() {
    const dist::Exchange::Stats st = sim_->exchange().stats();
    const std::int64_t ran = std::max<std::int64_t>(1, sim_->step_index() - first_);
    long long mine[3] = {(st.messages - stats0_.messages) / ran, (st.bytes - stats0_.bytes) / ran,
                         (st.host_staged_bytes - stats0_.host_staged_bytes) / ran};
    std::array<long long, 4> out = {0, 0, 0, 0};
    MPI_Reduce(mine, out.data(), 3, MPI_LONG_LONG, MPI_MAX, 0, ctx_.comm);
    MPI_Reduce(mine, &out[3], 1, MPI_LONG_LONG, MPI_MIN, 0, ctx_.comm);
    return out;
  }

  // The peak resident set of every rank since it started (state, work
  // buffers, halos, output bands, MPI and HDF5): {sum, largest}. The
  // kernel's high-water mark, VmHWM of /proc/self/status (getrusage's
  // ru_maxrss where /proc is missing). Collective.
  static long long peak_rss_bytes() {
    std::ifstream status("/proc/self/status");
    for (std::string line; std::getline(status, line);)
      if (line.rfind("VmHWM:", 0) == 0) return std::stoll(line.substr(6)) * 1024;  // kB
    struct rusage usage {};
    ::getrusage(RUSAGE_SELF, &usage);
    return static_cast<long long>(usage.ru_maxrss) * 1024;  // kB on Linux
  }
  std::array<long long, 2> peak_memory() {
    const long long rss = peak_rss_bytes();
    std::array<long long, 2> out = {0, 0};
    MPI_Reduce(&rss, &out[0], 1, MPI_LONG_LONG, MPI_SUM, 0, ctx_.comm);
    MPI_Reduce(&rss, &out[1], 1, MPI_LONG_LONG, MPI_MAX, 0, ctx_.comm);
    return out;
  }

  // Busy milliseconds per step of the loop (busy_s_): {rank 0's, the
  // median rank's}. Collective; O(ranks) on rank 0, once per run.
  std::array<double, 2> busy_ms_per_step() {
    const double ran = static_cast<double>(std::max<std::int64_t>(1, sim_->step_index() - first_));
    const double mine = 1000.0 * busy_s_ / ran;
    std::vector<double> all(ctx_.root() ? static_cast<std::size_t>(ctx_.size) : 0);
    MPI_Gather(&mine, 1, MPI_DOUBLE, all.data(), 1, MPI_DOUBLE, 0, ctx_.comm);
    if (!ctx_.root()) return {0, 0};
    std::vector<double> sorted = all;
    std::sort(sorted.begin(), sorted.end());
    return {all[0], sorted[sorted.size() / 2]};
  }

  // The done event: totals, halo traffic, memory, time per stage. Collective.
  void report_done() {
    const std::array<long long, 4> halo = halo_traffic_per_step();
    const std::array<double, 2> busy = busy_ms_per_step();
    const std::array<long long, 2> rss = peak_memory();
    const double cells = static_cast<double>(ctx_.d.gnx) * static_cast<double>(ctx_.d.gny);
    const erg::v1::WorkerEvent::Totals end_totals = totals();
    if (!ctx_.root()) return;
    const StageTimes& t = sim_->times();
    erg::v1::WorkerEvent e;
    e.set_step(sim_->step_index());
    auto& done = *e.mutable_done();
    *done.mutable_totals() = end_totals;
    done.set_halo_messages_per_step(halo[0]);
    done.set_halo_bytes_per_step(halo[1]);
    done.set_halo_path(dist::halo_path_name(sim_->backend().halo_path()));
    done.set_host_staged_bytes_per_step(halo[2]);
    done.set_halo_messages_min_rank_per_step(halo[3]);
    done.set_step_ms_rank0(busy[0]);
    done.set_step_ms_median_rank(busy[1]);
    done.set_peak_rss_bytes(rss[0]);
    done.set_peak_rss_bytes_max_rank(rss[1]);
    done.set_peak_rss_bytes_per_cell(static_cast<double>(rss[0]) / cells);
    for (int k = 0; k < kStageCount; ++k)
      (*done.mutable_stage_ms())[kStageNames[k]] = t.ms[static_cast<size_t>(k)];
    done.set_avalanche_most_iterations(t.avalanche_most);
    done.set_avalanche_capped_steps(t.avalanche_capped_steps);
    progress_.emit(e);
  }

  // This rank failed after setup: the failed event; every rank aborted.
  int fail(const std::exception& e) {
    std::cerr << "erg-worker rank " << ctx_.rank << ": run failed at step " << sim_->step_index()
              << ": " << e.what() << "\n";
    erg::v1::WorkerEvent ev;
    ev.set_step(sim_->step_index());
    ev.mutable_failed()->set_reason(job::valid_utf8(e.what()));
    ev.mutable_failed()->set_rank(ctx_.rank);
    progress_.emit(ev);
    if (ctx_.tiled()) MPI_Abort(ctx_.comm, 1);  // never leave the other ranks waiting
    return 1;
  }

  const RunConfig& cfg_;
  Context ctx_;
  Progress progress_{-1};
  std::string spec_json_;  // as validated (job.json of a new run)
  std::unique_ptr<Tiling> tiling_;
  std::unique_ptr<Simulation> sim_;
  std::int64_t steps_ = 0;
  bool steering_ = false, log_steering_ = false;
  std::vector<SteerFile> steered_;  // rank 0: taken, not yet applied
  Clock::time_point last_report_, last_log_;
  std::int64_t first_ = 0;              // the loop's first step
  erg::sim::MovingRate moving_rate_;    // steps/s and ETA of the progress events
  erg::sim::OutputCosts output_costs_;  // and the files' part of the ETA
  dist::Exchange::Stats stats0_{};
  double busy_s_ = 0;  // this rank's busy time in the loop (busy_ms_per_step)
};

}  // namespace

std::string latest_checkpoint(const std::string& out_dir) {
  return choose_resume_point(out_dir).path;
}

int run_job(const RunConfig& cfg, MPI_Comm world) {
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  return JobRun(cfg, world).run();
}

}  // namespace erg

#include "sim/runner.h"

#include <google/protobuf/util/json_util.h>
#include <sys/resource.h>
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
#include <stdexcept>

#include "dist/decomposition.h"
#include "job/worker_event.h"
#include "sim/resume_point.h"
#include "sim/tiling.h"

namespace erg {

namespace fs = std::filesystem;

namespace {

std::atomic<int> g_signal{0};
extern "C" void on_signal(int sig) {
  g_signal.store(sig);
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

void write_atomic_text(const std::string& path, const std::string& text) {
  const std::string tmp = path + ".tmp-" + std::to_string(::getpid());
  {
    std::ofstream o(tmp, std::ios::binary);
    o << text;
    if (!o) throw io::IoError(path + ": cannot write");
  }
  fs::rename(tmp, path);
}

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

void write_outputs(Simulation& sim, const std::string& dir, bool previews, Progress& progress,
                   const Context& ctx) {
  const std::string name = step_name(sim.step_index());
  Simulation::Output o = sim.output();
  io::SnapshotMeta meta = sim.snapshot_meta();  // collective: exact totals
  io::SnapshotFields f;
  f.bedrock = o.bedrock.data();
  f.sand = o.sand.data();
  f.vegetation = o.vegetation.data();
  f.wind = o.wind.data();
  f.airborne = o.airborne.data();
  f.shadow = o.shadow.data();
  f.obstacles = o.obstacles.data();
  const std::string h5 = dir + "/snapshots/" + name + ".h5";
  if (ctx.tiled())
    io::write_snapshot_parallel(ctx.cart, h5, meta, f, ctx.slab, ctx.chunk_x, ctx.chunk_y);
  else
    io::write_snapshot(h5, meta, f);
  if (!ctx.root()) return;
  io::write_xdmf(dir + "/snapshots/" + name + ".xdmf", name + ".h5", meta, true, true, true);
  io::write_run_xdmf(dir);
  std::string png;
  if (previews) {
    png = dir + "/previews/" + name + ".png";
    if (ctx.tiled()) {
      // The coordinator has only its tile: the preview is made from the file
      // (12 bytes per cell of the whole domain, on rank 0, for a moment).
      const io::Snapshot whole = io::read_snapshot(h5, /*terrain_only=*/true);
      io::write_preview_png(png, meta.nx, meta.ny, meta.cell_size_m, whole.bedrock.data(),
                            whole.sand.data(), whole.vegetation.data());
    } else {
      io::write_preview_png(png, meta.nx, meta.ny, meta.cell_size_m, o.bedrock.data(),
                            o.sand.data(), o.vegetation.data());
    }
  }
  erg::v1::WorkerEvent e;
  e.set_step(sim.step_index());
  e.mutable_snapshot()->set_path(job::valid_utf8(h5));
  e.mutable_snapshot()->set_preview(job::valid_utf8(png));
  progress.emit(e);
}

void write_checkpoint(Simulation& sim, const std::string& dir, const Context& ctx) {
  const std::string path = dir + "/checkpoints/" + step_name(sim.step_index()) + ".h5";
  if (ctx.tiled())
    io::write_checkpoint_parallel(ctx.cart, path, sim.checkpoint(), ctx.slab, ctx.chunk_x,
                                  ctx.chunk_y);
  else
    io::write_checkpoint(path, sim.checkpoint());
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
std::vector<SteerFile> collect_steering(const std::string& dir, const erg::v1::JobSpec& spec,
                                        std::int64_t step, Progress& progress, bool log) {
  std::vector<std::string> names;
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.size() > 5 && name[0] != '.' && name.compare(name.size() - 5, 5, ".json") == 0)
      names.push_back(name);
  }
  std::vector<SteerFile> good;
  if (names.empty()) return good;
  std::sort(names.begin(), names.end());
  // Validation without the layers: an event cannot change them, they were
  // checked when the run began, and their map files need not be read again.
  erg::v1::JobSpec check = spec;
  check.clear_layers();
  job::apply_defaults(check);
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
    if (log)
      std::cerr << "erg: steering " << name << " rejected at step " << step << ": " << reason
                << "\n";
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

}  // namespace

std::string step_name(std::int64_t step) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "step_%08lld", static_cast<long long>(step));
  return buf;
}

std::string latest_checkpoint(const std::string& out_dir) {
  return choose_resume_point(out_dir).path;
}

int run_job(const RunConfig& cfg, MPI_Comm world) {
  Context ctx;
  ctx.comm = world;
  MPI_Comm_rank(world, &ctx.rank);
  MPI_Comm_size(world, &ctx.size);
  Progress progress(ctx.root() ? cfg.progress_fd : -1);
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);

  // ---- the coordinator validates the job once and prepares the directory --
  int status = 0;
  std::string spec_json, base_dir = ".", checkpoint;
  if (ctx.root()) {
    try {
      if (cfg.resume) {
        // The newest checkpoint that proves its integrity and agrees with
        // job.json (sim/resume_point.h); each one passed over is named.
        ResumePoint point = choose_resume_point(cfg.out_dir);
        for (const std::string& why : point.skipped) std::cerr << "erg: checkpoint " << why << "\n";
        if (point.path.empty()) {
          std::cerr << "erg: " << cfg.out_dir
                    << (point.skipped.empty() ? " holds no checkpoint to resume from\n"
                                              : " holds no intact checkpoint to resume from\n");
          status = 2;
        } else {
          checkpoint = point.path;
          if (!point.skipped.empty())
            std::cerr << "erg: resuming from " << fs::path(point.path).filename().string()
                      << " (step " << point.step << "), the newest intact checkpoint\n";
          erg::v1::JobSpec spec = std::move(point.spec);
          job::apply_overrides(spec, cfg.overrides);
          spec_json = job::to_json(spec);
        }
      } else {
        erg::v1::JobSpec spec = job::load_job_file(cfg.job_path);
        job::apply_overrides(spec, cfg.overrides);
        base_dir = job::base_dir_of(cfg.job_path);
        auto problems = job::validate(spec, base_dir);
        if (!problems.empty()) throw job::SpecError(problems);
        // Any checkpoint file, intact or not, belongs to a run.
        std::error_code ec;
        if (!fs::is_empty(fs::path(cfg.out_dir) / "checkpoints", ec) && !ec) {
          std::cerr << "erg: " << cfg.out_dir
                    << " already holds a run; continue it with --resume or choose another --out\n";
          status = 2;
        } else {
          spec_json = job::to_json(spec);
        }
      }
    } catch (const job::SpecError& e) {
      std::cerr << "erg: invalid job:\n" << e.what() << "\n";
      status = 2;
    } catch (const std::exception& e) {
      std::cerr << "erg: " << e.what() << "\n";
      status = 2;
    }
  }
  status = bcast(status, ctx);
  if (status != 0) return status;
  bcast(spec_json, ctx);
  bcast(base_dir, ctx);
  bcast(checkpoint, ctx);

  // ---- every rank: the tile grid, its tile, its simulation -----------------
  std::unique_ptr<Simulation> sim;
  std::unique_ptr<Tiling> tiling;
  try {
    erg::v1::JobSpec spec = job::parse_json(spec_json, "job");
    job::apply_defaults(spec);
    tiling = make_tiling(spec, world, cfg.tiles_x, cfg.tiles_y);
    ctx.cart = tiling->cart;
    ctx.d = tiling->d;
    ctx.slab = tiling->slab;
    ctx.chunk_x = ctx.d.chunk_x;
    ctx.chunk_y = ctx.d.chunk_y;
    if (cfg.resume) {
      io::Checkpoint c = ctx.tiled() ? io::read_checkpoint_parallel(ctx.cart, checkpoint, ctx.slab)
                                     : io::read_checkpoint(checkpoint);
      c.job_spec_json = spec_json;  // with this run's overrides
      sim = std::make_unique<Simulation>(c, cfg.options, tiling->place);
    } else {
      sim = std::make_unique<Simulation>(spec, base_dir, cfg.options, tiling->place);
    }
  } catch (const std::exception& e) {
    // Every rank decides the same for a bad grid or spec; anything else is
    // this rank's alone, so the job is aborted.
    if (ctx.root()) std::cerr << "erg: " << e.what() << "\n";
    if (dynamic_cast<const std::invalid_argument*>(&e)) return 2;
    std::cerr << "erg-worker rank " << ctx.rank << ": " << e.what() << "\n";
    MPI_Abort(world, 1);
  }

  const auto& run = sim->spec().run();
  const std::int64_t steps = run.steps();
  const bool previews = run.previews();
  const auto totals = [&]() {
    const Totals t = sim->totals();  // collective
    erg::v1::WorkerEvent::Totals out;
    out.set_sand_units_total(to_decimal(t.sand));
    out.set_airborne_units_total(to_decimal(t.airborne));
    out.set_bedrock_units_total(to_decimal(t.bedrock));
    return out;
  };

  try {
    if (ctx.root()) {
      for (const char* sub : {"snapshots", "previews", "checkpoints"})
        fs::create_directories(fs::path(cfg.out_dir) / sub);
      if (!cfg.steer_dir.empty()) fs::create_directories(cfg.steer_dir);
      if (!cfg.resume) write_atomic_text(cfg.out_dir + "/job.json", spec_json);
      if (cfg.resume && !cfg.quiet)
        std::cerr << "erg: resuming " << cfg.out_dir << " at step " << sim->step_index() << "\n";
      erg::v1::WorkerEvent e;
      e.set_step(sim->step_index());
      auto& start = *e.mutable_start();
      start.set_steps(steps);
      start.set_backend(sim->backend().name());
      start.set_nx(sim->model().tile.gnx);
      start.set_ny(sim->model().tile.gny);
      start.set_ranks(ctx.size);
      start.set_tiles_x(ctx.d.px);
      start.set_tiles_y(ctx.d.py);
      progress.emit(e);
    }
    MPI_Barrier(world);  // the directories exist before any collective write
    if (!cfg.resume) {
      write_outputs(*sim, cfg.out_dir, previews, progress, ctx);
      if (run.checkpoint_every() > 0) write_checkpoint(*sim, cfg.out_dir, ctx);
    }
    // Steering: rank 0 finds the good events; every rank appends them
    // before the next step. Collective once rank 0's decision is known.
    const bool steering = !cfg.steer_dir.empty();                 // the same on every rank
    const bool log_steering = !cfg.quiet && cfg.progress_fd < 0;  // else the events say it
    std::vector<SteerFile> steered;
    const auto apply_steering = [&]() {
      std::vector<erg::v1::Event> events;
      std::string bytes;
      erg::v1::JobSpec carrier;
      if (ctx.root()) {
        for (const auto& f : steered) *carrier.add_events() = f.event;
        if (ctx.tiled()) carrier.SerializeToString(&bytes);
      }
      if (ctx.tiled()) {
        bcast(bytes, ctx);
        if (!ctx.root() && !carrier.ParseFromString(bytes))
          throw std::runtime_error("steering events: bad broadcast");
      }
      events.assign(carrier.events().begin(), carrier.events().end());
      sim->add_events(events);
      if (!ctx.root()) return;
      // Recorded before the files say so: an applied file is in job.json.
      write_atomic_text(cfg.out_dir + "/job.json", job::to_json(sim->spec()));
      for (const auto& f : steered) {
        mark_steer_file(cfg.steer_dir, f.name, ".applied");
        if (log_steering)
          std::cerr << "erg: steering " << f.name << " applied at step " << sim->step_index()
                    << "\n";
        erg::v1::WorkerEvent e;
        e.set_step(sim->step_index());
        e.mutable_steered()->set_file(job::valid_utf8(f.name));
        *e.mutable_steered()->mutable_event() = f.event;
        progress.emit(e);
      }
      steered.clear();
    };
    // Before the first step (one broadcast, only when steering).
    if (steering && sim->step_index() < steps) {
      int pending = 0;
      if (ctx.root()) {
        steered =
            collect_steering(cfg.steer_dir, sim->spec(), sim->step_index(), progress, log_steering);
        pending = steered.empty() ? 0 : 1;
      }
      if (bcast(pending, ctx)) apply_steering();
    }
    using Clock = std::chrono::steady_clock;
    const auto t0 = Clock::now();
    auto last_report = t0, last_log = t0;
    const std::int64_t first = sim->step_index();
    const dist::Exchange::Stats stats0 = sim->exchange().stats();
    while (sim->step_index() < steps) {
      sim->step();
      const std::int64_t s = sim->step_index();
      const bool last = s == steps;
      if (last || (run.snapshot_every() > 0 && s % run.snapshot_every() == 0))
        write_outputs(*sim, cfg.out_dir, previews, progress, ctx);
      if (last || (run.checkpoint_every() > 0 && s % run.checkpoint_every() == 0))
        write_checkpoint(*sim, cfg.out_dir, ctx);
      // The coordinator decides, for every rank, whether to report and
      // whether to stop (a signal reaches the ranks at different steps).
      const auto now = Clock::now();
      int control = 0;
      if (ctx.root()) {
        if (last || std::chrono::duration<double>(now - last_report).count() >= 0.25) control |= 1;
        if (g_signal.load() != 0 && !last) control |= 2;
        // Steering follows: events at step s, which the next step() applies.
        if (steering && !last && !(control & 2)) {
          steered = collect_steering(cfg.steer_dir, sim->spec(), s, progress, log_steering);
          if (!steered.empty()) control |= 4;
        }
      }
      control = bcast(control, ctx);
      const double elapsed = std::chrono::duration<double>(now - t0).count();
      const double rate = static_cast<double>(s - first) / std::max(elapsed, 1e-9);
      const double eta = static_cast<double>(steps - s) / std::max(rate, 1e-9);
      if (control & 1) {
        last_report = now;
        erg::v1::WorkerEvent e;
        e.set_step(s);
        auto& p = *e.mutable_progress();
        p.set_steps(steps);
        p.set_steps_per_s(rate);
        p.set_eta_s(eta);
        p.set_time_days(sim->time_days());
        p.set_time_years(sim->time_s() / (365.25 * 86400.0));
        *p.mutable_totals() = totals();
        progress.emit(e);
      }
      if (ctx.root() && !cfg.quiet && cfg.progress_fd < 0 &&
          (last || std::chrono::duration<double>(now - last_log).count() >= 5.0)) {
        last_log = now;
        std::cerr << "erg: step " << s << "/" << steps << "  " << rate << " steps/s  ETA "
                  << fmt_duration(eta) << "\n";
      }
      if (control & 4) apply_steering();
      if (control & 2) {
        write_checkpoint(*sim, cfg.out_dir, ctx);
        const int sig = bcast(g_signal.load(), ctx);
        if (ctx.root()) {
          std::cerr << "erg: stopped by signal " << sig << " at step " << s
                    << "; checkpoint written, resume with --resume\n";
          erg::v1::WorkerEvent e;
          e.set_step(s);
          e.mutable_stopped()->set_signal(sig);
          progress.emit(e);
        }
        return 128 + sig;
      }
    }
    // Halo traffic per step (the most any rank sent), and per-stage timing.
    const dist::Exchange::Stats st = sim->exchange().stats();
    const std::int64_t ran = std::max<std::int64_t>(1, sim->step_index() - first);
    long long mine[2] = {(st.messages - stats0.messages) / ran, (st.bytes - stats0.bytes) / ran};
    long long most[2] = {0, 0};
    MPI_Reduce(mine, most, 2, MPI_LONG_LONG, MPI_MAX, 0, world);
    // Memory: the peak resident set of every rank (state, work buffers,
    // halos, output copies, MPI and HDF5), summed and per cell of the domain.
    struct rusage usage {};
    ::getrusage(RUSAGE_SELF, &usage);
    const long long rss = static_cast<long long>(usage.ru_maxrss) * 1024;  // kB on Linux
    long long rss_sum = 0, rss_max = 0;
    MPI_Reduce(&rss, &rss_sum, 1, MPI_LONG_LONG, MPI_SUM, 0, world);
    MPI_Reduce(&rss, &rss_max, 1, MPI_LONG_LONG, MPI_MAX, 0, world);
    const double cells = static_cast<double>(ctx.d.gnx) * static_cast<double>(ctx.d.gny);
    const erg::v1::WorkerEvent::Totals end_totals = totals();
    if (ctx.root()) {
      const StageTimes& t = sim->times();
      erg::v1::WorkerEvent e;
      e.set_step(sim->step_index());
      auto& done = *e.mutable_done();
      *done.mutable_totals() = end_totals;
      done.set_halo_messages_per_step(most[0]);
      done.set_halo_bytes_per_step(most[1]);
      done.set_peak_rss_bytes(rss_sum);
      done.set_peak_rss_bytes_max_rank(rss_max);
      done.set_peak_rss_bytes_per_cell(static_cast<double>(rss_sum) / cells);
      for (int k = 0; k < kStageCount; ++k)
        (*done.mutable_stage_ms())[kStageNames[k]] = t.ms[static_cast<size_t>(k)];
      progress.emit(e);
    }
  } catch (const std::exception& e) {
    std::cerr << "erg-worker rank " << ctx.rank << ": run failed at step " << sim->step_index()
              << ": " << e.what() << "\n";
    erg::v1::WorkerEvent ev;
    ev.set_step(sim->step_index());
    ev.mutable_failed()->set_reason(job::valid_utf8(e.what()));
    ev.mutable_failed()->set_rank(ctx.rank);
    progress.emit(ev);
    if (ctx.tiled()) MPI_Abort(world, 1);  // never leave the other ranks waiting
    return 1;
  }
  return 0;
}

}  // namespace erg

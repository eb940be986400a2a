// erg-bench: the benchmark scenes of [N24] Table 1 (DESIGN.md section 7).
//
//   erg-bench --scene A|B --size 512|1024|2048|4096 [--steps N] [--warmup W]
//             [--threads T] [--backend auto|cpu|cuda] [--iterations I] [--json]
//
// Domain 1024 m x 1024 m, wind along +x, no bedrock relief, vegetation or
// abrasion; cell size 1024 m / size; avalanching 13/25/50/100 iterations.
// Scene A (barchans): sand uniform in [0.5, 2.0) m, wind 5 m/s.
// Scene B (transverse): sand uniform in [3, 5) m, wind 3 m/s.
// Prints ms per step, per-stage ms, cell updates per second and a roofline
// estimate: the bytes the pipeline must move per step divided by the memory
// bandwidth measured here with a STREAM-like triad.
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <iostream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "job/spec.h"
#include "sim/simulation.h"

namespace {

using Clock = std::chrono::steady_clock;

struct Args {
  std::string scene = "A";
  int size = 1024;
  int steps = 50;
  int warmup = 10;
  int threads = 0;
  int iterations = -1;
  std::string backend = "auto";
  bool json = false;
};

Args parse(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    const std::string f = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) throw std::invalid_argument(f + ": missing value");
      return argv[++i];
    };
    if (f == "--scene")
      a.scene = next();
    else if (f == "--size")
      a.size = std::stoi(next());
    else if (f == "--steps")
      a.steps = std::stoi(next());
    else if (f == "--warmup")
      a.warmup = std::stoi(next());
    else if (f == "--threads")
      a.threads = std::stoi(next());
    else if (f == "--iterations")
      a.iterations = std::stoi(next());
    else if (f == "--backend")
      a.backend = next();
    else if (f == "--json")
      a.json = true;
    else
      throw std::invalid_argument(f + ": unknown flag");
  }
  if (a.scene != "A" && a.scene != "B") throw std::invalid_argument("--scene must be A or B");
  if (a.size != 512 && a.size != 1024 && a.size != 2048 && a.size != 4096)
    throw std::invalid_argument("--size must be 512, 1024, 2048 or 4096");
  if (a.steps < 1) throw std::invalid_argument("--steps must be >= 1");
  return a;
}

erg::v1::JobSpec scene_spec(const Args& a) {
  const double l = 1024.0 / a.size;
  const int iterations =
      a.iterations >= 0 ? a.iterations : (a.size == 512 ? 13 : a.size / 1024 * 25);
  std::ostringstream j;
  j << R"({"name":"bench-)" << a.scene << "-" << a.size << R"(",)"
    << R"("domain":{"nx":)" << a.size << R"(,"ny":)" << a.size << R"(,"cell_size_m":)" << l << "},"
    << R"("layers":{"sand":{"uniform":{"min":)" << (a.scene == "A" ? 0.5 : 3.0) << R"(,"max":)"
    << (a.scene == "A" ? 2.0 : 5.0) << "}}},"
    << R"("wind":{"constant":{"speed_mps":)" << (a.scene == "A" ? 5 : 3)
    << R"(,"direction_deg":0}},)"
    // The hop must stay within 16 cells: at 0.25 m cells, 4 m.
    << R"("model":{"avalanche_iterations":)" << iterations << R"(,"max_hop_m":)"
    << std::min(8.0, 16 * l) << "},"
    << R"("run":{"steps":)" << a.steps + a.warmup << "}}";
  erg::v1::JobSpec spec = erg::job::parse_json(j.str(), "bench scene");
  erg::job::apply_defaults(spec);
  auto problems = erg::job::validate(spec);
  if (!problems.empty()) throw erg::job::SpecError(problems);
  return spec;
}

// STREAM-like triad a = b + s c over arrays far larger than the caches,
// with the benchmark's thread count: bytes per second.
double triad_bandwidth(int threads) {
  const size_t n = 64u << 20;  // 3 x 512 MiB of doubles
  std::vector<double> a(n), b(n, 1.0), c(n, 2.0);
#pragma omp parallel for num_threads(threads) schedule(static)
  for (size_t i = 0; i < n; ++i) a[i] = 0.0;
  double best = 0;
  for (int rep = 0; rep < 4; ++rep) {
    const auto t0 = Clock::now();
#pragma omp parallel for num_threads(threads) schedule(static)
    for (size_t i = 0; i < n; ++i) a[i] = b[i] + 3.0 * c[i];
    const double s = std::chrono::duration<double>(Clock::now() - t0).count();
    best = std::max(best, 3.0 * 8.0 * static_cast<double>(n) / s);
  }
  if (a[n / 2] != 7.0) std::cerr << "triad check failed\n";
  return best;
}

// Bytes the pipeline must move per cell per step if every field were read or
// written once per pass (the floor a streaming implementation cannot beat).
// Sizes: int64 state 8 B, float fields 4 B.
struct ByteModel {
  double per_cell_fixed = 0;      // everything but the avalanche iterations
  double per_cell_iteration = 0;  // one avalanching iteration
};
ByteModel byte_model() {
  ByteModel m;
  // wind: read b, s; write h; read h, write wind x/y             8+8+4 + 4+8
  // shadow: read h (once, cached march), wind, write shadow     4+8+4
  // saltation: lift r/w s, air, read shadow, veg                 16+16+4+4
  //            scatter: read air, wind, write landed            8+8+8
  //            impact: read landed, s, b, shadow, veg, res, wind; write s, b, air, s_r
  //                    8+8+8+4+4+4+8 + 8+8+8+4
  // reptation: read b, s, s_r; write s                          8+8+4+8
  // avalanche setup: read b, s; write h                         8+8+4
  m.per_cell_fixed = (8 + 8 + 4 + 4 + 8) + (4 + 8 + 4) + (16 + 16 + 4 + 4) + (8 + 8 + 8) +
                     (8 + 8 + 8 + 4 + 4 + 4 + 8 + 8 + 8 + 8 + 4) + (8 + 8 + 4 + 8) + (8 + 8 + 4);
  // one iteration: pass 1 read h, tan, s; write f, out             4+4+8+4+8
  //                pass 2 read h, tan, f, out, s, b; write s, h    4+4+4+8+8+8+8+4
  m.per_cell_iteration = (4 + 4 + 8 + 4 + 8) + (4 + 4 + 4 + 8 + 8 + 8 + 8 + 4);
  return m;
}

}  // namespace

int main(int argc, char** argv) {
  Args a;
  try {
    a = parse(argc, argv);
  } catch (const std::exception& e) {
    std::cerr
        << "erg-bench: " << e.what() << "\n"
        << "usage: erg-bench --scene A|B --size 512|1024|2048|4096 [--steps N] [--warmup W]\n"
        << "                 [--threads T] [--backend auto|cpu|cuda] [--iterations I] [--json]\n";
    return 2;
  }
  const erg::v1::JobSpec spec = scene_spec(a);
  erg::RunOptions opt;
  opt.threads = a.threads > 0 ? a.threads : omp_get_max_threads();
  opt.backend = a.backend == "cpu"    ? erg::BackendKind::kCpu
                : a.backend == "cuda" ? erg::BackendKind::kCuda
                                      : erg::BackendKind::kAuto;
  erg::Simulation sim(spec, ".", opt);
  // The first steps relax the random initial sand (every avalanching
  // iteration moves sand everywhere): reported apart from the steady steps.
  const auto tw = Clock::now();
  for (int i = 0; i < a.warmup; ++i) sim.step();
  sim.backend().synchronize();
  const double warmup_ms =
      a.warmup > 0 ? std::chrono::duration<double, std::milli>(Clock::now() - tw).count() / a.warmup
                   : 0.0;
  const erg::StageTimes before = sim.times();
  const auto t0 = Clock::now();
  for (int i = 0; i < a.steps; ++i) sim.step();
  sim.backend().synchronize();
  const double total_ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  const erg::StageTimes& after = sim.times();

  const double cells = static_cast<double>(a.size) * a.size;
  const double ms_per_step = total_ms / a.steps;
  const double iters_per_step =
      static_cast<double>(after.avalanche_iterations - before.avalanche_iterations) / a.steps;
  const int iterations = static_cast<int>(spec.model().avalanche_iterations());
  const bool cpu = sim.backend().name() == "cpu";
  const double bandwidth = cpu ? triad_bandwidth(opt.threads) : 0.0;
  const ByteModel bm = byte_model();
  // The iterations that ran: those that moved sand, plus the one that found
  // nothing to move (avalanching stops there; later ones would be identities).
  const double iterations_run = std::min<double>(iterations, iters_per_step + 1.0);
  const double bytes_per_step =
      cells * (bm.per_cell_fixed + bm.per_cell_iteration * iterations_run);
  const double roofline_ms = bandwidth > 0 ? 1e3 * bytes_per_step / bandwidth : 0.0;

  std::ostringstream o;
  o.precision(4);
  o << std::fixed;
  o << "{\"scene\":\"" << a.scene << "\",\"size\":" << a.size
    << ",\"cell_size_m\":" << 1024.0 / a.size << ",\"steps\":" << a.steps << ",\"backend\":\""
    << sim.backend().name() << "\",\"threads\":" << (cpu ? opt.threads : 0)
    << ",\"avalanche_iterations\":" << iterations
    << ",\"avalanche_iterations_moving_per_step\":" << iters_per_step
    << ",\"ms_per_step\":" << ms_per_step << ",\"warmup_steps\":" << a.warmup
    << ",\"warmup_ms_per_step\":" << warmup_ms << ",\"cell_updates_per_s\":" << std::scientific
    << cells * a.steps / (total_ms * 1e-3) << std::fixed << ",\"stage_ms\":{";
  for (int k = 0; k < erg::kStageCount; ++k)
    o << (k ? "," : "") << "\"" << erg::kStageNames[k]
      << "\":" << (after.ms[static_cast<size_t>(k)] - before.ms[static_cast<size_t>(k)]) / a.steps;
  o << "},\"bytes_per_step_model\":" << std::scientific << bytes_per_step << std::fixed
    << ",\"memory_bandwidth_gbs\":" << bandwidth / 1e9
    << ",\"roofline_ms_per_step\":" << roofline_ms
    << ",\"ratio_to_roofline\":" << (roofline_ms > 0 ? ms_per_step / roofline_ms : 0.0) << "}";
  if (a.json) {
    std::cout << o.str() << "\n";
  } else {
    std::cout << "scene " << a.scene << " " << a.size << "x" << a.size << " (" << 1024.0 / a.size
              << " m cells), " << sim.backend().name() << ", " << (cpu ? opt.threads : 0)
              << " threads\n"
              << "  " << ms_per_step << " ms/step, " << cells * a.steps / (total_ms * 1e-3) / 1e6
              << " Mcell-updates/s; avalanching moved sand in " << iters_per_step << " of "
              << iterations << " iterations per step\n"
              << "  first " << a.warmup << " steps (relaxing the random sand): " << warmup_ms
              << " ms/step\n";
    for (int k = 0; k < erg::kStageCount; ++k)
      std::cout << "  " << erg::kStageNames[k] << ": "
                << (after.ms[static_cast<size_t>(k)] - before.ms[static_cast<size_t>(k)]) / a.steps
                << " ms\n";
    if (cpu)
      std::cout << "  roofline: " << bytes_per_step / 1e6 << " MB/step at " << bandwidth / 1e9
                << " GB/s = " << roofline_ms << " ms/step; erg is " << ms_per_step / roofline_ms
                << "x from it\n";
  }
  return 0;
}

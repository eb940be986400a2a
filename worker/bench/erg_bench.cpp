// SPDX-License-Identifier: Apache-2.0
// erg-bench: the benchmark scenes of [N24] Table 1 (docs/design.md, "Benchmarks").
//
//   erg-bench --scene A|B --size 512|1024|2048|4096|8192 [--steps N] [--warmup W]
//             [--threads T] [--backend auto|cpu|cuda] [--iterations I] [--json]
//             [--ranks P [--tiles PXxPY]] [--scaling] [--no-bandwidth]
//   erg-bench --device-info [--json]
//
// --ranks P runs the scene on P MPI ranks (erg-bench starts mpirun itself),
// one tile each, and reports the halo messages and bytes per rank and step.
// --scaling runs it on 1 rank and on P ranks with the same threads per rank
// and reports the strong-scaling efficiency T1 / (P TP).
//
// Domain 1024 m x 1024 m, wind along +x, no bedrock relief, vegetation or
// abrasion; cell size 1024 m / size; avalanching until settled (the job's
// default cap, model.avalanche_iterations; --iterations I sets another cap).
// Scene A (barchans): sand uniform in [0.5, 2.0) m, wind 5 m/s.
// Scene B (transverse): sand uniform in [3, 5) m, wind 3 m/s.
// Prints ms per step, per-stage ms, cell updates per second and a roofline
// estimate: the bytes the pipeline must move per step divided by the memory
// bandwidth measured here: a STREAM-like triad on the CPU backend, a
// device-to-device copy on the CUDA backend (cuda_device_info, backend.h).
// --no-bandwidth skips that measurement (the triad's arrays take 1.5 GB;
// no roofline is reported then).
// --device-info prints the GPU (name, compute capability, memory, SMs,
// runtime and driver) and its measured copy bandwidth, and exits.
#include <mpi.h>
#include <omp.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "job/spec.h"
#include "sim/simulation.h"
#include "sim/tiling.h"

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
  int ranks = 0;      // 0: this process alone
  std::string tiles;  // --tiles PXxPY
  int tiles_x = 0, tiles_y = 0;
  bool scaling = false;
  bool device_info = false;
  bool no_bandwidth = false;  // skip the triad (and the roofline)
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
    else if (f == "--ranks")
      a.ranks = std::stoi(next());
    else if (f == "--tiles")
      a.tiles = next();
    else if (f == "--scaling")
      a.scaling = true;
    else if (f == "--device-info")
      a.device_info = true;
    else if (f == "--no-bandwidth")
      a.no_bandwidth = true;
    else
      throw std::invalid_argument(f + ": unknown flag");
  }
  if (a.scene != "A" && a.scene != "B") throw std::invalid_argument("--scene must be A or B");
  if (a.size != 512 && a.size != 1024 && a.size != 2048 && a.size != 4096 && a.size != 8192)
    throw std::invalid_argument("--size must be 512, 1024, 2048, 4096 or 8192");
  if (a.steps < 1) throw std::invalid_argument("--steps must be >= 1");
  if (a.ranks < 0 || a.ranks > 4096) throw std::invalid_argument("--ranks must be in [1, 4096]");
  if (!a.tiles.empty()) {
    if (a.ranks < 1) throw std::invalid_argument("--tiles needs --ranks P");
    int tx = 0, ty = 0;
    char extra = 0;
    if (std::sscanf(a.tiles.c_str(), "%dx%d%c", &tx, &ty, &extra) != 2 || tx < 1 || ty < 1 ||
        tx * ty != a.ranks)
      throw std::invalid_argument("--tiles must be PXxPY with PX * PY = --ranks, got '" + a.tiles +
                                  "'");
    a.tiles_x = tx;
    a.tiles_y = ty;
  }
  if (a.scaling && a.ranks < 2)
    throw std::invalid_argument("--scaling needs --ranks P with P >= 2");
  return a;
}

erg::v1::JobSpec scene_spec(const Args& a) {
  const double l = 1024.0 / a.size;
  std::ostringstream j;
  j << R"({"name":"bench-)" << a.scene << "-" << a.size << R"(",)"
    << R"("domain":{"nx":)" << a.size << R"(,"ny":)" << a.size << R"(,"cell_size_m":)" << l << "},"
    << R"("layers":{"sand":{"uniform":{"min":)" << (a.scene == "A" ? 0.5 : 3.0) << R"(,"max":)"
    << (a.scene == "A" ? 2.0 : 5.0) << "}}},"
    << R"("wind":{"constant":{"speed_mps":)" << (a.scene == "A" ? 5 : 3)
    << R"(,"direction_deg":0}},)"
    // The hop must stay within 16 cells: at 0.25 m cells, 4 m.
    << R"("model":{)"
    << (a.iterations >= 0 ? R"("avalanche_iterations":)" + std::to_string(a.iterations) + "," : "")
    << R"("max_hop_m":)" << std::min(8.0, 16 * l) << "},"
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

// The command line that runs this benchmark again under mpirun on `ranks`
// ranks (ERG_BENCH_CHILD marks the children), with `extra` flags.
std::vector<std::string> mpirun_argv(const Args& a, int ranks, int threads, bool json) {
  const char* mpirun = std::getenv("ERG_MPIRUN");
  std::vector<std::string> v = {
      mpirun ? mpirun : "mpirun", "-n", std::to_string(ranks), "--bind-to", "none", "-x",
      "ERG_BENCH_CHILD=1"};
  if (static_cast<unsigned>(ranks) > std::max(1u, static_cast<unsigned>(omp_get_num_procs())))
    v.push_back("--oversubscribe");
  char self[4096];
  const ssize_t n = ::readlink("/proc/self/exe", self, sizeof self - 1);
  v.push_back(n > 0 ? std::string(self, static_cast<size_t>(n)) : std::string("erg-bench"));
  v.insert(v.end(),
           {"--scene", a.scene, "--size", std::to_string(a.size), "--steps",
            std::to_string(a.steps), "--warmup", std::to_string(a.warmup), "--threads",
            std::to_string(threads), "--backend", a.backend, "--ranks", std::to_string(ranks)});
  if (a.iterations >= 0) v.insert(v.end(), {"--iterations", std::to_string(a.iterations)});
  if (!a.tiles.empty() && ranks == a.ranks) v.insert(v.end(), {"--tiles", a.tiles});
  if (json) v.push_back("--json");
  return v;
}

std::string shell_quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

// Runs a child benchmark; returns its JSON line (throws if it failed).
std::string run_child(const std::vector<std::string>& argv) {
  std::string cmd;
  for (const auto& s : argv) cmd += shell_quote(s) + " ";
  FILE* p = ::popen(cmd.c_str(), "r");
  if (!p) throw std::runtime_error("cannot start " + argv[0]);
  std::string out;
  char buf[4096];
  while (size_t n = std::fread(buf, 1, sizeof buf, p)) out.append(buf, n);
  const int rc = ::pclose(p);
  const size_t j = out.rfind("{\"scene\"");
  if (rc != 0 || j == std::string::npos)
    throw std::runtime_error("benchmark run failed (" + cmd + "):\n" + out);
  return out.substr(j, out.find('\n', j) - j);
}

double json_number(const std::string& json, const std::string& key) {
  const size_t k = json.find("\"" + key + "\":");
  if (k == std::string::npos) throw std::runtime_error("no " + key + " in " + json);
  return std::strtod(json.c_str() + k + key.size() + 3, nullptr);
}

void set_root_env() {
  // Containers often run as root, which mpirun refuses without these.
  if (::geteuid() == 0) {
    ::setenv("OMPI_ALLOW_RUN_AS_ROOT", "1", 1);
    ::setenv("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1", 1);
  }
}

// --scaling: the scene on 1 rank and on P ranks, the same threads per rank.
int scaling(const Args& a) {
  const int cores = std::max(1, omp_get_num_procs());
  const int threads = a.threads > 0 ? a.threads : std::max(1, cores / a.ranks);
  set_root_env();
  const std::string one = run_child(mpirun_argv(a, 1, threads, true));
  const std::string many = run_child(mpirun_argv(a, a.ranks, threads, true));
  const double t1 = json_number(one, "ms_per_step"), tp = json_number(many, "ms_per_step");
  const double speedup = t1 / tp, efficiency = speedup / a.ranks;
  if (a.json) {
    std::cout << "{\"one_rank\":" << one << ",\"ranks\":" << many << ",\"speedup\":" << speedup
              << ",\"efficiency\":" << efficiency << "}\n";
  } else {
    std::cout.precision(4);
    std::cout << std::fixed << "scene " << a.scene << " " << a.size << "x" << a.size
              << ", strong scaling with " << threads << " thread(s) per rank\n"
              << "  1 rank:  " << t1 << " ms/step\n"
              << "  " << a.ranks << " ranks: " << tp << " ms/step ("
              << json_number(many, "halo_messages_per_step") << " halo messages, "
              << json_number(many, "halo_bytes_per_step") / 1e6 << " MB per rank and step)\n"
              << "  speedup " << speedup << ", efficiency T1/(P TP) = " << 100 * efficiency
              << " %\n";
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  Args a;
  try {
    a = parse(argc, argv);
  } catch (const std::exception& e) {
    std::cerr
        << "erg-bench: " << e.what() << "\n"
        << "usage: erg-bench --scene A|B --size 512|1024|2048|4096|8192 [--steps N]\n"
        << "                 [--warmup W] [--threads T] [--backend auto|cpu|cuda]\n"
        << "                 [--iterations I] [--json] [--ranks P [--tiles PXxPY]] [--scaling]\n"
        << "       erg-bench --device-info [--json]\n";
    return 2;
  }
  if (a.device_info) {
    try {
      const erg::CudaDeviceInfo d = erg::cuda_device_info(0);
      std::ostringstream o;
      o.precision(4);
      o << std::fixed;
      if (a.json)
        o << "{\"device\":\"" << d.name << "\",\"compute_capability\":\"" << d.major << "."
          << d.minor << "\",\"memory_gib\":" << d.memory_bytes / (1u << 30)
          << ",\"multiprocessors\":" << d.multiprocessors
          << ",\"cuda_runtime\":" << d.runtime_version << ",\"cuda_driver\":" << d.driver_version
          << ",\"copy_bandwidth_gbs\":" << d.copy_bytes_per_s / 1e9 << "}\n";
      else
        o << "device 0: " << d.name << ", compute capability " << d.major << "." << d.minor << ", "
          << d.memory_bytes / (1u << 30) << " GiB, " << d.multiprocessors << " SMs; CUDA runtime "
          << d.runtime_version << ", driver " << d.driver_version
          << "\n  device-to-device copy (256 MiB, read + write): " << d.copy_bytes_per_s / 1e9
          << " GB/s\n";
      std::cout << o.str();
      return 0;
    } catch (const std::exception& e) {
      std::cerr << "erg-bench: --device-info: " << e.what() << "\n";
      return 1;
    }
  }
  const bool child = std::getenv("ERG_BENCH_CHILD") != nullptr;
  if (a.ranks >= 1 && !child) {
    try {
      if (a.scaling) return scaling(a);
      const int cores = std::max(1, omp_get_num_procs());
      const int threads = a.threads > 0 ? a.threads : std::max(1, cores / a.ranks);
      set_root_env();
      const std::vector<std::string> v = mpirun_argv(a, a.ranks, threads, a.json);
      std::vector<char*> cv;
      for (const auto& s : v) cv.push_back(const_cast<char*>(s.c_str()));
      cv.push_back(nullptr);
      ::execvp(cv[0], cv.data());
      throw std::runtime_error("cannot run " + v[0] + ": " + std::strerror(errno));
    } catch (const std::exception& e) {
      std::cerr << "erg-bench: " << e.what() << "\n";
      return 1;
    }
  }

  int provided = 0;
  MPI_Init_thread(&argc, &argv, MPI_THREAD_FUNNELED, &provided);
  int rank = 0, nranks = 1;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &nranks);
  const erg::v1::JobSpec spec = scene_spec(a);
  erg::RunOptions opt;
  opt.threads = a.threads > 0 ? a.threads : omp_get_max_threads();
  opt.backend = a.backend == "cpu"    ? erg::BackendKind::kCpu
                : a.backend == "cuda" ? erg::BackendKind::kCuda
                                      : erg::BackendKind::kAuto;
  std::unique_ptr<erg::Tiling> tiling;
  std::unique_ptr<erg::Simulation> simp;
  try {
    tiling = erg::make_tiling(spec, MPI_COMM_WORLD, a.tiles_x, a.tiles_y);
    simp = std::make_unique<erg::Simulation>(spec, ".", opt, tiling->place);
  } catch (const std::exception& e) {
    if (rank == 0) std::cerr << "erg-bench: " << e.what() << "\n";
    MPI_Finalize();
    return 2;
  }
  erg::Simulation& sim = *simp;
  const bool cpu = sim.backend().name() == "cpu";
  // The run takes as long as its slowest rank.
  auto slowest = [](double v) {
    MPI_Allreduce(MPI_IN_PLACE, &v, 1, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
    return v;
  };
  // The first steps relax the random initial sand (every avalanching
  // iteration moves sand everywhere): reported apart from the steady steps.
  MPI_Barrier(MPI_COMM_WORLD);
  const auto tw = Clock::now();
  for (int i = 0; i < a.warmup; ++i) sim.step();
  sim.backend().synchronize();
  const double warmup_ms =
      a.warmup > 0
          ? slowest(std::chrono::duration<double, std::milli>(Clock::now() - tw).count()) / a.warmup
          : 0.0;
  const erg::StageTimes before = sim.times();
  const erg::dist::Exchange::Stats halo0 = sim.exchange().stats();
  MPI_Barrier(MPI_COMM_WORLD);
  const auto t0 = Clock::now();
  for (int i = 0; i < a.steps; ++i) sim.step();
  sim.backend().synchronize();
  const double total_ms =
      slowest(std::chrono::duration<double, std::milli>(Clock::now() - t0).count());
  const erg::StageTimes& after = sim.times();
  const erg::dist::Exchange::Stats halo1 = sim.exchange().stats();
  std::array<double, erg::kStageCount> stage_ms{};
  for (int k = 0; k < erg::kStageCount; ++k)
    stage_ms[static_cast<size_t>(k)] =
        slowest((after.ms[static_cast<size_t>(k)] - before.ms[static_cast<size_t>(k)]) / a.steps);
  const double halo_messages =
      slowest(static_cast<double>(halo1.messages - halo0.messages) / a.steps);
  const double halo_bytes = slowest(static_cast<double>(halo1.bytes - halo0.bytes) / a.steps);
  // Bytes a device backend copied between device and host for the halos
  // (0 on the CPU backend and on one tile).
  const double staged_bytes =
      slowest(static_cast<double>(halo1.host_staged_bytes - halo0.host_staged_bytes) / a.steps);
  // Iterations that moved sand anywhere: every tile runs as many as the
  // most active one (they exchange in rounds together).
  const double iters_per_step = slowest(
      static_cast<double>(after.avalanche_iterations - before.avalanche_iterations) / a.steps);
  // Bandwidth only alone: ranks sharing a node (or a GPU) share its
  // bandwidth. The CPU's is a triad, the GPU's a device-to-device copy.
  double bandwidth = 0.0;
  std::string bandwidth_source = "none";
  if (a.no_bandwidth) {
    // (none measured: no roofline)
  } else if (nranks == 1 && cpu) {
    bandwidth = triad_bandwidth(opt.threads);
    bandwidth_source = "cpu_triad";
  } else if (nranks == 1 && sim.backend().name() == "cuda") {
    bandwidth = erg::cuda_device_info(0).copy_bytes_per_s;
    bandwidth_source = "cuda_device_copy";
  }
  if (rank != 0) {
    MPI_Finalize();
    return 0;
  }

  const double cells = static_cast<double>(a.size) * a.size;
  const double ms_per_step = total_ms / a.steps;
  const int iterations = static_cast<int>(spec.model().avalanche_iterations());
  const ByteModel bm = byte_model();
  // The iterations that ran: those that moved sand, plus the one that found
  // nothing to move (avalanching stops there; later ones would be identities).
  const double iterations_run = std::min<double>(iterations, iters_per_step + 1.0);
  const double bytes_per_step =
      cells * (bm.per_cell_fixed + bm.per_cell_iteration * iterations_run);
  const double roofline_ms = bandwidth > 0 ? 1e3 * bytes_per_step / bandwidth : 0.0;
  const std::string tiles = std::to_string(tiling->d.px) + "x" + std::to_string(tiling->d.py);

  std::ostringstream o;
  o.precision(4);
  o << std::fixed;
  o << "{\"scene\":\"" << a.scene << "\",\"size\":" << a.size
    << ",\"cell_size_m\":" << 1024.0 / a.size << ",\"steps\":" << a.steps << ",\"backend\":\""
    << sim.backend().name() << "\",\"ranks\":" << nranks << ",\"tiles\":\"" << tiles
    << "\",\"threads\":" << (cpu ? opt.threads : 0) << ",\"avalanche_iterations\":" << iterations
    << ",\"avalanche_iterations_moving_per_step\":" << iters_per_step
    << ",\"avalanche_most_iterations_per_step\":" << after.avalanche_most
    << ",\"avalanche_capped_steps\":" << after.avalanche_capped_steps
    << ",\"ms_per_step\":" << ms_per_step << ",\"warmup_steps\":" << a.warmup
    << ",\"warmup_ms_per_step\":" << warmup_ms << ",\"cell_updates_per_s\":" << std::scientific
    << cells * a.steps / (total_ms * 1e-3) << std::fixed
    << ",\"halo_messages_per_step\":" << halo_messages << ",\"halo_bytes_per_step\":" << halo_bytes
    << ",\"halo_path\":\"" << erg::dist::halo_path_name(sim.backend().halo_path())
    << "\",\"host_staged_bytes_per_step\":" << staged_bytes << ",\"stage_ms\":{";
  for (int k = 0; k < erg::kStageCount; ++k)
    o << (k ? "," : "") << "\"" << erg::kStageNames[k] << "\":" << stage_ms[static_cast<size_t>(k)];
  o << "},\"bytes_per_step_model\":" << std::scientific << bytes_per_step << std::fixed
    << ",\"memory_bandwidth_gbs\":" << bandwidth / 1e9 << ",\"bandwidth_source\":\""
    << bandwidth_source << "\""
    << ",\"roofline_ms_per_step\":" << roofline_ms
    << ",\"ratio_to_roofline\":" << (roofline_ms > 0 ? ms_per_step / roofline_ms : 0.0) << "}";
  if (a.json) {
    std::cout << o.str() << "\n";
  } else {
    std::cout << "scene " << a.scene << " " << a.size << "x" << a.size << " (" << 1024.0 / a.size
              << " m cells), " << sim.backend().name() << ", " << nranks << " rank(s) as " << tiles
              << " tiles, " << (cpu ? opt.threads : 0) << " threads per rank\n"
              << "  " << ms_per_step << " ms/step, " << cells * a.steps / (total_ms * 1e-3) / 1e6
              << " Mcell-updates/s; avalanching moved sand in " << iters_per_step
              << " iterations per step (at most " << after.avalanche_most << " in a step, cap "
              << iterations << ", " << after.avalanche_capped_steps << " steps capped)\n"
              << "  first " << a.warmup << " steps (relaxing the random sand): " << warmup_ms
              << " ms/step\n";
    if (nranks > 1)
      std::cout << "  halo exchange: " << halo_messages << " messages, " << halo_bytes / 1e6
                << " MB per rank and step (the slowest rank's stage times below), path "
                << erg::dist::halo_path_name(sim.backend().halo_path()) << "\n";
    if (staged_bytes > 0)
      std::cout << "  staged between device and host for the halos: " << staged_bytes / 1e6
                << " MB per rank and step\n";
    for (int k = 0; k < erg::kStageCount; ++k)
      std::cout << "  " << erg::kStageNames[k] << ": " << stage_ms[static_cast<size_t>(k)]
                << " ms\n";
    if (bandwidth > 0)
      std::cout << "  roofline: " << bytes_per_step / 1e6 << " MB/step at " << bandwidth / 1e9
                << " GB/s (" << bandwidth_source << ") = " << roofline_ms << " ms/step; erg is "
                << ms_per_step / roofline_ms << "x from it\n";
  }
  MPI_Finalize();
  return 0;
}

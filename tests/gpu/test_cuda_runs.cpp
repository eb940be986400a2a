// SPDX-License-Identifier: Apache-2.0
// Whole runs on the CUDA backend (label gpu: they need a device, so CI,
// which has none, excludes the label by name in its preset):
// - two runs of the same job give the same bits, in both transport modes;
// - sand, airborne sand and bedrock are conserved to the unit;
// - 1, 2 and 4 tiles on one GPU (ranks sharing it) give the same bits, on
//   the halo path the MPI library allows (dist/halo_path.h): host-staged,
//   with its copies overlapping the wind warping (a split fill) and every
//   exchange's bytes counted, or CUDA-aware MPI with none staged; where
//   the library is CUDA-aware, the staged path (ERG_CUDA_AWARE_MPI=0) too;
// - a checkpoint and resume continues bitwise;
// - the landforms match the CPU backend's: the same exact totals and the
//   relief within 2% (the float fields may differ in the last bits: the
//   device's math functions need not round as the host's do, so the wind,
//   and then the cells it moves, can differ).
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "../common/same_snapshots.h"
#include "../common/temp_dir.h"
#include "io/io.h"
#include "job/worker_event.h"

namespace {

namespace fs = std::filesystem;
using TempDir = erg::test_support::TempDir;

// The build's erg-worker and mpiexec, unless ERG_WORKER_BIN / ERG_MPIEXEC
// name others: a bundle (deploy/gpu/bundle.sh) runs this binary on a machine
// where the build's paths do not exist, through its own loader.
std::string from_env(const char* name, const char* built) {
  const char* v = std::getenv(name);
  return v && *v ? std::string(v) : std::string(built);
}
const std::string kWorker = from_env("ERG_WORKER_BIN", ERG_WORKER_BIN);
const std::string kMpirun =
    from_env("ERG_MPIEXEC", ERG_MPIEXEC) + " --allow-run-as-root --oversubscribe --bind-to none";

// No events that add sand: the totals are those of the initial layers.
std::string job(const std::string& transport) {
  return R"({
  "name": "gpu",
  "domain": {"nx": 128, "ny": 96, "cell_size_m": 1.0},
  "layers": {
    "bedrock": {"fbm": {"amplitude": 2, "wavelength_m": 64, "octaves": 2}},
    "sand": {"patches": {"coverage": 0.4, "radius_m": 10, "height": 3, "falloff_m": 4}},
    "vegetation": {"uniform": {"min": 0, "max": 0.2}},
    "obstacles": {"shapes": [{"height_m": 3, "disk": {"x_m": 60, "y_m": 40, "radius_m": 8}}]}
  },
  "wind": {"constant": {"speed_mps": 6, "direction_deg": 30}},
  "transport": ")" +
         transport + R"(",
  "seed": 5,
  "run": {"steps": 40, "snapshot_every": 20, "checkpoint_every": 20}
})";
}

int run(const std::string& cmd, std::string* out = nullptr) {
  std::array<char, 4096> buf{};
  std::string text;
  FILE* p = ::popen((cmd + " 2>&1").c_str(), "r");
  if (!p) return -1;
  size_t n;
  while ((n = std::fread(buf.data(), 1, buf.size(), p)) > 0) text.append(buf.data(), n);
  const int status = ::pclose(p);
  if (out) *out = text;
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

std::string snapshot(const fs::path& dir, int step) {
  char name[32];
  std::snprintf(name, sizeof name, "step_%08d.h5", step);
  return (dir / "snapshots" / name).string();
}

void run_ok(const std::string& cmd) {
  std::string out;
  ASSERT_EQ(run(cmd, &out), 0) << cmd << "\n" << out;
}

__int128 total(const erg::io::Snapshot& s) {
  __int128 t = 0;
  for (const std::string* d :
       {&s.meta.sand_units_total, &s.meta.airborne_units_total, &s.meta.bedrock_units_total}) {
    __int128 v = 0;
    bool neg = false;
    for (char c : *d) {
      if (c == '-')
        neg = true;
      else
        v = v * 10 + (c - '0');
    }
    t += neg ? -v : v;
  }
  return t;
}

double relief_m(const erg::io::Snapshot& s) {
  const auto& b = s[erg::fields::kBedrock];
  const auto& a = s[erg::fields::kSand];
  double sum = 0, sq = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    const double h = static_cast<double>(a[i]) + b[i];
    sum += h;
    sq += h * h;
  }
  const double n = static_cast<double>(a.size());
  return std::sqrt(std::max(0.0, sq / n - (sum / n) * (sum / n)));
}

// The done event of a worker's progress output (--progress-fd 1).
erg::v1::WorkerEvent::Done done_of(const std::string& output) {
  std::istringstream lines(output);
  for (std::string line; std::getline(lines, line);)
    if (const auto ev = erg::job::parse_worker_event(line); ev && ev->has_done()) return ev->done();
  ADD_FAILURE() << "no done event in\n" << output;
  return {};
}

class CudaRuns : public ::testing::TestWithParam<std::string> {};

TEST_P(CudaRuns, RepeatTilesRestartConservationAndTheCpu) {
  TempDir t("erg_gpu");
  const fs::path spec = t / "job.json";
  std::ofstream(spec) << job(GetParam());
  const std::string base = kWorker + " " + spec.string() + " --quiet --backend ";
  run_ok(base + "cuda --out " + (t / "a"));
  std::string text;  // one tile: the periodic wrap on the device, nothing staged
  ASSERT_EQ(run(base + "cuda --progress-fd 1 --out " + (t / "b"), &text), 0) << text;
  EXPECT_EQ(done_of(text).halo_path(), "device");
  EXPECT_EQ(done_of(text).host_staged_bytes_per_step(), 0);
  for (int step : {20, 40})
    erg::test::expect_same_snapshot(snapshot(t / "a", step), snapshot(t / "b", step),
                                    "two CUDA runs, step " + std::to_string(step));
  // Conservation: the exact totals of every snapshot are those of step 0.
  const __int128 t0 = total(erg::io::read_snapshot(snapshot(t / "a", 0)));
  for (int step : {20, 40})
    EXPECT_TRUE(total(erg::io::read_snapshot(snapshot(t / "a", step))) == t0) << "step " << step;
  // Tiles on one GPU: ranks share the device. The done event says which
  // halo path ran and what it staged: the frames of every exchange, there
  // and back (dist/halo_path.h), on the staged path, where the heights'
  // split fill overlaps its copies with the wind warping; nothing on the
  // CUDA-aware path, which is then run staged too (ERG_CUDA_AWARE_MPI=0).
  for (int ranks : {2, 4})
    for (const std::string env : {"", "ERG_CUDA_AWARE_MPI=0 "}) {
      const fs::path out = t / ("tiles" + std::to_string(ranks) + (env.empty() ? "" : "_staged"));
      ASSERT_EQ(run(env + kMpirun + " -n " + std::to_string(ranks) + " " + base +
                        "cuda --progress-fd 1 --out " + out.string(),
                    &text),
                0)
          << text;
      const erg::v1::WorkerEvent::Done done = done_of(text);
      const bool staged = done.halo_path() == "host-staged";
      EXPECT_TRUE(staged || (env.empty() && done.halo_path() == "cuda-aware-mpi"))
          << env << done.halo_path();
      if (staged) {
        EXPECT_GT(done.host_staged_bytes_per_step(), 0);
      } else {
        EXPECT_EQ(done.host_staged_bytes_per_step(), 0);
      }
      EXPECT_GT(done.halo_bytes_per_step(), 0);
      erg::test::expect_same_snapshot(snapshot(t / "a", 40), snapshot(out, 40),
                                      std::to_string(ranks) + " tiles, " + done.halo_path());
      if (staged) break;  // the MPI library is not CUDA-aware: no other path to compare
    }
  // Stop at the checkpoint of step 20, resume to 40.
  run_ok(base + "cuda --out " + (t / "r") + " --steps 20");
  run_ok(kWorker + " --resume " + (t / "r") + " --steps 40 --quiet --backend cuda");
  erg::test::expect_same_snapshot(snapshot(t / "a", 40), snapshot(t / "r", 40), "resumed");
  // The CPU backend's landforms.
  run_ok(base + "cpu --out " + (t / "cpu"));
  const erg::io::Snapshot g = erg::io::read_snapshot(snapshot(t / "a", 40));
  const erg::io::Snapshot c = erg::io::read_snapshot(snapshot(t / "cpu", 40));
  EXPECT_TRUE(total(g) == total(c));
  EXPECT_NEAR(relief_m(g), relief_m(c), 0.02 * relief_m(c));
}

INSTANTIATE_TEST_SUITE_P(Transport, CudaRuns, ::testing::Values("EXPECTED", "STOCHASTIC"));

}  // namespace

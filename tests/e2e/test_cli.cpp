// SPDX-License-Identifier: Apache-2.0
// The programs as users run them: `erg run` (progress, outputs, the snapshot
// file contract, resume, refusal to clobber, bad jobs, signals), the
// examples, erg-bench and the backend flag.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>

#include "../common/temp_dir.h"
#include "io/io.h"

namespace fs = std::filesystem;

namespace {

const std::string kErg = ERG_BIN;
const std::string kWorker = ERG_WORKER_BIN;
const std::string kBench = ERG_BENCH_BIN;
const std::string kExamples = ERG_EXAMPLES_DIR;

struct Result {
  int code;
  std::string output;  // stdout and stderr
};

Result run(const std::string& cmd) {
  std::array<char, 4096> buf{};
  std::string out;
  FILE* p = ::popen((cmd + " 2>&1").c_str(), "r");
  if (!p) return {-1, ""};
  size_t n;
  while ((n = std::fread(buf.data(), 1, buf.size(), p)) > 0) out.append(buf.data(), n);
  const int status = ::pclose(p);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status), out};
}

using TempDir = erg::test_support::TempDir;

void write(const std::string& path, const std::string& text) {
  std::ofstream o(path);
  o << text;
}

// A small job exercising every layer and an event.
const char* kSmallJob = R"({
  "name": "e2e",
  "domain": {"nx": 64, "ny": 48, "cell_size_m": 2.0},
  "layers": {
    "bedrock": {"fbm": {"amplitude": 2, "wavelength_m": 64, "octaves": 2}},
    "sand": {"patches": {"coverage": 0.3, "radius_m": 10, "height": 2, "falloff_m": 4}},
    "vegetation": {"uniform": {"min": 0, "max": 0.2}},
    "obstacles": {"shapes": [{"height_m": 3, "disk": {"x_m": 60, "y_m": 40, "radius_m": 8}}]}
  },
  "wind": {"constant": {"speed_mps": 5, "direction_deg": 30}},
  "events": [{"step": 5, "sand": {"x_m": 60, "y_m": 40, "radius_m": 12, "falloff_m": 4, "height": 2}}],
  "seed": 3,
  "run": {"steps": 24, "snapshot_every": 8, "checkpoint_every": 8}
})";

TEST(Cli, RunWritesTheDocumentedOutputs) {
  TempDir t("erg_e2e");
  write(t / "job.json", kSmallJob);
  const Result r =
      run(kErg + " run " + (t / "job.json") + " --out " + (t / "out") + " --threads 2");
  ASSERT_EQ(r.code, 0) << r.output;
  // Progress bar (non-TTY form: a line per 10%) and the summary.
  EXPECT_NE(r.output.find("step 24/24"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("100%"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("steps/s"), std::string::npos) << r.output;
  for (const char* s : {"00000000", "00000008", "00000016", "00000024"}) {
    EXPECT_TRUE(fs::exists(t / ("out/snapshots/step_" + std::string(s) + ".h5"))) << s;
    EXPECT_TRUE(fs::exists(t / ("out/snapshots/step_" + std::string(s) + ".xdmf"))) << s;
    EXPECT_TRUE(fs::exists(t / ("out/previews/step_" + std::string(s) + ".png"))) << s;
  }
  EXPECT_TRUE(fs::exists(t / "out/checkpoints/step_00000024.h5"));
  EXPECT_TRUE(fs::exists(t / "out/job.json"));
  // Only the newest two checkpoints are kept; no temporaries are left.
  int checkpoints = 0;
  for (const auto& e : fs::recursive_directory_iterator(t / "out")) {
    EXPECT_EQ(e.path().string().find(".tmp-"), std::string::npos) << e.path();
    if (e.path().parent_path().filename() == "checkpoints") ++checkpoints;
  }
  EXPECT_EQ(checkpoints, 2);

  // The file contract, read back by erg's reader ...
  const erg::io::Snapshot s = erg::io::read_snapshot(t / "out/snapshots/step_00000024.h5");
  EXPECT_EQ(s.meta.step, 24);
  EXPECT_EQ(s.meta.nx, 64);
  EXPECT_EQ(s.meta.ny, 48);
  EXPECT_DOUBLE_EQ(s.meta.cell_size_m, 2.0);
  EXPECT_DOUBLE_EQ(s.meta.time_days, 240.0);
  EXPECT_DOUBLE_EQ(s.meta.unit_m, 1.0 / 4294967296.0);
  EXPECT_EQ(s[erg::fields::kBedrock].size(), 64u * 48u);
  EXPECT_EQ(s.wind.size(), 64u * 48u * 2u);
  EXPECT_NE(s.meta.job_spec_json.find("\"nx\": \"64\""), std::string::npos);
  // Every snapshot layer of the field registry is there, the deposition
  // diagnostic included: sand that landed and stayed in the last step, in
  // metres, never negative, none on the obstacle, some somewhere; none at
  // step 0, before any step.
  for (const erg::fields::Id id : erg::fields::snapshot_order())
    EXPECT_EQ(s[id].size(), 64u * 48u) << erg::fields::info(id).name;
  const std::vector<float>& deposited = s[erg::fields::kDeposited];
  double total = 0;
  for (std::size_t c = 0; c < deposited.size(); ++c) {
    EXPECT_GE(deposited[c], 0.0f) << c;
    if (s[erg::fields::kObstacles][c] > 0) {
      EXPECT_EQ(deposited[c], 0.0f) << c;
    }
    total += deposited[c];
  }
  EXPECT_GT(total, 0.0);
  const erg::io::Snapshot first = erg::io::read_snapshot(t / "out/snapshots/step_00000000.h5");
  for (const float d : first[erg::fields::kDeposited]) ASSERT_EQ(d, 0.0f);
  // ... and by an independent tool (h5py): shapes, dtypes, and the exact
  // totals match the checkpoint's integers.
  const std::string py = R"(
import h5py, numpy as np, sys
f = h5py.File(sys.argv[1], 'r')
c = h5py.File(sys.argv[2], 'r')
# Layers are (time, y, x) with one time: netCDF-4 / CF (README).
for n in ('bedrock', 'sand', 'vegetation', 'wind_x', 'wind_y', 'airborne', 'shadow', 'obstacles'):
    assert f[n].shape == (1, 48, 64) and f[n].dtype == np.float32, n
assert f.attrs['Conventions'] == 'CF-1.10' and f['time'][0] == f.attrs['time_days']
# The obstacle disk (3 m high, radius 8 m at (60 m, 40 m)) holds no sand,
# and the checkpoint carries the same mask.
o = f['obstacles'][0]
assert o.max() == 3 and 40 <= (o > 0).sum() <= 60, (o.max(), (o > 0).sum())
assert (f['sand'][0][o > 0] == 0).all() and (f['airborne'][0][o > 0] == 0).all()
assert (c['obstacles'][:] == o).all()
for a in ('step', 'time_days', 'cell_size_m', 'nx', 'ny', 'job_spec', 'erg_version', 'unit_m',
          'sand_units_total', 'bedrock_units_total'):
    assert a in f.attrs, a
assert int(f.attrs['sand_units_total']) == int(c['sand_units'][:].astype(object).sum())
assert int(f.attrs['bedrock_units_total']) == int(c['bedrock_units'][:].astype(object).sum())
unit = f.attrs['unit_m']
assert np.allclose(f['sand'][0], c['sand_units'][:] * unit, rtol=1e-6, atol=1e-6)
print('contract ok')
)";
  write(t / "check.py", py);
  const Result p =
      run("/usr/bin/python3 " + (t / "check.py") + " " + (t / "out/snapshots/step_00000024.h5") +
          " " + (t / "out/checkpoints/step_00000024.h5"));
  if (p.output.find("No module named") != std::string::npos)
    GTEST_SKIP() << "h5py missing: " << p.output;
  EXPECT_EQ(p.code, 0) << p.output;
  EXPECT_NE(p.output.find("contract ok"), std::string::npos) << p.output;
}

// erg amplify on a real run: a region across the torus edge, upsampled,
// as an HDF5 heightmap (read back by h5py) and a PNG; bad regions named.
TEST(Cli, AmplifyWritesAHeightmapAndPreview) {
  TempDir t("erg_e2e");
  write(t / "job.json", kSmallJob);
  ASSERT_EQ(
      run(kErg + " run " + (t / "job.json") + " --out " + (t / "out") + " --steps 8 --threads 2")
          .code,
      0);
  const Result r = run(kErg + " amplify " + (t / "out") + " --step 8 --region 56,40,16,12" +
                       " --upsample 4 --out " + (t / "amp.h5"));
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_TRUE(fs::exists(t / "amp.png"));
  for (const auto& e : fs::directory_iterator(t.path()))
    EXPECT_EQ(e.path().string().find(".tmp-"), std::string::npos) << e.path();
  const std::string py = R"(
import h5py, numpy as np, sys
f = h5py.File(sys.argv[1], 'r')
s = h5py.File(sys.argv[2], 'r')
h = f['height'][:]
assert h.shape == (48, 64) and h.dtype == np.float32, h.shape
assert f.attrs['cell_size_m'] == 0.5 and f.attrs['upsample'] == 4
assert f.attrs['region_x0'] == 56 and f.attrs['region_w'] == 16
# The heightmap follows the snapshot's terrain (cell 0,0 of the region is
# snapshot cell (56, 40)), plus centimetres of ripples and bumps.
t = s['bedrock'][0] + s['sand'][0]
c = h.reshape(12, 4, 16, 4).mean(axis=(1, 3))
ref = np.roll(np.roll(t, -40, axis=0), -56, axis=1)[:12, :16]
assert np.abs(c - ref).mean() < 0.25, np.abs(c - ref).mean()
print('heightmap ok')
)";
  write(t / "check.py", py);
  const Result p = run("/usr/bin/python3 " + (t / "check.py") + " " + (t / "amp.h5") + " " +
                       (t / "out/snapshots/step_00000008.h5"));
  if (p.output.find("No module named") != std::string::npos)
    GTEST_SKIP() << "h5py missing: " << p.output;
  EXPECT_EQ(p.code, 0) << p.output;
  EXPECT_NE(p.output.find("heightmap ok"), std::string::npos) << p.output;
  // Same arguments, same bits.
  ASSERT_EQ(run(kErg + " amplify " + (t / "out") + " --step 8 --region 56,40,16,12" +
                " --upsample 4 --out " + (t / "amp2.h5"))
                .code,
            0);
  EXPECT_EQ(erg::io::read_hdf5_map(t / "amp.h5", "height").values,
            erg::io::read_hdf5_map(t / "amp2.h5", "height").values);

  const Result bad =
      run(kErg + " amplify " + (t / "out") + " --region 0,0,65,4 --out " + (t / "bad.h5"));
  EXPECT_EQ(bad.code, 2);
  EXPECT_NE(bad.output.find("--region W = 65 is out of range; allowed [1, 64]"), std::string::npos)
      << bad.output;
  EXPECT_FALSE(fs::exists(t / "bad.h5"));
  EXPECT_EQ(run(kErg + " amplify " + (t / "out") + " --step 7 --out " + (t / "x.h5")).code, 1);
}

std::vector<std::int64_t> final_sand(const std::string& dir, const std::string& step) {
  return erg::io::read_checkpoint(dir + "/checkpoints/step_" + step + ".h5")
      .units[erg::fields::kSand];
}

// Stopping and resuming gives the same bits as running straight through, in
// both transport modes.
TEST(Cli, ResumeContinuesBitwiseIdentically) {
  for (const std::string transport : {"EXPECTED", "STOCHASTIC"}) {
    TempDir t("erg_e2e");
    std::string job = kSmallJob;
    job.replace(job.find("\"seed\""), 0, "\"transport\": \"" + transport + "\", ");
    write(t / "job.json", job);
    ASSERT_EQ(run(kErg + " run " + (t / "job.json") + " --out " + (t / "straight")).code, 0);
    ASSERT_EQ(
        run(kErg + " run " + (t / "job.json") + " --out " + (t / "split") + " --steps 8").code, 0);
    const Result r = run(kErg + " run --resume " + (t / "split") + " --steps 24 --threads 1");
    ASSERT_EQ(r.code, 0) << r.output;
    const auto a = erg::io::read_checkpoint(t / "straight/checkpoints/step_00000024.h5");
    const auto b = erg::io::read_checkpoint(t / "split/checkpoints/step_00000024.h5");
    EXPECT_TRUE(a.units[erg::fields::kSand] == b.units[erg::fields::kSand]) << transport;
    EXPECT_TRUE(a.units[erg::fields::kBedrock] == b.units[erg::fields::kBedrock]) << transport;
    EXPECT_TRUE(a.units[erg::fields::kAirborne] == b.units[erg::fields::kAirborne]) << transport;
    EXPECT_TRUE(a.reals[erg::fields::kVegetation] == b.reals[erg::fields::kVegetation])
        << transport;
    const auto sa = erg::io::read_snapshot(t / "straight/snapshots/step_00000024.h5");
    const auto sb = erg::io::read_snapshot(t / "split/snapshots/step_00000024.h5");
    EXPECT_TRUE(sa[erg::fields::kSand] == sb[erg::fields::kSand] && sa.wind == sb.wind &&
                sa[erg::fields::kBedrock] == sb[erg::fields::kBedrock])
        << transport;
    EXPECT_EQ(sa.meta.sand_units_total, sb.meta.sand_units_total);
  }
}

TEST(Cli, SigtermCheckpointsAndResumeFinishesTheSameRun) {
  TempDir t("erg_e2e");
  std::string job = kSmallJob;
  job.replace(job.find("\"steps\": 24, \"snapshot_every\": 8, \"checkpoint_every\": 8"), 55,
              "\"steps\": 2000, \"snapshot_every\": 50, \"checkpoint_every\": 500");
  write(t / "job.json", job);
  ASSERT_EQ(run(kErg + " run " + (t / "job.json") + " --out " + (t / "straight")).code, 0);
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::execl(kWorker.c_str(), kWorker.c_str(), (t / "job.json").c_str(), "--out",
            (t / "stopped").c_str(), "--quiet", static_cast<char*>(nullptr));
    _exit(127);
  }
  // Let it start stepping, then ask it to stop.
  for (int i = 0; i < 400 && !fs::exists(t / "stopped/snapshots/step_00000050.h5"); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(25));
  ::kill(pid, SIGTERM);
  int status = 0;
  ::waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFEXITED(status));
  if (WEXITSTATUS(status) == 0) GTEST_SKIP() << "the run finished before the signal";
  EXPECT_EQ(WEXITSTATUS(status), 128 + SIGTERM);
  const Result r = run(kErg + " run --resume " + (t / "stopped"));
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_TRUE(final_sand(t / "straight", "00002000") == final_sand(t / "stopped", "00002000"));
}

TEST(Cli, RefusesToOverwriteARunAndRejectsBadJobs) {
  TempDir t("erg_e2e");
  write(t / "job.json", kSmallJob);
  ASSERT_EQ(run(kErg + " run " + (t / "job.json") + " --out " + (t / "out") + " --steps 8").code,
            0);
  const auto before = fs::last_write_time(t / "out/checkpoints/step_00000008.h5");
  Result r = run(kErg + " run " + (t / "job.json") + " --out " + (t / "out"));
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("already holds a run"), std::string::npos) << r.output;
  EXPECT_EQ(fs::last_write_time(t / "out/checkpoints/step_00000008.h5"), before);

  std::string bad = kSmallJob;
  bad.replace(bad.find("\"nx\": 64"), 8, "\"nx\": -5");
  write(t / "bad.json", bad);
  r = run(kErg + " run " + (t / "bad.json") + " --out " + (t / "bad-out"));
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("domain.nx = -5"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("[8, 1048576]"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(t / "bad-out")) << "a rejected job created its output directory";

  r = run(kErg + " run " + (t / "job.json") + " --out " + (t / "x") + " --steps -3");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("--steps -3"), std::string::npos) << r.output;
  r = run(kErg + " run --resume " + (t / "nothing-here"));
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("no checkpoint"), std::string::npos) << r.output;
}

TEST(Cli, CheckAndParamsPrintTheSchema) {
  TempDir t("erg_e2e");
  write(t / "job.json", kSmallJob);
  Result r = run(kErg + " check " + (t / "job.json"));
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("\"venturi_k\": 0.005"), std::string::npos) << r.output;
  r = run(kErg + " params");
  ASSERT_EQ(r.code, 0);
  EXPECT_NE(r.output.find("`model.repose_deg` | 33"), std::string::npos) << r.output;
}

TEST(Cli, BackendFlag) {
  TempDir t("erg_e2e");
  write(t / "job.json", kSmallJob);
  Result r = run(kWorker + " " + (t / "job.json") + " --out " + (t / "a") +
                 " --steps 2 --backend auto --quiet");
  ASSERT_EQ(r.code, 0) << r.output;
  // auto says when it falls back to the CPU (no device, or a build without
  // CUDA); then cuda refuses, naming the flag. Where a device exists, auto
  // says nothing and cuda runs.
  const bool no_device = r.output.find("using the CPU backend") != std::string::npos;
  r = run(kWorker + " " + (t / "job.json") + " --out " + (t / "b") +
          " --steps 2 --backend cuda --quiet");
  if (no_device) {
    EXPECT_EQ(r.code, 2) << r.output;
    EXPECT_NE(r.output.find("--backend cuda"), std::string::npos) << r.output;
  } else {
    EXPECT_EQ(r.code, 0) << r.output;
  }
  r = run(kWorker + " " + (t / "job.json") + " --out " + (t / "c") + " --backend gpu");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("expected auto, cpu or cuda"), std::string::npos) << r.output;
}

TEST(Cli, BenchPrintsJsonWithStageTimes) {
  const Result r = run(kBench + " --scene A --size 512 --steps 2 --warmup 1 --threads 2 --json");
  ASSERT_EQ(r.code, 0) << r.output;
  for (const char* key :
       {"\"ms_per_step\"", "\"stage_ms\"", "\"avalanching\"", "\"cell_updates_per_s\"",
        "\"threads\":2", "\"backend\":\"cpu\"", "\"roofline_ms_per_step\"",
        "\"host_staged_bytes_per_step\":0", "\"halo_path\":\"host\""})
    EXPECT_NE(r.output.find(key), std::string::npos) << key << " in " << r.output;
}

// --no-bandwidth skips the triad (1.5 GB) and the roofline; --iterations
// sets the job's model.avalanche_iterations (README, "Performance").
TEST(Cli, BenchWithoutBandwidthAndWithAnotherCap) {
  const Result r = run(kBench +
                       " --scene A --size 512 --steps 1 --warmup 1 --threads 2 --json"
                       " --no-bandwidth --iterations 50");
  ASSERT_EQ(r.code, 0) << r.output;
  for (const char* key : {"\"bandwidth_source\":\"none\"", "\"roofline_ms_per_step\":0.0000",
                          "\"avalanche_iterations\":50,"})
    EXPECT_NE(r.output.find(key), std::string::npos) << key << " in " << r.output;
}

// Every example runs (for a few steps: the full runs are for users).
class Example : public ::testing::TestWithParam<std::string> {};
TEST_P(Example, Runs) {
  TempDir t("erg_e2e");
  const std::string job = kExamples + "/" + GetParam() + ".json";
  Result r = run(kErg + " check " + job);
  ASSERT_EQ(r.code, 0) << r.output;
  r = run(kErg + " run " + job + " --out " + (t / "out") + " --steps 6 --snapshot-every 3");
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_TRUE(fs::exists(t / "out/previews/step_00000006.png"));
  const erg::io::Snapshot s = erg::io::read_snapshot(t / "out/snapshots/step_00000006.h5");
  EXPECT_EQ(s.meta.step, 6);
}
// (examples/sand_sea/sand_sea.json is 6.5e9 cells: it is checked, never run,
// below; its 1/4096-area twin runs here.)
INSTANTIATE_TEST_SUITE_P(Examples, Example,
                         ::testing::Values("barchans", "transverse", "linear", "star", "nabkha",
                                           "yardangs", "echo_dune", "vortex", "barchans_expected",
                                           "transverse_expected", "linear_expected",
                                           "sand_sea/sand_sea_small"));

// The continent-scale sand sea passes `erg check` (domain a multiple of the
// coarse wind cell, physical wind) and is 4096 times its small twin.
TEST(SandSea, TheContinentJobIsValidAndNotRun) {
  const Result r = run(kErg + " check " + kExamples + "/sand_sea/sand_sea.json");
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("\"nx\": 80640"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("steps per year"), std::string::npos) << r.output;
}

}  // namespace

namespace {

// One source of truth: README's parameter table is `erg params` verbatim.
TEST(Cli, ReadmeParameterTableMatchesTheSchema) {
  std::ifstream in(std::string(ERG_SOURCE_DIR) + "/README.md");
  std::stringstream ss;
  ss << in.rdbuf();
  const std::string readme = ss.str();
  const std::string begin = "<!-- erg params: begin -->\n", end = "<!-- erg params: end -->";
  const size_t b = readme.find(begin), e = readme.find(end);
  ASSERT_NE(b, std::string::npos);
  ASSERT_NE(e, std::string::npos);
  const Result r = run(kErg + " params");
  ASSERT_EQ(r.code, 0);
  EXPECT_EQ(readme.substr(b + begin.size(), e - b - begin.size()), r.output)
      << "README's table is stale: replace it with the output of `erg params`";
}

}  // namespace

namespace {

// A job whose cells are too coarse for a length the model uses is valid
// and warned, by erg check and by the worker's start-up log, in the same
// words (sim/resolution.h); a fine one is not warned.
TEST(Cli, CoarseCellsGetAWarningNamingTheLength) {
  TempDir t("erg_e2e");
  write(t / "coarse.json", R"({"domain": {"nx": 16, "ny": 16, "cell_size_m": 4},
    "layers": {"sand": {"uniform": {"min": 1, "max": 2}}},
    "wind": {"constant": {"speed_mps": 5}}, "run": {"steps": 1}})");
  const std::string warning =
      "erg: warning: the wind shadow's reach, model.shadow_radius_m = 10 m, is shorter than 4 "
      "cells of 4 m (domain.cell_size_m): it is taken as 3 whole cells (12 m, 20% longer)";
  const Result check = run(kErg + " check " + (t / "coarse.json"));
  EXPECT_EQ(check.code, 0) << check.output;
  EXPECT_NE(check.output.find(warning), std::string::npos) << check.output;
  const Result worker =
      run(kWorker + " " + (t / "coarse.json") + " --out " + (t / "out") + " --threads 1 --quiet");
  EXPECT_EQ(worker.code, 0) << worker.output;
  EXPECT_NE(worker.output.find(warning), std::string::npos) << worker.output;
  write(t / "fine.json", kSmallJob);
  const Result fine = run(kErg + " check " + (t / "fine.json"));
  EXPECT_EQ(fine.code, 0) << fine.output;
  EXPECT_EQ(fine.output.find("warning"), std::string::npos) << fine.output;
}

// The job shown in README is a valid job.
TEST(Cli, ReadmeExampleJobIsValid) {
  std::ifstream in(std::string(ERG_SOURCE_DIR) + "/README.md");
  std::stringstream ss;
  ss << in.rdbuf();
  const std::string readme = ss.str();
  const size_t b = readme.find("```json\n");
  ASSERT_NE(b, std::string::npos);
  const size_t e = readme.find("```", b + 8);
  TempDir t("erg_e2e");
  write(t / "readme.json", readme.substr(b + 8, e - b - 8));
  const Result r = run(kErg + " check " + (t / "readme.json"));
  EXPECT_EQ(r.code, 0) << r.output;
}

}  // namespace

// SPDX-License-Identifier: Apache-2.0
// The tiled worker: the same job on 1, 2, 3, 4 and 6 MPI ranks
// gives identical exact state and identical snapshot datasets after every
// snapshot, in both transport modes, with abrasion, vegetation, events, a
// wind rose and local wind primitives (over the seams, added and removed)
// on; a restart on another rank count continues bitwise; a rank killed
// mid-run leaves the previous snapshot and checkpoint intact; a bad tile
// grid is refused on every rank without hanging.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "../common/same_snapshots.h"
#include "../common/temp_dir.h"
#include "io/io.h"
#include "job/worker_event.h"

namespace fs = std::filesystem;

namespace {

using TempDir = erg::test_support::TempDir;

const std::string kErg = ERG_BIN;
const std::string kWorker = ERG_WORKER_BIN;
// As root, Open MPI wants to be told; more ranks than cores need oversubscribe.
const std::string kMpirun =
    std::string(ERG_MPIEXEC) + " --allow-run-as-root --oversubscribe --bind-to none";

struct Result {
  int code;
  std::string output;
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

void write(const std::string& path, const std::string& text) {
  std::ofstream o(path);
  o << text;
}

// Every stage and coupling on: bedrock relief, patches, vegetation,
// resistance, obstacles across tile edges, echo dunes in front of a steep
// bedrock mesa across tile edges, a wind rose, wind primitives (a vortex over
// the corner of the torus, a drifting, evolving turbulence region, a vortex an
// event adds for three steps, one an event removes), five kinds of events (an
// obstacle built and one cleared), abrasion turning rock into sand,
// bedrock avalanching. 120 x 96 cells: 6 tiles of 40 x 48 still hold
// the halo of 12 avalanching iterations (25 cells).
std::string job(const std::string& transport) {
  return R"({"domain": {"nx": 120, "ny": 96, "cell_size_m": 1.0},
 "layers": {"bedrock": {"fbm": {"amplitude": 3, "wavelength_m": 48, "octaves": 3},
                       "piles": [{"x_m": 80, "y_m": 30, "height": 6, "radius_m": 10, "shape": "CYLINDER"}]},
            "sand": {"patches": {"coverage": 0.4, "radius_m": 8, "height": 3, "falloff_m": 3}},
            "vegetation": {"fbm": {"amplitude": 0.6, "offset": 0.1, "wavelength_m": 40, "octaves": 2}},
            "resistance": {"fbm": {"amplitude": 0.5, "offset": 0.5, "wavelength_m": 30, "octaves": 2}},
            "obstacles": {"shapes": [
              {"height_m": 3, "disk": {"x_m": 40, "y_m": 48, "radius_m": 5}},
              {"height_m": 5, "rect": {"x_m": 77, "y_m": 60, "size_x_m": 6, "size_y_m": 30}},
              {"height_m": 0.3, "road": {"points": [{"x_m": 2, "y_m": 90}, {"x_m": 118, "y_m": 40}], "width_m": 2}}]}},
 "wind": {"rose": {"entries": [{"direction_deg": 30, "speed_mps": 6, "probability": 0.6},
                               {"direction_deg": 200, "speed_mps": 4, "probability": 0.4}],
                   "hold_steps": 3}},
 "wind_primitives": [{"name": "eddy", "start_step": 2, "ramp_steps": 3,
                      "vortex": {"x_m": 117, "y_m": 92, "radius_m": 10, "peak_speed_mps": 4}},
                     {"turbulence": {"amplitude_mps": 1.5, "wavelength_m": 24, "x_m": 60, "y_m": 48,
                      "radius_m": 40, "falloff_m": 12, "period_steps": 16,
                      "drift_m_per_step": 0.5, "drift_direction_deg": 45}}],
 "events": [{"step": 5, "sand": {"x_m": 60, "y_m": 50, "radius_m": 15, "falloff_m": 5, "height": 2}},
            {"step": 9, "wind_primitive": {"end_step": 12, "vortex": {"x_m": 30, "y_m": 2,
             "radius_m": 6, "peak_speed_mps": 3, "rotation": "CLOCKWISE"}}},
            {"step": 22, "remove_wind_primitive": "eddy"},
            {"step": 8, "vegetation": {"x_m": 10, "y_m": 10, "width_m": 20, "height_m": 30, "density": 0.8}},
            {"step": 12, "bedrock": {"x_m": 100, "y_m": 20, "radius_m": 12, "falloff_m": 4, "height": -3}},
            {"step": 15, "wind": {"constant": {"speed_mps": 7, "direction_deg": 120}}},
            {"step": 18, "add_obstacle": {"height_m": 2, "rect": {"x_m": 36, "y_m": 4, "size_x_m": 8, "size_y_m": 3}}},
            {"step": 25, "remove_obstacle": {"disk": {"x_m": 40, "y_m": 48, "radius_m": 3}}}],
 "model": {"abrasion_k": 0.05, "avalanche_iterations": 12, "bedrock_to_sand": true,
           "echo_dunes": true, "echo_reach_m": 16},
 "transport": ")" +
         transport + R"(",
 "run": {"steps": 30, "snapshot_every": 10, "checkpoint_every": 10}})";
}

std::string worker_on(int ranks, const std::string& args) {
  if (ranks == 1) return kWorker + " " + args;
  return kMpirun + " -n " + std::to_string(ranks) + " " + kWorker + " " + args;
}

// Bitwise comparison of two runs' snapshots and checkpoints at the given steps.
void expect_same_runs(const std::string& a, const std::string& b,
                      const std::vector<std::string>& steps, const std::string& what) {
  for (const auto& s : steps) {
    erg::test::expect_same_snapshot(a + "/snapshots/step_" + s + ".h5",
                                    b + "/snapshots/step_" + s + ".h5", what + " step " + s);
    EXPECT_FALSE(
        erg::io::read_snapshot(a + "/snapshots/step_" + s + ".h5")[erg::fields::kObstacles].empty())
        << what << " step " << s << ": no /obstacles";
    const std::string ca = a + "/checkpoints/step_" + s + ".h5",
                      cb = b + "/checkpoints/step_" + s + ".h5";
    if (fs::exists(ca) && fs::exists(cb)) {
      const auto ka = erg::io::read_checkpoint(ca), kb = erg::io::read_checkpoint(cb);
      EXPECT_TRUE(ka.units[erg::fields::kSand] == kb.units[erg::fields::kSand])
          << what << " step " << s << ": sand units";
      EXPECT_TRUE(ka.units[erg::fields::kBedrock] == kb.units[erg::fields::kBedrock])
          << what << " step " << s << ": bedrock units";
      EXPECT_TRUE(ka.units[erg::fields::kAirborne] == kb.units[erg::fields::kAirborne])
          << what << " step " << s << ": airborne units";
      EXPECT_TRUE(ka.reals[erg::fields::kVegetation] == kb.reals[erg::fields::kVegetation])
          << what << " step " << s << ": vegetation";
      EXPECT_TRUE(ka.reals[erg::fields::kObstacles] == kb.reals[erg::fields::kObstacles])
          << what << " step " << s << ": obstacles";
    }
  }
}

class Tiling : public ::testing::TestWithParam<std::string> {};

TEST_P(Tiling, EveryRankCountGivesTheSameBits) {
  TempDir t("erg_tiling");
  write(t / "job.json", job(GetParam()));
  const std::string one = t / "ranks1";
  Result r = run(worker_on(1, (t / "job.json") + " --out " + one + " --quiet --threads 1"));
  ASSERT_EQ(r.code, 0) << r.output;
  for (int ranks : {2, 3, 4, 6}) {
    const std::string dir = t / ("ranks" + std::to_string(ranks));
    r = run(worker_on(ranks, (t / "job.json") + " --out " + dir + " --quiet --threads 1"));
    ASSERT_EQ(r.code, 0) << ranks << " ranks: " << r.output;
    expect_same_runs(one, dir, {"00000000", "00000010", "00000020", "00000030"},
                     GetParam() + " on " + std::to_string(ranks) + " ranks");
  }
  // An explicit, elongated grid too.
  const std::string strips = t / "strips";
  r = run(worker_on(3, (t / "job.json") + " --out " + strips + " --tiles 3x1 --quiet --threads 1"));
  ASSERT_EQ(r.code, 0) << r.output;
  expect_same_runs(one, strips, {"00000030"}, GetParam() + " on 3x1 tiles");
}

INSTANTIATE_TEST_SUITE_P(Transport, Tiling, ::testing::Values("EXPECTED", "STOCHASTIC"));

TEST(Tiling, RestartOnAnotherRankCountContinuesBitwise) {
  TempDir t("erg_tiling");
  write(t / "job.json", job("STOCHASTIC"));
  ASSERT_EQ(run(worker_on(1, (t / "job.json") + " --out " + (t / "straight") + " --quiet")).code,
            0);
  // Written by 4 ranks, resumed on 3, then on 1.
  Result r = run(worker_on(
      4, (t / "job.json") + " --out " + (t / "moved") + " --steps 10 --quiet --threads 1"));
  ASSERT_EQ(r.code, 0) << r.output;
  r = run(worker_on(3, "--resume " + (t / "moved") + " --steps 20 --quiet --threads 1"));
  ASSERT_EQ(r.code, 0) << r.output;
  r = run(worker_on(1, "--resume " + (t / "moved") + " --steps 30 --quiet"));
  ASSERT_EQ(r.code, 0) << r.output;
  expect_same_runs(t / "straight", t / "moved", {"00000020", "00000030"}, "4 -> 3 -> 1 ranks");
}

// Children (ranks) of a process.
std::vector<pid_t> children(pid_t parent) {
  std::vector<pid_t> out;
  for (const auto& e : fs::directory_iterator("/proc")) {
    const std::string name = e.path().filename().string();
    if (name.find_first_not_of("0123456789") != std::string::npos) continue;
    std::ifstream stat(e.path() / "stat");
    std::string line;
    std::getline(stat, line);
    const size_t close = line.rfind(')');
    if (close == std::string::npos) continue;
    std::istringstream rest(line.substr(close + 2));
    char state;
    pid_t ppid = 0;
    rest >> state >> ppid;
    if (ppid == parent) out.push_back(static_cast<pid_t>(std::stol(name)));
  }
  return out;
}

TEST(Tiling, AKilledRankLeavesThePreviousSnapshotAndCheckpointIntact) {
  TempDir t("erg_tiling");
  std::string long_job = job("EXPECTED");
  long_job.replace(long_job.find("\"steps\": 30, \"snapshot_every\": 10, \"checkpoint_every\": 10"),
                   57, "\"steps\": 100000, \"snapshot_every\": 5, \"checkpoint_every\": 5");
  write(t / "job.json", long_job);
  const std::string out = t / "out";
  const pid_t mpirun = ::fork();
  if (mpirun == 0) {
    const std::string cmd =
        "exec " + worker_on(2, (t / "job.json") + " --out " + out + " --quiet --threads 1") +
        " > /dev/null 2>&1";
    ::execl("/bin/sh", "sh", "-c", cmd.c_str(), static_cast<char*>(nullptr));
    _exit(127);
  }
  // Wait for a few snapshots, then kill one rank in the middle of the run.
  for (int i = 0; i < 600 && !fs::exists(out + "/snapshots/step_00000015.h5"); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  ASSERT_TRUE(fs::exists(out + "/snapshots/step_00000015.h5")) << "the run did not get going";
  const auto ranks = children(mpirun);
  ASSERT_FALSE(ranks.empty());
  ::kill(ranks.back(), SIGKILL);
  int status = 0;
  ::waitpid(mpirun, &status, 0);  // mpirun notices and ends the job
  EXPECT_FALSE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "the job went on without a rank";
  // Every file under its final name is complete and readable.
  int checkpoints = 0, snapshots = 0;
  for (const auto& e : fs::directory_iterator(out + "/checkpoints")) {
    if (e.path().string().find(".tmp-") != std::string::npos) continue;
    EXPECT_NO_THROW((void)erg::io::read_checkpoint(e.path().string())) << e.path();
    ++checkpoints;
  }
  for (const auto& e : fs::directory_iterator(out + "/snapshots")) {
    if (e.path().extension() != ".h5") continue;
    EXPECT_NO_THROW((void)erg::io::read_snapshot(e.path().string())) << e.path();
    ++snapshots;
  }
  EXPECT_GE(checkpoints, 1);
  EXPECT_GE(snapshots, 4);
  // And the run continues from the newest one.
  const Result r = run(worker_on(1, "--resume " + out + " --steps 40 --quiet"));
  EXPECT_EQ(r.code, 0) << r.output;
}

// A 60 m sand column in one tile spreads over the others for many rounds of
// avalanching iterations per step while the tiles it has not reached find
// nothing to move: they stop computing but keep refilling with the others
// until every tile has settled (backend/cpu/avalanching.cpp). Same bits.
TEST(Tiling, SettledTilesWaitForASpreadingColumn) {
  TempDir t("erg_tiling");
  write(t / "column.json", R"({"domain": {"nx": 96, "ny": 80, "cell_size_m": 1.0},
 "layers": {"bedrock": {"fbm": {"amplitude": 4, "wavelength_m": 32, "octaves": 3}},
            "sand": {"piles": [{"x_m": 22, "y_m": 20, "height": 60, "radius_m": 6, "shape": "CYLINDER"}]}},
 "wind": {"constant": {"speed_mps": 1, "direction_deg": 30}},
 "model": {"avalanche_iterations": 12, "bedrock_avalanche_iterations": 6, "abrasion_k": 0.05,
           "bedrock_to_sand": true},
 "run": {"steps": 20, "snapshot_every": 10}})");
  Result r = run(worker_on(1, (t / "column.json") + " --out " + (t / "one") + " --quiet"));
  ASSERT_EQ(r.code, 0) << r.output;
  for (const std::string tiles : {"2x2", "1x4"}) {
    const std::string dir = t / tiles;
    r = run(worker_on(
        4, (t / "column.json") + " --out " + dir + " --tiles " + tiles + " --quiet --threads 1"));
    ASSERT_EQ(r.code, 0) << r.output;
    expect_same_runs(t / "one", dir, {"00000010", "00000020"}, "column on " + tiles + " tiles");
  }
  // The column did cross tile edges, and one tile stayed bare (settled from
  // the first iteration of every step: the case this test is for).
  const auto s = erg::io::read_snapshot((t / "one") + "/snapshots/step_00000020.h5");
  int cells[2][2] = {{0, 0}, {0, 0}};
  for (int y = 0; y < 80; ++y)
    for (int x = 0; x < 96; ++x)
      cells[y / 40][x / 48] += s[erg::fields::kSand][static_cast<size_t>(y) * 96 + x] > 0;
  EXPECT_GT(cells[0][1], 0) << "the column did not cross into tile (1, 0)";
  EXPECT_GT(cells[1][0], 0) << "the column did not cross into tile (0, 1)";
  EXPECT_EQ(cells[1][1], 0) << "no tile stayed settled: the test no longer covers waiting tiles";
}

// Avalanching iterates until settled, with the default safety cap: a 10 m
// sand column at 0.5 m cells on the corner of four tiles needs hundreds of
// iterations per step, many later rounds of 46, and the tiles stop together
// when every one has settled. Same bits on 1, 2 and 4 ranks, and no step
// reached the cap.
// The done event of a worker's progress output.
erg::v1::WorkerEvent::Done done_event(const std::string& output) {
  std::istringstream lines(output);
  for (std::string line; std::getline(lines, line);)
    if (const auto ev = erg::job::parse_worker_event(line); ev && ev->has_done()) return ev->done();
  ADD_FAILURE() << "no done event in\n" << output;
  return {};
}

TEST(Tiling, SettlingAColumnAcrossTileCornersGivesTheSameBits) {
  TempDir t("erg_tiling");
  write(t / "settle.json", R"({"domain": {"nx": 200, "ny": 192, "cell_size_m": 0.5},
 "layers": {"sand": {"piles": [{"x_m": 50, "y_m": 48, "height": 10, "radius_m": 6, "shape": "CYLINDER"}]}},
 "wind": {"speed_is": "SHEAR_VELOCITY", "constant": {"speed_mps": 0.31, "direction_deg": 30}},
 "transport": "STOCHASTIC", "seed": 5,
 "model": {"slab_m": 0.05, "reptation_k": 0.2, "avalanche_iterations": 10000},
 "run": {"steps": 4, "snapshot_every": 2}})");
  Result r = run(worker_on(1, (t / "settle.json") + " --out " + (t / "one") + " --progress-fd 1"));
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_EQ(r.output.find("reached model.avalanche_iterations"), std::string::npos) << r.output;
  const auto one = done_event(r.output);
  EXPECT_EQ(one.avalanche_capped_steps(), 0);
  EXPECT_EQ(one.halo_path(), "host");  // the CPU backend: nothing staged
  EXPECT_EQ(one.host_staged_bytes_per_step(), 0);
  EXPECT_GT(one.avalanche_most_iterations(), 4 + 2 * 46) << "too few iterations for later rounds";
  for (const std::string tiles : {"2x1", "2x2"}) {
    const std::string dir = t / tiles;
    const int ranks = tiles == "2x1" ? 2 : 4;
    r = run(worker_on(ranks, (t / "settle.json") + " --out " + dir + " --tiles " + tiles +
                                 " --progress-fd 1 --threads 1"));
    ASSERT_EQ(r.code, 0) << r.output;
    EXPECT_EQ(r.output.find("reached model.avalanche_iterations"), std::string::npos) << r.output;
    const auto done = done_event(r.output);
    EXPECT_EQ(done.avalanche_capped_steps(), 0) << tiles;
    EXPECT_EQ(done.halo_path(), "host") << tiles;
    EXPECT_EQ(done.host_staged_bytes_per_step(), 0) << tiles;
    expect_same_runs(t / "one", dir, {"00000002", "00000004"}, "settling on " + tiles + " tiles");
  }
}

// The exchange rounds per step must not grow with the number of
// avalanching iterations. The column keeps sand moving through every
// iteration of the first steps, so N = 12 and N = 48 both use the second,
// wider round; refills every 4 iterations would send several times the
// messages at N = 48.
// The wind warping's coarse halo (102 coarse cells of 4 m at the default
// radii) is wider than every tile and than the torus itself (64 x 48 coarse
// cells): every tile gathers its window from the tiles that cover it,
// several times around the torus. 1, 2, 4, 8 and 16 ranks give the same bits.
TEST(Tiling, WindWarpingGivesTheSameBitsOnOneToSixteenRanks) {
  TempDir t("erg_tiling");
  write(t / "relief.json", R"({"domain": {"nx": 256, "ny": 192, "cell_size_m": 1.0},
 "layers": {"bedrock": {"fbm": {"amplitude": 8, "wavelength_m": 96, "octaves": 3}},
            "sand": {"patches": {"coverage": 0.5, "radius_m": 10, "height": 2, "falloff_m": 4}}},
 "wind": {"constant": {"speed_mps": 6, "direction_deg": 25}},
 "model": {"avalanche_iterations": 12},
 "run": {"steps": 6, "snapshot_every": 3}})");
  const std::string one = t / "ranks1";
  Result r = run(worker_on(1, (t / "relief.json") + " --out " + one + " --quiet --threads 1"));
  ASSERT_EQ(r.code, 0) << r.output;
  for (int ranks : {2, 4, 8, 16}) {
    const std::string dir = t / ("ranks" + std::to_string(ranks));
    r = run(worker_on(ranks, (t / "relief.json") + " --out " + dir + " --quiet --threads 1"));
    ASSERT_EQ(r.code, 0) << ranks << " ranks: " << r.output;
    expect_same_runs(one, dir, {"00000003", "00000006"}, std::to_string(ranks) + " ranks");
  }
}

// The shear stress over relief of the physical modes (stages/shear_stress.h)
// is computed on the same coarse window, its kernel (100 m: 25 coarse cells)
// inside the coarse halo, wider than the torus (32 x 24 coarse cells): 1, 2
// and 6 ranks give the same bits, with the wind at 25 degrees (a kernel with
// no symmetry of the grid).
// A job run on 1 rank (2 threads) and on 2 and 6 ranks (1 thread): the same
// snapshots at steps 3 and 6.
void expect_same_bits_on_one_to_six_ranks(const std::string& job) {
  TempDir t("erg_tiling");
  write(t / "job.json", job);
  const std::string one = t / "ranks1";
  Result r = run(worker_on(1, (t / "job.json") + " --out " + one + " --quiet --threads 2"));
  ASSERT_EQ(r.code, 0) << r.output;
  for (int ranks : {2, 6}) {
    const std::string dir = t / ("ranks" + std::to_string(ranks));
    r = run(worker_on(ranks, (t / "job.json") + " --out " + dir + " --quiet --threads 1"));
    ASSERT_EQ(r.code, 0) << ranks << " ranks: " << r.output;
    expect_same_runs(one, dir, {"00000003", "00000006"}, std::to_string(ranks) + " ranks");
  }
}

TEST(Tiling, ShearStressGivesTheSameBitsOnOneToSixRanks) {
  expect_same_bits_on_one_to_six_ranks(R"({"domain": {"nx": 128, "ny": 96, "cell_size_m": 1.0},
 "layers": {"bedrock": {"fbm": {"amplitude": 4, "wavelength_m": 64, "octaves": 3}},
            "sand": {"patches": {"coverage": 0.5, "radius_m": 10, "height": 3, "falloff_m": 5}}},
 "wind": {"speed_is": "SHEAR_VELOCITY", "constant": {"speed_mps": 0.31, "direction_deg": 25}},
 "transport": "STOCHASTIC", "model": {"slab_m": 0.05, "avalanche_iterations": 12},
 "physics": {"shear_stress_a": 3, "shear_stress_b": 1},
 "run": {"steps": 6, "snapshot_every": 3}})");
}

// The hop turned down the slope (physics.hop_slope_deflection) reads the
// heights' ghosts one cell out: in the expected mode's vectorised scatter
// (no obstacles) and the stochastic mode's plain one (an obstacle counted
// level), steep sand patches under a wind at 25 degrees give the same bits
// on 1, 2 and 6 ranks.
TEST(Tiling, HopSlopeDeflectionGivesTheSameBitsOnOneToSixRanks) {
  for (const std::string transport : {"EXPECTED", "STOCHASTIC"}) {
    SCOPED_TRACE(transport);
    const std::string obstacle =
        transport == "STOCHASTIC"
            ? R"(, "obstacles": {"shapes": [{"height_m": 3, "disk": {"x_m": 60, "y_m": 40, "radius_m": 6}}]})"
            : "";
    expect_same_bits_on_one_to_six_ranks(R"({"domain": {"nx": 128, "ny": 96, "cell_size_m": 1.0},
 "layers": {"sand": {"patches": {"coverage": 0.5, "radius_m": 8, "height": 5, "falloff_m": 3}})" +
                                         obstacle + R"(},
 "wind": {"speed_is": "SHEAR_VELOCITY", "constant": {"speed_mps": 0.45, "direction_deg": 25}},
 "transport": ")" + transport + R"(", "model": {"slab_m": 0.05, "avalanche_iterations": 12},
 "physics": {"hop_slope_deflection": 0.34},
 "run": {"steps": 6, "snapshot_every": 3}})");
  }
}

// The shadow's cubic samples read two cells past the march (its halo) and
// the isotropic repose has each receiver recompute its donors' tangents from
// their 3 x 3 heights (two cells from the receiver, at the edge of each
// avalanching iteration's grown tile): steep sand patches (above repose, so
// that every step avalanches in both rounds of its 12 iterations, 4 and 8)
// under a wind at 25 degrees give the same bits on 1, 2 and 6 ranks.
TEST(Tiling, CubicShadowAndIsotropicReposeGiveTheSameBitsOnOneToSixRanks) {
  expect_same_bits_on_one_to_six_ranks(R"({"domain": {"nx": 128, "ny": 96, "cell_size_m": 1.0},
 "layers": {"sand": {"patches": {"coverage": 0.5, "radius_m": 8, "height": 6, "falloff_m": 2}}},
 "wind": {"constant": {"speed_mps": 5, "direction_deg": 25}},
 "transport": "STOCHASTIC",
 "model": {"slab_m": 0.2, "shadow_sampling": "CUBIC", "repose": "ISOTROPIC",
           "avalanche_iterations": 12},
 "run": {"steps": 6, "snapshot_every": 3}})");
}

// halo_messages_per_step of the worker's done event (the most any rank sent).
double halo_messages_per_step(const std::string& output) {
  std::istringstream lines(output);
  for (std::string line; std::getline(lines, line);)
    if (const auto ev = erg::job::parse_worker_event(line); ev && ev->has_done())
      return static_cast<double>(ev->done().halo_messages_per_step());
  ADD_FAILURE() << "no done event in\n" << output;
  return 0.0;
}

// The exchanges of a step are the ones Simulation::step lists: on a terrain
// where nothing avalanches, the heights (before the shadow), the landed sand
// (summed back) and sand, bedrock and impact strengths together (before
// reptation), each one message per neighbour and phase: 3 x 4 per rank and
// step, where one message per field and exchange made 5 x 4; plus the wind
// warping's coarse window, one message to each other tile it needs (here
// the one other tile: 13).
TEST(Tiling, AStepSendsOneMessagePerNeighbourForEachExchangeItLists) {
  TempDir t("erg_tiling");
  write(t / "flat.json", R"({"domain": {"nx": 192, "ny": 96, "cell_size_m": 1.0},
 "layers": {"sand": {"constant": 1}}, "wind": {"constant": {"speed_mps": 6}},
 "run": {"steps": 10, "snapshot_every": 0}})");
  const Result r = run(
      worker_on(2, (t / "flat.json") + " --out " + (t / "flat") + " --progress-fd 1 --threads 1"));
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_EQ(halo_messages_per_step(r.output), 13.0) << r.output;
}

TEST(Tiling, HaloMessagesDoNotGrowWithAvalancheIterations) {
  TempDir t("erg_tiling");
  auto messages = [&](int iterations) {
    const std::string name = "n" + std::to_string(iterations);
    write(t / (name + ".json"),
          R"({"domain": {"nx": 192, "ny": 192, "cell_size_m": 1.0},
 "layers": {"sand": {"piles": [{"x_m": 96, "y_m": 96, "height": 80, "radius_m": 8, "shape": "CYLINDER"}]}},
 "wind": {"constant": {"speed_mps": 1, "direction_deg": 0}},
 "model": {"avalanche_iterations": )" +
              std::to_string(iterations) + R"(}, "run": {"steps": 10, "snapshot_every": 0}})");
    const Result r = run(worker_on(
        2, (t / (name + ".json")) + " --out " + (t / name) + " --progress-fd 1 --threads 1"));
    EXPECT_EQ(r.code, 0) << r.output;
    return halo_messages_per_step(r.output);
  };
  const double few = messages(12), many = messages(48);
  EXPECT_GT(few, 0);
  EXPECT_LE(many, few * 1.05) << "messages per step grow with the avalanching iterations: " << few
                              << " at N = 12, " << many << " at N = 48";
}

TEST(Tiling, BadTileGridsAreRefusedOnEveryRank) {
  TempDir t("erg_tiling");
  write(t / "job.json", job("EXPECTED"));
  Result r = run(worker_on(4, (t / "job.json") + " --out " + (t / "a") + " --tiles 3x2 --quiet"));
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("has 6 tiles but there are 4 ranks"), std::string::npos) << r.output;
  // 32 rows in 4 tiles of 8, narrower than the halo (9 avalanching cells
  // and one for reptation at least).
  // (A job of its own: the full tiling job's wind primitives do not fit 32 rows.)
  write(t / "narrow.json", R"({"domain": {"nx": 120, "ny": 32, "cell_size_m": 1.0},
      "layers": {"sand": {"constant": 1}}, "wind": {"constant": {"speed_mps": 6}},
      "run": {"steps": 2}})");
  r = run(worker_on(4, (t / "narrow.json") + " --out " + (t / "b") + " --tiles 1x4 --quiet"));
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("(the widest halo)"), std::string::npos) << r.output;
}

TEST(Tiling, ErgRunStartsRanksAndReportsHaloTraffic) {
  TempDir t("erg_tiling");
  write(t / "job.json", job("EXPECTED"));
  Result r = run(kErg + " run " + (t / "job.json") + " --out " + (t / "one"));
  ASSERT_EQ(r.code, 0) << r.output;
  r = run(kErg + " run " + (t / "job.json") + " --out " + (t / "two") + " --ranks 2");
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("2 rank(s) as 2x1 tiles"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("halo exchange:"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("bytes per cell (peak resident, all ranks:"), std::string::npos)
      << r.output;
  expect_same_runs(t / "one", t / "two", {"00000030"}, "erg run --ranks 2");
}

// Many ranks on small tiles (oversubscribed on the test machine): 16, 32 and
// 64 ranks give the bits of one rank, overview pyramid included, and every
// rank sends the same number of halo messages per step at every rank count:
// each tile has eight distinct neighbours, and the wind warping's coarse
// window (small radii here) lies within them. A rank's traffic per step
// does not grow with the number of ranks.
class ManyRanks : public ::testing::TestWithParam<int> {};

// Measured: 12 for the ghosts (three exchanges of 4 messages each:
// x then y, the corners carried by the second) and 8 for the coarse wind
// window, one to each neighbour; the same on 16 (4 x 4 tiles), 32 (8 x 4)
// and 64 (8 x 8) ranks.
constexpr long long kManyRanksMessagesPerStep = 20;

TEST_P(ManyRanks, GiveTheBitsOfOneRankAndTheSameMessagesPerRank) {
  const int ranks = GetParam();
  TempDir t("erg_tiling");
  write(t / "small.json", R"({"domain": {"nx": 128, "ny": 128, "cell_size_m": 2.0},
 "layers": {"bedrock": {"fbm": {"amplitude": 2, "wavelength_m": 64, "octaves": 2}},
            "sand": {"patches": {"coverage": 0.5, "radius_m": 12, "height": 2, "falloff_m": 4}},
            "vegetation": {"fbm": {"amplitude": 0.4, "offset": 0.1, "wavelength_m": 64, "octaves": 2}}},
 "wind": {"constant": {"speed_mps": 6, "direction_deg": 25}},
 "model": {"avalanche_iterations": 4, "warp_large_radius_m": 4, "warp_small_radius_m": 2},
 "run": {"steps": 3, "snapshot_every": 3, "checkpoint_every": 0}})");
  const std::string one = t / "ranks1";
  Result r = run(worker_on(1, (t / "small.json") + " --out " + one + " --quiet --threads 1"));
  ASSERT_EQ(r.code, 0) << r.output;
  const std::string dir = t / ("ranks" + std::to_string(ranks));
  const auto t0 = std::chrono::steady_clock::now();
  r = run(worker_on(ranks, (t / "small.json") + " --out " + dir + " --progress-fd 1 --threads 1"));
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  ASSERT_EQ(r.code, 0) << ranks << " ranks: " << r.output;
  expect_same_runs(one, dir, {"00000000", "00000003"}, std::to_string(ranks) + " ranks");
  const auto done = done_event(r.output);
  EXPECT_EQ(done.halo_messages_per_step(), done.halo_messages_min_rank_per_step())
      << ranks << " ranks: ranks send different numbers of messages";
  if (kManyRanksMessagesPerStep > 0) {
    EXPECT_EQ(done.halo_messages_per_step(), kManyRanksMessagesPerStep) << ranks << " ranks";
  }
  std::cout << "[ many ranks ] " << ranks << " ranks: " << wall << " s wall, "
            << done.halo_messages_per_step() << " messages and " << done.halo_bytes_per_step()
            << " bytes per rank and step; busy ms per step: rank 0 " << done.step_ms_rank0()
            << ", median rank " << done.step_ms_median_rank() << "\n";
}

INSTANTIATE_TEST_SUITE_P(Ranks, ManyRanks, ::testing::Values(16, 32, 64));

// Width and height of a PNG (its IHDR chunk).
std::array<int, 2> png_size(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  unsigned char h[24] = {};
  f.read(reinterpret_cast<char*>(h), sizeof h);
  const auto be = [&](int at) {
    return (h[at] << 24) | (h[at + 1] << 16) | (h[at + 2] << 8) | h[at + 3];
  };
  return {be(16), be(20)};
}

// A domain wider than a preview: the preview is drawn from the overview
// level that fits (level 2 here: 4112 cells -> 1028 blocks), the same on one
// rank and on two, and the pyramid's blocks are the means of their cells.
TEST(Tiling, PreviewsOfLargeDomainsComeFromTheOverviewPyramid) {
  TempDir t("erg_tiling");
  write(t / "wide.json", R"({"domain": {"nx": 4112, "ny": 48, "cell_size_m": 1.0},
 "layers": {"sand": {"patches": {"coverage": 0.5, "radius_m": 8, "height": 2, "falloff_m": 3}},
            "vegetation": {"fbm": {"amplitude": 0.4, "offset": 0.1, "wavelength_m": 40, "octaves": 2}}},
 "wind": {"constant": {"speed_mps": 6, "direction_deg": 25}},
 "model": {"avalanche_iterations": 4, "warp_large_radius_m": 8, "warp_small_radius_m": 4},
 "run": {"steps": 1, "snapshot_every": 1}})");
  for (const int ranks : {1, 2}) {
    const std::string dir = t / ("ranks" + std::to_string(ranks));
    const Result r =
        run(worker_on(ranks, (t / "wide.json") + " --out " + dir + " --quiet --threads 1"));
    ASSERT_EQ(r.code, 0) << r.output;
  }
  const std::string a = t / "ranks1", b = t / "ranks2";
  erg::test::expect_same_snapshot(a + "/snapshots/step_00000001.h5",
                                  b + "/snapshots/step_00000001.h5", "1 and 2 ranks");
  const std::string pa = a + "/previews/step_00000001.png", pb = b + "/previews/step_00000001.png";
  EXPECT_EQ(png_size(pa)[0], 1028);
  std::ifstream fa(pa, std::ios::binary), fb(pb, std::ios::binary);
  const std::string ba((std::istreambuf_iterator<char>(fa)), {}),
      bb((std::istreambuf_iterator<char>(fb)), {});
  EXPECT_FALSE(ba.empty());
  EXPECT_TRUE(ba == bb) << "the previews of 1 and 2 ranks differ";
  // Every block of level 1 and of level 3 is the mean of its cells.
  const auto s = erg::io::read_snapshot(a + "/snapshots/step_00000001.h5");
  EXPECT_EQ(erg::io::overview_levels(4112, 48), 13);
  for (const int level : {1, 3}) {
    const auto l = erg::io::read_overview_level(a + "/snapshots/step_00000001.h5", level);
    const int k = 1 << level;
    ASSERT_EQ(l.nx, (4112 + k - 1) / k);
    ASSERT_EQ(l.ny, 48 / k);
    for (int by = 0; by < l.ny; ++by)
      for (int bx = 0; bx < l.nx; ++bx) {
        double sand = 0, veg = 0;
        int n = 0;
        for (int y = by * k; y < std::min(48, (by + 1) * k); ++y)
          for (int x = bx * k; x < std::min(4112, (bx + 1) * k); ++x, ++n) {
            sand += s[erg::fields::kSand][static_cast<std::size_t>(y) * 4112 + x];
            veg += s[erg::fields::kVegetation][static_cast<std::size_t>(y) * 4112 + x];
          }
        const std::size_t i = static_cast<std::size_t>(by) * l.nx + bx;
        ASSERT_NEAR(l.sand[i], sand / n, 1e-6 * (1 + sand / n))
            << level << ": " << bx << ", " << by;
        ASSERT_NEAR(l.vegetation[i], veg / n, 1e-6) << level << ": " << bx << ", " << by;
      }
  }
}

}  // namespace

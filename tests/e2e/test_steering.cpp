// SPDX-License-Identifier: Apache-2.0
// Steering a running worker (erg-worker --steer-dir DIR, used by ergd's
// SteerJob): events dropped into DIR as NAME.json apply at the next step
// boundary and are renamed NAME.applied, bad ones NAME.rejected, each with a
// progress event; DIR_OUT/job.json records them at the step they took effect,
// so re-running it reproduces the steered run bitwise, on any number of
// ranks, and a resume from a checkpoint older than the steering re-applies
// them.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>
#include <vector>

#include "../common/same_snapshots.h"
#include "../common/temp_dir.h"
#include "io/io.h"
#include "job/spec.h"
#include "job/worker_event.h"
#include "stages/events.h"

namespace fs = std::filesystem;

namespace {

using TempDir = erg::test_support::TempDir;

const std::string kWorker = ERG_WORKER_BIN;
// As in test_tiling.cpp: as root, Open MPI wants to be told.
const std::string kMpirun =
    std::string(ERG_MPIEXEC) + " --allow-run-as-root --oversubscribe --bind-to none";

struct Result {
  int code;
  std::string output;  // stdout (progress events with --progress-fd 1) and stderr
};

// Runs `cmd` under sh; on_line sees every output line as it comes, with the
// pid of the process that runs it (the worker, or mpirun).
Result run(const std::string& cmd,
           const std::function<void(const std::string&, pid_t)>& on_line = nullptr) {
  int fds[2];
  if (::pipe(fds) != 0) return {-1, ""};
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::dup2(fds[1], 1);
    ::dup2(fds[1], 2);
    ::close(fds[0]);
    ::close(fds[1]);
    const std::string exec = "exec " + cmd;
    ::execl("/bin/sh", "sh", "-c", exec.c_str(), static_cast<char*>(nullptr));
    _exit(127);
  }
  ::close(fds[1]);
  std::string out, pending;
  std::array<char, 4096> buf{};
  for (;;) {
    const ssize_t n = ::read(fds[0], buf.data(), buf.size());
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    out.append(buf.data(), static_cast<size_t>(n));
    pending.append(buf.data(), static_cast<size_t>(n));
    for (size_t nl; (nl = pending.find('\n')) != std::string::npos; pending.erase(0, nl + 1))
      if (on_line) on_line(pending.substr(0, nl), pid);
  }
  ::close(fds[0]);
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  return {WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status), out};
}

void write(const std::string& path, const std::string& text) {
  std::ofstream o(path);
  o << text;
}

// What a steering client does: write elsewhere, then rename into place.
void drop(const std::string& dir, const std::string& name, const std::string& text) {
  write(dir + "/" + name + ".tmp", text);
  fs::rename(dir + "/" + name + ".tmp", dir + "/" + name);
}

// Stochastic transport, an event of the job's own at step 0 (steering at
// step 0 comes after it), previews off to keep it quick.
std::string job(int steps, int snapshot_every) {
  return R"({"domain": {"nx": 64, "ny": 64, "cell_size_m": 1.0},
 "layers": {"bedrock": {"fbm": {"amplitude": 1, "wavelength_m": 32, "octaves": 2}},
            "sand": {"patches": {"coverage": 0.3, "radius_m": 6, "height": 2, "falloff_m": 2}}},
 "wind": {"constant": {"speed_mps": 5, "direction_deg": 20}},
 "events": [{"step": 0, "sand": {"x_m": 16, "y_m": 16, "radius_m": 5, "height": 1}}],
 "model": {"avalanche_iterations": 12}, "transport": "STOCHASTIC", "seed": 11,
 "run": {"steps": )" +
         std::to_string(steps) + R"(, "snapshot_every": )" + std::to_string(snapshot_every) +
         R"(, "checkpoint_every": 20, "previews": false}})";
}

const char* kBrushA =
    R"({"sand": {"x_m": 20, "y_m": 40, "radius_m": 6, "falloff_m": 2, "height": 1.5}})";
const char* kWindB =
    R"({"step": 999, "wind": {"constant": {"speed_mps": 7, "direction_deg": 100}}})";
const char* kBrushC =
    R"({"sand": {"x_m": 50, "y_m": 10, "radius_m": 5, "falloff_m": 1, "height": 2}})";

// Units a sand brush adds to a 64 x 64 torus of 1 m cells (none removed).
long long brush_units(double x, double y, double r, double falloff, double h) {
  const erg::events::Brush b{x, y, r, falloff, h, 64.0, 64.0};
  long long sum = 0;
  for (int cy = 0; cy < 64; ++cy)
    for (int cx = 0; cx < 64; ++cx) sum += erg::events::brush_units(b, cx + 0.5, cy + 0.5);
  return sum;
}

using Kind = erg::v1::WorkerEvent::KindCase;

// The events of one kind in a run's output (erg.v1.WorkerEvent lines), in
// order.
std::vector<erg::v1::WorkerEvent> events_of(const std::string& output, Kind kind) {
  std::vector<erg::v1::WorkerEvent> out;
  std::istringstream in(output);
  for (std::string line; std::getline(in, line);)
    if (const auto ev = erg::job::parse_worker_event(line); ev && ev->kind_case() == kind)
      out.push_back(*ev);
  return out;
}
// Whether an output line is the event of the snapshot at `step`.
bool is_snapshot(const std::string& line, long long step) {
  const auto ev = erg::job::parse_worker_event(line);
  return ev && ev->has_snapshot() && ev->step() == step;
}

long long total_sand(const std::string& snapshot) {
  const auto s = erg::io::read_snapshot(snapshot);
  return std::stoll(s.meta.sand_units_total) + std::stoll(s.meta.airborne_units_total);
}

erg::v1::JobSpec recorded_job(const std::string& out) {
  std::ifstream in(out + "/job.json");
  std::stringstream ss;
  ss << in.rdbuf();
  erg::v1::JobSpec spec = erg::job::parse_json(ss.str(), out + "/job.json");
  erg::job::apply_defaults(spec);
  return spec;
}

void expect_same_snapshots(const std::string& a, const std::string& b,
                           const std::vector<std::string>& steps, const std::string& what) {
  for (const auto& s : steps) {
    erg::test::expect_same_snapshot(a + "/snapshots/step_" + s + ".h5",
                                    b + "/snapshots/step_" + s + ".h5", what + " step " + s);
  }
}

const std::vector<std::string> kSteps60 = {"00000000", "00000020", "00000040", "00000060"};

TEST(Steering, AppliedEventsAreRecordedAndReplayBitwise) {
  TempDir t("erg_steer");
  write(t / "job.json", job(60, 20));
  const std::string steer = t / "steer";
  fs::create_directories(steer);
  Result r =
      run(kWorker + " " + (t / "job.json") + " --out " + (t / "plain") + " --quiet --threads 1");
  ASSERT_EQ(r.code, 0) << r.output;

  // Two events waiting before the run starts (applied at step 0, after the
  // job's own), one dropped while it runs (the worker held still meanwhile).
  drop(steer, "a.json", kBrushA);
  drop(steer, "b.json", kWindB);
  r = run(kWorker + " " + (t / "job.json") + " --out " + (t / "steered") + " --steer-dir " + steer +
              " --progress-fd 1 --threads 1",
          [&](const std::string& line, pid_t pid) {
            if (!is_snapshot(line, 20)) return;
            ::kill(pid, SIGSTOP);
            drop(steer, "c.json", kBrushC);
            ::kill(pid, SIGCONT);
          });
  ASSERT_EQ(r.code, 0) << r.output;
  for (const char* name : {"a", "b", "c"}) {
    EXPECT_TRUE(fs::exists(steer + "/" + name + ".applied")) << name << "\n" << r.output;
    EXPECT_FALSE(fs::exists(steer + "/" + name + ".json")) << name;
  }
  const auto steered = events_of(r.output, Kind::kSteered);
  ASSERT_EQ(steered.size(), 3u) << r.output;
  EXPECT_EQ(steered[0].step(), 0);
  EXPECT_EQ(steered[0].steered().file(), "a.json");
  EXPECT_EQ(steered[0].steered().event().step(), 0);
  EXPECT_TRUE(steered[0].steered().event().has_sand()) << steered[0].DebugString();
  EXPECT_EQ(steered[1].step(), 0);
  EXPECT_EQ(steered[1].steered().file(), "b.json");
  EXPECT_EQ(steered[1].steered().event().wind().constant().speed_mps(), 7)
      << steered[1].DebugString();
  EXPECT_EQ(steered[1].steered().event().wind().constant().direction_deg(), 100);
  const long long s = steered[2].step();
  EXPECT_GE(s, 20) << steered[2].DebugString();
  EXPECT_LT(s, 60) << steered[2].DebugString();
  EXPECT_EQ(steered[2].steered().file(), "c.json");

  // The recorded job: the job's own event, then the three at their steps.
  const erg::v1::JobSpec spec = recorded_job(t / "steered");
  ASSERT_EQ(spec.events_size(), 4);
  EXPECT_EQ(spec.events(0).step(), 0);
  EXPECT_EQ(spec.events(0).sand().x_m(), 16);
  EXPECT_EQ(spec.events(1).step(), 0);
  EXPECT_EQ(spec.events(1).sand().x_m(), 20);
  EXPECT_EQ(spec.events(1).sand().height(), 1.5);
  EXPECT_EQ(spec.events(2).step(), 0);  // the file's step 999 is the next boundary's
  EXPECT_EQ(spec.events(2).wind().constant().direction_deg(), 100);
  EXPECT_EQ(spec.events(3).step(), s);
  EXPECT_EQ(spec.events(3).sand().y_m(), 10);
  // The final checkpoint carries them too.
  const auto ckpt = erg::io::read_checkpoint(t / "steered/checkpoints/step_00000060.h5");
  EXPECT_NE(ckpt.job_spec_json.find("\"direction_deg\": 100"), std::string::npos);

  // Exactly the brushes' sand more than without steering; another wind.
  const std::string last = "/snapshots/step_00000060.h5";
  EXPECT_EQ(total_sand(t / "steered" + last) - total_sand(t / "plain" + last),
            brush_units(20, 40, 6, 2, 1.5) + brush_units(50, 10, 5, 1, 2));
  EXPECT_FALSE(erg::io::read_snapshot(t / "steered" + last).wind ==
               erg::io::read_snapshot(t / "plain" + last).wind);

  // The recorded job, run as any job, gives the same bits.
  r = run(kWorker + " " + (t / "steered/job.json") + " --out " + (t / "replay") +
          " --quiet --threads 1");
  ASSERT_EQ(r.code, 0) << r.output;
  expect_same_snapshots(t / "steered", t / "replay", kSteps60, "replay of the recorded job");
}

TEST(Steering, BadEventsAreRejectedAndTheRunGoesOn) {
  TempDir t("erg_steer");
  write(t / "job.json", job(60, 20));
  const std::string steer = t / "steer";
  fs::create_directories(steer);
  drop(steer, "bad.json", R"({"vegetation": {"x_m": 3, "y_m": 3, "radius_m": 4, "density": 5}})");
  drop(steer, "typo.json", R"({"sand": {"x_m": 3, "y_m": 3, "radius_m": 4, "hieght": 1}})");
  write(steer + "/later.json.tmp", kBrushA);  // still being written: left alone
  write(steer + "/notes.txt", "not an event");
  Result r = run(kWorker + " " + (t / "job.json") + " --out " + (t / "out") + " --steer-dir " +
                 steer + " --progress-fd 1 --threads 1");
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_TRUE(fs::exists(steer + "/bad.rejected"));
  EXPECT_TRUE(fs::exists(steer + "/typo.rejected"));
  EXPECT_TRUE(fs::exists(steer + "/later.json.tmp"));
  EXPECT_TRUE(fs::exists(steer + "/notes.txt"));
  EXPECT_TRUE(events_of(r.output, Kind::kSteered).empty()) << r.output;
  const auto rejected = events_of(r.output, Kind::kSteerRejected);
  ASSERT_EQ(rejected.size(), 2u) << r.output;
  EXPECT_EQ(rejected[0].steer_rejected().file(), "bad.json");
  EXPECT_NE(rejected[0].steer_rejected().reason().find(
                "event.vegetation.density = 5 is out of range; allowed [0, 1]"),
            std::string::npos)
      << rejected[0].DebugString();
  EXPECT_EQ(rejected[1].steer_rejected().file(), "typo.json");
  EXPECT_NE(rejected[1].steer_rejected().reason().find("hieght"), std::string::npos)
      << rejected[1].DebugString();
  EXPECT_EQ(recorded_job(t / "out").events_size(), 1);
  // Nothing changed: the same bits as a run without --steer-dir.
  r = run(kWorker + " " + (t / "job.json") + " --out " + (t / "plain") + " --quiet --threads 1");
  ASSERT_EQ(r.code, 0) << r.output;
  expect_same_snapshots(t / "out", t / "plain", {"00000060"}, "rejected steering");
}

// Wind primitives [P19 4.4] by steering: a vortex added before the run, one
// removal of a name that does not exist rejected, the vortex removed while
// the run goes on; the recorded job replays to the same bits.
TEST(Steering, WindPrimitivesAreAddedAndRemoved) {
  TempDir t("erg_steer");
  write(t / "job.json", job(60, 20));
  const std::string steer = t / "steer";
  fs::create_directories(steer);
  Result r =
      run(kWorker + " " + (t / "job.json") + " --out " + (t / "plain") + " --quiet --threads 1");
  ASSERT_EQ(r.code, 0) << r.output;
  drop(steer, "a.json", R"({"wind_primitive": {"name": "eddy", "vortex": {"x_m": 32, "y_m": 32,
      "radius_m": 10, "peak_speed_mps": 4, "rotation": "CLOCKWISE"}}})");
  drop(steer, "b.json", R"({"remove_wind_primitive": "gust"})");
  r = run(kWorker + " " + (t / "job.json") + " --out " + (t / "steered") + " --steer-dir " + steer +
              " --progress-fd 1 --threads 1",
          [&](const std::string& line, pid_t pid) {
            if (!is_snapshot(line, 20)) return;
            ::kill(pid, SIGSTOP);
            drop(steer, "c.json", R"({"remove_wind_primitive": "eddy"})");
            ::kill(pid, SIGCONT);
          });
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_TRUE(fs::exists(steer + "/a.applied")) << r.output;
  EXPECT_TRUE(fs::exists(steer + "/b.rejected")) << r.output;
  EXPECT_TRUE(fs::exists(steer + "/c.applied")) << r.output;
  const auto rejected = events_of(r.output, Kind::kSteerRejected);
  ASSERT_EQ(rejected.size(), 1u) << r.output;
  EXPECT_NE(rejected[0].steer_rejected().reason().find(
                "event.remove_wind_primitive = \"gust\" names no wind primitive"),
            std::string::npos)
      << rejected[0].DebugString();
  const erg::v1::JobSpec spec = recorded_job(t / "steered");
  ASSERT_EQ(spec.events_size(), 3);
  EXPECT_EQ(spec.events(1).step(), 0);
  EXPECT_EQ(spec.events(1).wind_primitive().name(), "eddy");
  EXPECT_EQ(spec.events(1).wind_primitive().vortex().rotation(), erg::v1::Vortex::CLOCKWISE);
  EXPECT_GE(spec.events(2).step(), 20);
  EXPECT_EQ(spec.events(2).remove_wind_primitive(), "eddy");
  // The vortex blew: the wind of step 20 differs from the plain run's.
  EXPECT_FALSE(erg::io::read_snapshot(t / "steered/snapshots/step_00000020.h5").wind ==
               erg::io::read_snapshot(t / "plain/snapshots/step_00000020.h5").wind);
  r = run(kWorker + " " + (t / "steered/job.json") + " --out " + (t / "replay") +
          " --quiet --threads 1");
  ASSERT_EQ(r.code, 0) << r.output;
  expect_same_snapshots(t / "steered", t / "replay", kSteps60, "replay of the recorded job");
}

// A run resumed from a checkpoint written before a steering event takes the
// event from DIR/job.json and applies it again at its step.
TEST(Steering, ResumeFromAnOlderCheckpointReappliesRecordedEvents) {
  TempDir t("erg_steer");
  write(t / "job.json", job(60, 20));
  const std::string steer = t / "steer", out = t / "out", redo = t / "redo";
  fs::create_directories(steer);
  Result r =
      run(kWorker + " " + (t / "job.json") + " --out " + out + " --steps 30 --quiet --threads 1");
  ASSERT_EQ(r.code, 0) << r.output;
  fs::create_directories(redo + "/checkpoints");
  fs::copy_file(out + "/checkpoints/step_00000020.h5", redo + "/checkpoints/step_00000020.h5");
  drop(steer, "a.json", kBrushA);
  r = run(kWorker + " --resume " + out + " --steps 60 --steer-dir " + steer +
          " --progress-fd 1 --threads 1");
  ASSERT_EQ(r.code, 0) << r.output;
  const auto steered = events_of(r.output, Kind::kSteered);
  ASSERT_EQ(steered.size(), 1u) << r.output;
  EXPECT_EQ(steered[0].step(), 30);
  // The checkpoint at 20 lacks the event; job.json has it at step 30.
  fs::copy_file(out + "/job.json", redo + "/job.json");
  r = run(kWorker + " --resume " + redo + " --steps 60 --quiet --threads 1");
  ASSERT_EQ(r.code, 0) << r.output;
  expect_same_snapshots(out, redo, {"00000040", "00000060"}, "resumed from step 20");
  // And the recorded job from scratch.
  r = run(kWorker + " " + (out + "/job.json") + " --out " + (t / "replay") +
          " --quiet --threads 1");
  ASSERT_EQ(r.code, 0) << r.output;
  expect_same_snapshots(out, t / "replay", {"00000040", "00000060"}, "replay");
}

TEST(Steering, TwoRanksGiveTheSameBitsAsOne) {
  TempDir t("erg_steer");
  write(t / "job.json", job(120, 40));
  const std::string steer = t / "steer";
  fs::create_directories(steer);
  drop(steer, "a.json", kBrushA);
  drop(steer, "b.json", kWindB);
  bool dropped = false;
  Result r = run(kMpirun + " -n 2 " + kWorker + " " + (t / "job.json") + " --out " + (t / "two") +
                     " --steer-dir " + steer + " --progress-fd 1 --threads 1",
                 [&](const std::string& line, pid_t) {
                   if (dropped) return;
                   const auto ev = erg::job::parse_worker_event(line);
                   if (!ev || !ev->has_steered()) return;
                   drop(steer, "c.json", kBrushC);  // while it runs
                   dropped = true;
                 });
  ASSERT_EQ(r.code, 0) << r.output;
  const auto steered = events_of(r.output, Kind::kSteered);
  ASSERT_EQ(steered.size(), 3u) << "the run ended before the file dropped while it ran\n"
                                << r.output;
  EXPECT_EQ(steered[0].step(), 0);
  EXPECT_EQ(steered[1].step(), 0);
  EXPECT_GT(steered[2].step(), 0);
  EXPECT_EQ(recorded_job(t / "two").events_size(), 4);
  // One rank running the recorded job.
  r = run(kWorker + " " + (t / "two/job.json") + " --out " + (t / "one") + " --quiet --threads 1");
  ASSERT_EQ(r.code, 0) << r.output;
  expect_same_snapshots(t / "two", t / "one", {"00000040", "00000080", "00000120"},
                        "2 ranks steered, replayed on 1");
}

}  // namespace

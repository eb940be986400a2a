// SPDX-License-Identifier: Apache-2.0
// Run flags: parse_run_flags accepts the documented flags and rejects bad
// values with one message naming the flag.
#include <gtest/gtest.h>

#include <stdexcept>
#include <string>
#include <vector>

#include "job/run_flags.h"

namespace erg::job {
namespace {

std::string error_of(const std::vector<std::string>& args) {
  try {
    parse_run_flags(args);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "(accepted)";
}

TEST(RunFlags, AcceptsEveryDocumentedFlag) {
  const RunFlags f =
      parse_run_flags({"job.json", "--out", "runs/a", "--steps", "250", "--snapshot-every", "25",
                       "--checkpoint-every", "0", "--threads", "4", "--backend", "cpu",
                       "--progress-fd", "3", "--quiet", "--steer-dir", "runs/a.steer"});
  EXPECT_EQ(f.job_path, "job.json");
  EXPECT_EQ(f.out_dir, "runs/a");
  EXPECT_TRUE(f.resume_dir.empty());
  EXPECT_EQ(f.overrides.steps, 250);
  EXPECT_EQ(f.overrides.snapshot_every, 25);
  EXPECT_EQ(f.overrides.checkpoint_every, 0);
  EXPECT_EQ(f.threads, 4);
  EXPECT_EQ(f.backend, "cpu");
  EXPECT_EQ(f.progress_fd, 3);
  EXPECT_TRUE(f.quiet);
  EXPECT_EQ(f.steer_dir, "runs/a.steer");
}

TEST(RunFlags, DefaultsWhenFlagsAreOmitted) {
  const RunFlags f = parse_run_flags({"--out", "o", "j.json"});
  EXPECT_EQ(f.job_path, "j.json");
  EXPECT_EQ(f.out_dir, "o");
  EXPECT_EQ(f.overrides.steps, -1);
  EXPECT_EQ(f.overrides.snapshot_every, -1);
  EXPECT_EQ(f.overrides.checkpoint_every, -1);
  EXPECT_EQ(f.threads, 0);
  EXPECT_EQ(f.backend, "auto");
  EXPECT_EQ(f.progress_fd, -1);
  EXPECT_FALSE(f.quiet);
  EXPECT_TRUE(f.steer_dir.empty());
  for (const char* b : {"auto", "cpu", "cuda"})
    EXPECT_EQ(parse_run_flags({"j.json", "--out", "o", "--backend", b}).backend, b);
}

TEST(RunFlags, ResumeTakesNoJobAndWritesIntoItsDirectory) {
  RunFlags f = parse_run_flags({"--resume", "runs/a", "--steps", "10"});
  EXPECT_EQ(f.resume_dir, "runs/a");
  EXPECT_EQ(f.out_dir, "runs/a");
  EXPECT_TRUE(f.job_path.empty());
  EXPECT_EQ(f.overrides.steps, 10);
  f = parse_run_flags({"--resume", "runs/a", "--out", "runs/a"});
  EXPECT_EQ(f.out_dir, "runs/a");
}

struct BadFlags {
  std::vector<std::string> args;
  std::vector<std::string> expect;  // all in the message
};

TEST(RunFlags, RejectsBadValuesNamingTheFlag) {
  const std::vector<BadFlags> cases = {
      {{"j.json", "--out", "o", "--steps", "-3"}, {"--steps -3", "[0, 1000000000]"}},
      {{"j.json", "--out", "o", "--steps", "ten"}, {"--steps ten", "integer"}},
      {{"j.json", "--out", "o", "--steps", "12x"}, {"--steps 12x"}},
      {{"j.json", "--out", "o", "--steps", ""}, {"--steps"}},
      {{"j.json", "--out", "o", "--steps", "99999999999999999999999"}, {"--steps 9999"}},
      {{"j.json", "--out", "o", "--snapshot-every", "-1"}, {"--snapshot-every -1"}},
      {{"j.json", "--out", "o", "--checkpoint-every", "1.5"}, {"--checkpoint-every 1.5"}},
      {{"j.json", "--out", "o", "--threads", "0"}, {"--threads 0", "[1, 4096]"}},
      {{"j.json", "--out", "o", "--threads", "5000"}, {"--threads 5000"}},
      {{"j.json", "--out", "o", "--progress-fd", "-2"}, {"--progress-fd -2"}},
      {{"j.json", "--out", "o", "--steer-dir"}, {"--steer-dir", "missing value"}},
      {{"j.json", "--out", "o", "--steer-dir", ""}, {"--steer-dir"}},
      {{"j.json", "--out", "o", "--backend", "gpu"}, {"--backend gpu", "auto, cpu or cuda"}},
      {{"j.json", "--out", "o", "--fast"}, {"--fast", "unknown flag"}},
      {{"j.json", "--out", "o", "-x"}, {"-x", "unknown flag"}},
      {{"j.json", "--out", "o", "--steps"}, {"--steps", "missing value"}},
      {{"j.json", "--out"}, {"--out", "missing value"}},
      {{"j.json"}, {"missing --out"}},
      {{"--out", "o"}, {"missing the job file"}},
      {{}, {"missing the job file"}},
      {{"j.json", "k.json", "--out", "o"}, {"k.json", "unexpected argument", "j.json"}},
      {{"--resume", "runs/a", "j.json"}, {"--resume", "give no job file"}},
      {{"j.json", "--resume", "runs/a"}, {"--resume", "give no job file"}},
      {{"--resume", "runs/a", "--out", "runs/b"}, {"--resume", "--out"}},
  };
  for (const auto& c : cases) {
    std::string cmd;
    for (const auto& a : c.args) cmd += " '" + a + "'";
    const std::string e = error_of(c.args);
    ASSERT_NE(e, "(accepted)") << cmd;
    for (const auto& part : c.expect)
      EXPECT_NE(e.find(part), std::string::npos) << cmd << "\n" << e;
  }
}

TEST(RunFlags, UsageNamesTheFlags) {
  const std::string u = run_flags_usage();
  for (const char* flag : {"--out", "--steps", "--snapshot-every", "--checkpoint-every",
                           "--threads", "--backend", "--resume", "--progress-fd", "--steer-dir"})
    EXPECT_NE(u.find(flag), std::string::npos) << flag;
  EXPECT_NE(error_of({"j.json", "--bogus"}).find("usage"), std::string::npos);
  // Both programs that parse these flags, each with how it is called: the
  // worker takes the job file directly, without erg's "run".
  for (const char* call : {"erg run JOB.json --out DIR", "erg run --resume DIR",
                           "erg-worker JOB.json --out DIR", "erg-worker --resume DIR"})
    EXPECT_NE(u.find(call), std::string::npos) << call;
}

}  // namespace
}  // namespace erg::job

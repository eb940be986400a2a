// SPDX-License-Identifier: Apache-2.0
// erg_client_lib: how the remote commands find ergd (flags, environment,
// config file), their argument parsing, status codes and retries, and the
// bookkeeping of resumable, sha256-checked snapshot downloads.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

#include "../common/temp_dir.h"
#include "remote/args.h"
#include "remote/config.h"
#include "remote/download.h"
#include "remote/status.h"

namespace erg::client {
namespace {

using erg::test_support::TempDir;
namespace fs = std::filesystem;

// A fake environment.
struct Env {
  std::map<std::string, std::string> vars;
  EnvLookup lookup() const {
    return [this](const char* name) -> const char* {
      const auto it = vars.find(name);
      return it == vars.end() ? nullptr : it->second.c_str();
    };
  }
};

void write(const std::string& path, const std::string& text) {
  std::ofstream(path, std::ios::binary | std::ios::trunc) << text;
}

std::string read(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "(no error)";
}

// ---- connection flags --------------------------------------------------------

TEST(ConnectionFlags, ExtractedAnywhereAndRemoved) {
  std::vector<std::string> args = {"--token",  "t0k", "j-1",  "--json",
                                   "--server", "h:1", "--ca", "ca.pem"};
  const ConnectionFlags f = extract_connection_flags(args);
  EXPECT_EQ(args, (std::vector<std::string>{"j-1", "--json"}));
  EXPECT_EQ(f.server, "h:1");
  EXPECT_EQ(f.token, "t0k");
  EXPECT_EQ(f.ca, "ca.pem");
  EXPECT_TRUE(f.any());
}

TEST(ConnectionFlags, NoneLeavesArgumentsAlone) {
  std::vector<std::string> args = {"j-1", "--step", "5"};
  const ConnectionFlags f = extract_connection_flags(args);
  EXPECT_FALSE(f.any());
  EXPECT_EQ(args.size(), 3u);
}

TEST(ConnectionFlags, MissingValueNamesTheFlag) {
  std::vector<std::string> args = {"j-1", "--server"};
  EXPECT_EQ(error_of([&] { extract_connection_flags(args); }), "--server: missing value");
  std::vector<std::string> empty = {"--token", ""};
  EXPECT_EQ(error_of([&] { extract_connection_flags(empty); }), "--token: missing value");
}

// ---- config file -------------------------------------------------------------

TEST(ConfigFile, KeysCommentsAndBlanks) {
  const auto cfg = parse_config(
      "# erg client\n"
      "\n"
      "server = ergd.example.org:7443   # the cluster\n"
      "  token=abc#def\n"
      "ca = certs/ca.pem\n",
      "cfg");
  EXPECT_EQ(cfg.at("server"), "ergd.example.org:7443");
  EXPECT_EQ(cfg.at("token"), "abc#def");  // '#' inside a value is kept
  EXPECT_EQ(cfg.at("ca"), "certs/ca.pem");
}

TEST(ConfigFile, BadLinesNameFileAndLine) {
  EXPECT_EQ(error_of([] { parse_config("server = a:1\nsevrer = b:2\n", "/x/config"); }),
            "/x/config:2: unknown key 'sevrer' (expected server, token or ca)");
  EXPECT_EQ(error_of([] { parse_config("\n\njust text\n", "c"); }),
            "c:3: expected `key = value`, got 'just text'");
  EXPECT_EQ(error_of([] { parse_config("token =   \n", "c"); }), "c:1: token: missing value");
}

TEST(ServerAddress, DefaultPortAndForms) {
  EXPECT_EQ(normalize_server("ergd"), "ergd:7117");
  EXPECT_EQ(normalize_server(" 10.0.0.5:9000 "), "10.0.0.5:9000");
  EXPECT_EQ(normalize_server("[::1]:80"), "[::1]:80");
  EXPECT_EQ(normalize_server("[::1]"), "[::1]:7117");
  EXPECT_EQ(normalize_server("::1"), "[::1]:7117");
  EXPECT_EQ(normalize_server("dns:///ergd:7117"), "dns:///ergd:7117");
  EXPECT_EQ(normalize_server("unix:/run/ergd.sock"), "unix:/run/ergd.sock");
  EXPECT_THROW(normalize_server("  "), std::invalid_argument);
}

// ---- resolution: flag > environment > config file > default ------------------

TEST(Resolve, DefaultsWithNothingConfigured) {
  TempDir home;
  Env env{{{"HOME", home.str()}}};
  const auto s = resolve_connection({}, env.lookup());
  EXPECT_EQ(s.server, "127.0.0.1:7117");
  EXPECT_EQ(s.server_origin, "default");
  EXPECT_EQ(s.token, "");
  EXPECT_EQ(s.ca, "");
  EXPECT_TRUE(s.warnings.empty());
}

TEST(Resolve, HomeConfigIsRead) {
  TempDir home;
  fs::create_directories(home.path() / ".config" / "erg");
  const std::string cfg = (home.path() / ".config" / "erg" / "config").string();
  write(cfg, "server = cfg-host:1\ntoken = cfg-token\nca = ca.pem\n");
  ::chmod(cfg.c_str(), 0600);
  Env env{{{"HOME", home.str()}}};
  const auto s = resolve_connection({}, env.lookup());
  EXPECT_EQ(s.server, "cfg-host:1");
  EXPECT_EQ(s.token, "cfg-token");
  EXPECT_EQ(s.server_origin, cfg);
  EXPECT_EQ(s.token_origin, cfg);
  // A relative CA is relative to the config file's folder.
  EXPECT_EQ(s.ca, (home.path() / ".config" / "erg" / "ca.pem").string());
  EXPECT_TRUE(s.warnings.empty());
}

TEST(Resolve, EachSettingOnItsOwnFlagBeatsEnvBeatsConfig) {
  TempDir dir;
  write(dir / "config", "server = cfg-host:1\ntoken = cfg-token\nca = /etc/cfg-ca.pem\n");
  ::chmod((dir / "config").c_str(), 0600);
  Env env{{{"ERG_CONFIG", dir / "config"}, {"ERG_TOKEN", "env-token"}, {"HOME", dir.str()}}};
  ConnectionFlags flags;
  flags.server = "flag-host";
  const auto s = resolve_connection(flags, env.lookup());
  EXPECT_EQ(s.server, "flag-host:7117");
  EXPECT_EQ(s.server_origin, "--server");
  EXPECT_EQ(s.token, "env-token");
  EXPECT_EQ(s.token_origin, "ERG_TOKEN");
  EXPECT_EQ(s.ca, "/etc/cfg-ca.pem");
  EXPECT_EQ(s.ca_origin, dir / "config");

  env.vars["ERG_SERVER"] = "env-host:2";
  env.vars["ERG_CA"] = "/env/ca.pem";
  const auto t = resolve_connection({}, env.lookup());
  EXPECT_EQ(t.server, "env-host:2");
  EXPECT_EQ(t.ca, "/env/ca.pem");
  flags.token = "flag-token";
  flags.ca = "flag-ca.pem";
  const auto u = resolve_connection(flags, env.lookup());
  EXPECT_EQ(u.token, "flag-token");
  EXPECT_EQ(u.ca, "flag-ca.pem");  // as given: relative to the working directory
}

TEST(Resolve, EmptyEnvironmentVariableCountsAsUnset) {
  TempDir dir;
  Env env{{{"ERG_SERVER", ""}, {"HOME", dir.str()}}};
  EXPECT_EQ(resolve_connection({}, env.lookup()).server, "127.0.0.1:7117");
}

TEST(Resolve, ConfigNotReadWhenFlagsAndEnvironmentSettleEverything) {
  TempDir dir;
  write(dir / "config", "this is not a config\n");
  Env env{{{"ERG_CONFIG", dir / "config"}, {"ERG_TOKEN", "t"}}};
  ConnectionFlags flags;
  flags.server = "h:1";
  flags.ca = "ca.pem";
  EXPECT_NO_THROW(resolve_connection(flags, env.lookup()));
  flags.ca.reset();  // now the file is needed, and bad
  EXPECT_EQ(error_of([&] { resolve_connection(flags, env.lookup()); }),
            dir / "config" + ":1: expected `key = value`, got 'this is not a config'");
}

TEST(Resolve, NamedConfigMustExistDefaultNeedNot) {
  TempDir dir;
  Env named{{{"ERG_CONFIG", dir / "missing"}}};
  EXPECT_EQ(error_of([&] { resolve_connection({}, named.lookup()); }),
            "cannot read the config file " + dir / "missing" + " (named by ERG_CONFIG)");
  Env home{{{"HOME", dir / "nohome"}}};
  EXPECT_NO_THROW(resolve_connection({}, home.lookup()));
  Env nothing;
  EXPECT_EQ(resolve_connection({}, nothing.lookup()).server, "127.0.0.1:7117");
}

TEST(Resolve, WarnsOfATokenInAFileOthersCanRead) {
  TempDir dir;
  write(dir / "config", "token = secret\n");
  ::chmod((dir / "config").c_str(), 0644);
  Env env{{{"ERG_CONFIG", dir / "config"}}};
  const auto s = resolve_connection({}, env.lookup());
  ASSERT_EQ(s.warnings.size(), 1u);
  EXPECT_NE(s.warnings[0].find("chmod 600"), std::string::npos);
  // No token in it: nothing to warn about.
  write(dir / "config", "server = h:1\n");
  EXPECT_TRUE(resolve_connection({}, env.lookup()).warnings.empty());
}

// ---- command arguments -------------------------------------------------------

TEST(Args, PositionalsValuesAndSwitchesInAnyOrder) {
  const auto p = parse_args({"--out", "d", "j-1", "--all", "--step", "3", "--step", "4"},
                            {"--out", "--step"}, {"--all"});
  EXPECT_EQ(p.positional, std::vector<std::string>{"j-1"});
  EXPECT_EQ(p.values.at("--out"), "d");
  EXPECT_EQ(p.values.at("--step"), "4");  // the last one wins
  EXPECT_TRUE(p.has("--all"));
  EXPECT_FALSE(p.has("--json"));
}

TEST(Args, ErrorsNameTheFlag) {
  EXPECT_EQ(error_of([] { parse_args({"j", "--bogus"}, {"--out"}, {}); }), "--bogus: unknown flag");
  EXPECT_EQ(error_of([] { parse_args({"j", "--out"}, {"--out"}, {}); }), "--out: missing value");
  EXPECT_EQ(error_of([] { parse_int_flag("--step", "1x", 0, 9); }),
            "--step 1x: expected an integer in [0, 9]");
  EXPECT_EQ(error_of([] { parse_int_flag("--step", "-1", 0, 9); }),
            "--step -1: expected an integer in [0, 9]");
  EXPECT_EQ(parse_int_flag("--step", "7", 0, 9), 7);
}

// ---- status codes, exit codes, retries ---------------------------------------

TEST(Status, NamesAndExitCodes) {
  EXPECT_EQ(status_code_name(0), "OK");
  EXPECT_EQ(status_code_name(3), "INVALID_ARGUMENT");
  EXPECT_EQ(status_code_name(9), "FAILED_PRECONDITION");
  EXPECT_EQ(status_code_name(14), "UNAVAILABLE");
  EXPECT_EQ(status_code_name(16), "UNAUTHENTICATED");
  EXPECT_EQ(status_code_name(99), "CODE_99");
  EXPECT_EQ(exit_code_for_status(0), 0);
  EXPECT_EQ(exit_code_for_status(3), kExitUsage);
  EXPECT_EQ(exit_code_for_status(16), kExitAuth);
  EXPECT_EQ(exit_code_for_status(7), kExitAuth);
  EXPECT_EQ(exit_code_for_status(5), kExitNotFound);
  EXPECT_EQ(exit_code_for_status(9), kExitError);
  EXPECT_EQ(exit_code_for_status(14), kExitError);
  EXPECT_EQ(kExitUsage, 2);
  EXPECT_EQ(kExitCancelled, 3);
  EXPECT_EQ(kExitAuth, 4);
  EXPECT_EQ(kExitNotFound, 5);
}

TEST(Status, StreamBreaksAreRetriedRefusalsAreNot) {
  EXPECT_TRUE(is_stream_break(14, "Socket closed"));
  EXPECT_TRUE(is_stream_break(1, "Cancelled"));
  EXPECT_TRUE(is_stream_break(13, "Received RST_STREAM with error code 2"));
  EXPECT_TRUE(is_stream_break(2, "Stream removed"));
  EXPECT_FALSE(is_stream_break(13, "checkpoint corrupt"));
  EXPECT_FALSE(is_stream_break(5, "no such job"));
  EXPECT_FALSE(is_stream_break(16, "bad token"));
  EXPECT_FALSE(is_stream_break(3, "bad offset"));
}

TEST(Status, RetryBudgetBacksOffThenGivesUp) {
  RetryBudget r(30, 0.25, 4);
  double t = 100;
  std::vector<double> waits;
  for (;;) {
    const double w = r.next_delay(t);
    if (w < 0) break;
    waits.push_back(w);
    t += w;
  }
  ASSERT_GE(waits.size(), 6u);
  EXPECT_DOUBLE_EQ(waits[0], 0.25);
  EXPECT_DOUBLE_EQ(waits[1], 0.5);
  EXPECT_DOUBLE_EQ(waits[2], 1);
  EXPECT_DOUBLE_EQ(waits[4], 4);
  EXPECT_DOUBLE_EQ(waits[5], 4);   // capped
  EXPECT_NEAR(t - 100, 30, 1e-9);  // gave up after 30 s of failures in a row
  EXPECT_NEAR(r.failing_for(t), 30, 1e-9);
  // Success starts the schedule afresh.
  r.reset();
  EXPECT_EQ(r.failing_for(t), 0);
  EXPECT_DOUBLE_EQ(r.next_delay(t + 1000), 0.25);
}

// ---- downloads -----------------------------------------------------------------

const std::string kAbcSha = "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad";

TEST(Sha256, KnownDigests) {
  Sha256 h;
  h.update("a", 1);
  h.update("bc", 2);
  EXPECT_EQ(h.hex(), kAbcSha);
  Sha256 empty;
  EXPECT_EQ(empty.hex(), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
  TempDir dir;
  write(dir / "f", "abcdef");
  EXPECT_EQ(sha256_of_file(dir / "f", 3), kAbcSha);
  EXPECT_TRUE(file_has_sha256(dir / "f", sha256_of_file(dir / "f")));
  EXPECT_FALSE(file_has_sha256(dir / "f", kAbcSha));
  EXPECT_FALSE(file_has_sha256(dir / "none", kAbcSha));
  EXPECT_THROW(sha256_of_file(dir / "none"), std::runtime_error);
}

TEST(Download, FileNamesStayInTheFolder) {
  EXPECT_TRUE(is_plain_file_name("step_00000100.h5"));
  EXPECT_FALSE(is_plain_file_name(""));
  EXPECT_FALSE(is_plain_file_name("."));
  EXPECT_FALSE(is_plain_file_name(".."));
  EXPECT_FALSE(is_plain_file_name("../etc/passwd"));
  EXPECT_FALSE(is_plain_file_name("/etc/passwd"));
  EXPECT_FALSE(is_plain_file_name("a\nb"));
  EXPECT_EQ(snapshot_file_name(100), "step_00000100.h5");
  TempDir dir;
  EXPECT_THROW(PartialDownload(dir.str(), "../x.h5"), std::invalid_argument);
}

// The server's side of a download: the file, sent from an offset in chunks.
struct Served {
  std::string data;
  std::string sha;
  explicit Served(std::string d) : data(std::move(d)) {
    Sha256 h;
    h.update(data.data(), data.size());
    sha = h.hex();
  }
  // Sends [from, to) in chunks of `chunk` bytes.
  void send(PartialDownload& dl, size_t from, size_t to, size_t chunk = 7) const {
    for (size_t at = from; at < to; at += chunk)
      dl.append(static_cast<std::int64_t>(at), data.data() + at, std::min(chunk, to - at));
  }
};

std::string pattern(size_t n) {
  std::string s(n, '\0');
  for (size_t i = 0; i < n; ++i) s[i] = static_cast<char>((i * 131 + i / 7) & 0xff);
  return s;
}

TEST(Download, FreshDownloadEndsInTheVerifiedFileOnly) {
  TempDir dir;
  const Served f(pattern(1000));
  PartialDownload dl(dir.str(), "step_00000010.h5");
  EXPECT_EQ(dl.resume_offset(), 0);
  ASSERT_EQ(dl.start(0, 1000, f.sha), PartialDownload::Start::kGo);
  EXPECT_TRUE(fs::exists(dl.part_path()));
  EXPECT_EQ(read(dl.sha_path()), f.sha + "\n");
  f.send(dl, 0, 1000);
  EXPECT_TRUE(dl.complete());
  dl.finish();
  EXPECT_EQ(read(dir / "step_00000010.h5"), f.data);
  EXPECT_EQ(dir.entries(), std::set<std::string>{"step_00000010.h5"});
}

TEST(Download, InterruptedDownloadResumesFromThePartSize) {
  TempDir dir;
  const Served f(pattern(5000));
  {
    PartialDownload dl(dir.str(), "s.h5");
    ASSERT_EQ(dl.start(0, 5000, f.sha), PartialDownload::Start::kGo);
    f.send(dl, 0, 1234);
    // The connection drops (or erg is killed) here.
  }
  EXPECT_FALSE(fs::exists(dir / "s.h5"));
  PartialDownload dl(dir.str(), "s.h5");
  EXPECT_EQ(dl.resume_offset(), 1234);
  ASSERT_EQ(dl.start(1234, 5000, f.sha), PartialDownload::Start::kGo);
  EXPECT_FALSE(dl.discarded());
  EXPECT_EQ(dl.bytes(), 1234);
  f.send(dl, 1234, 5000, 1000);
  dl.finish();  // the digest covers the bytes from both sessions
  EXPECT_EQ(read(dir / "s.h5"), f.data);
  EXPECT_EQ(dir.entries(), std::set<std::string>{"s.h5"});
}

TEST(Download, CorruptPartFailsTheChecksumAndIsDeleted) {
  TempDir dir;
  const Served f(pattern(300));
  std::string bad = f.data.substr(0, 100);
  bad[50] ^= 1;
  write(dir / "s.h5.part", bad);  // no recorded sha256: resumed as it is
  PartialDownload dl(dir.str(), "s.h5");
  ASSERT_EQ(dl.start(100, 300, f.sha), PartialDownload::Start::kGo);
  f.send(dl, 100, 300);
  const std::string err = error_of([&] { dl.finish(); });
  EXPECT_NE(err.find("sha256 mismatch for s.h5"), std::string::npos) << err;
  EXPECT_NE(err.find(f.sha), std::string::npos) << err;
  EXPECT_NE(err.find("deleted"), std::string::npos) << err;
  EXPECT_TRUE(dir.entries().empty());
}

TEST(Download, PartOfAnotherFileIsDiscarded) {
  TempDir dir;
  const Served old_file(pattern(400));
  const Served f(pattern(600).replace(0, 3, "new"));
  {
    PartialDownload dl(dir.str(), "s.h5");
    ASSERT_EQ(dl.start(0, 400, old_file.sha), PartialDownload::Start::kGo);
    old_file.send(dl, 0, 200);
  }
  PartialDownload dl(dir.str(), "s.h5");
  EXPECT_EQ(dl.resume_offset(), 200);
  // The server announces another sha256 for the name: start again from 0.
  ASSERT_EQ(dl.start(200, 600, f.sha), PartialDownload::Start::kRestart);
  EXPECT_TRUE(dl.discarded());
  EXPECT_EQ(dl.resume_offset(), 0);
  ASSERT_EQ(dl.start(0, 600, f.sha), PartialDownload::Start::kGo);
  f.send(dl, 0, 600);
  dl.finish();
  EXPECT_EQ(read(dir / "s.h5"), f.data);
}

TEST(Download, PartLongerThanTheFileIsDiscarded) {
  TempDir dir;
  const Served f(pattern(100));
  write(dir / "s.h5.part", pattern(150));
  PartialDownload dl(dir.str(), "s.h5");
  ASSERT_EQ(dl.start(150, 100, f.sha), PartialDownload::Start::kRestart);
  EXPECT_TRUE(dl.discarded());
  EXPECT_EQ(dl.resume_offset(), 0);
}

TEST(Download, WholeFileRequestedDespiteAPartStartsOver) {
  TempDir dir;
  const Served f(pattern(100));
  write(dir / "s.h5.part", "garbage");
  PartialDownload dl(dir.str(), "s.h5");
  ASSERT_EQ(dl.start(0, 100, f.sha), PartialDownload::Start::kGo);
  EXPECT_EQ(dl.bytes(), 0);
  f.send(dl, 0, 100);
  dl.finish();
  EXPECT_EQ(read(dir / "s.h5"), f.data);
}

TEST(Download, OffsetNotMatchingThePartAsksAgain) {
  TempDir dir;
  const Served f(pattern(100));
  write(dir / "s.h5.part", f.data.substr(0, 40));
  PartialDownload dl(dir.str(), "s.h5");
  // Asked from 10 (another name's .part, say): ask again from 40.
  EXPECT_EQ(dl.start(10, 100, f.sha), PartialDownload::Start::kRestart);
  EXPECT_FALSE(dl.discarded());
  EXPECT_EQ(dl.resume_offset(), 40);
}

TEST(Download, OutOfPlaceOrExcessBytesAreRefused) {
  TempDir dir;
  const Served f(pattern(100));
  PartialDownload dl(dir.str(), "s.h5");
  ASSERT_EQ(dl.start(0, 100, f.sha), PartialDownload::Start::kGo);
  f.send(dl, 0, 50);
  EXPECT_NE(error_of([&] { dl.append(60, "x", 1); }).find("offset 60"), std::string::npos);
  EXPECT_NE(error_of([&] { dl.append(50, pattern(51).data(), 51); }).find("more than"),
            std::string::npos);
  EXPECT_NE(error_of([&] { dl.finish(); }).find("have 50 of 100 bytes"), std::string::npos);
}

TEST(Download, ReplacesAnOlderFinishedFileAtomically) {
  TempDir dir;
  write(dir / "s.h5", "stale");
  const Served f(pattern(64));
  PartialDownload dl(dir.str(), "s.h5");
  ASSERT_EQ(dl.start(0, 64, f.sha), PartialDownload::Start::kGo);
  f.send(dl, 0, 64);
  EXPECT_EQ(read(dir / "s.h5"), "stale");  // untouched until the new one is whole
  dl.finish();
  EXPECT_EQ(read(dir / "s.h5"), f.data);
}

TEST(Download, EmptyFile) {
  TempDir dir;
  const Served f("");
  PartialDownload dl(dir.str(), "e.h5");
  ASSERT_EQ(dl.start(0, 0, f.sha), PartialDownload::Start::kGo);
  EXPECT_TRUE(dl.complete());
  dl.finish();
  EXPECT_EQ(fs::file_size(dir / "e.h5"), 0u);
}

}  // namespace
}  // namespace erg::client

// SPDX-License-Identifier: Apache-2.0
// The tokens file as ergd reads it, without the network: roles, bad lines
// skipped and reported with their numbers (the others apply), revocation on
// change, fail closed when the file is gone, and dashboard sessions bound to
// their token.
#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <thread>

#include "../common/temp_dir.h"
#include "auth/sessions.h"
#include "auth/throttle.h"
#include "auth/tokens.h"

namespace fs = std::filesystem;
using erg::server::Identity;
using erg::server::Sessions;
using erg::server::SignInThrottle;
using erg::server::Tokens;

namespace {

// Rewrites the file as an editor would (in place) and waits past the
// 100 ms between checks.
void rewrite(const fs::path& f, const std::string& text) {
  { std::ofstream(f, std::ios::trunc) << text; }
  std::this_thread::sleep_for(std::chrono::milliseconds(150));
}

struct Logged {
  std::vector<std::string> lines;
  Tokens::Log log() {
    return [this](const std::string& m) { lines.push_back(m); };
  }
  bool has(const std::string& part) const {
    for (const auto& l : lines)
      if (l.find(part) != std::string::npos) return true;
    return false;
  }
};

}  // namespace

TEST(Tokens, ParsesTokenTenantAndRole) {
  auto t = Tokens::parse(
      "# comment\n\nabcdefghijklmnop alice  # trailing\nqrstuvwxyz012345 bob operator\n", "tokens");
  EXPECT_TRUE(t.problems.empty());
  ASSERT_EQ(t.tokens.size(), 2u);
  EXPECT_EQ(t.tokens.at("abcdefghijklmnop"), (Identity{"alice", false}));
  EXPECT_EQ(t.tokens.at("qrstuvwxyz012345"), (Identity{"bob", true}));
}

TEST(Tokens, BadLinesAreSkippedNamingTheLineAndTheOthersApply) {
  auto t = Tokens::parse(
      "abcdefghijklmnop\n"                   // 1: no tenant
      "ok-ok-ok-ok-ok-ok a\n"                // 2: fine
      "abcdefghijklmnop alice admin\n"       // 3: unknown role
      "abcdefghijklmnop alice operator x\n"  // 4: too many fields
      "short alice\n"                        // 5: short token
      "ok-ok-ok-ok-ok-ok a\n"                // 6: duplicate, same tenant: kept
      "shared-shared-shared b\n"             // 7
      "shared-shared-shared c\n"             // 8: one token, two tenants: neither
      "shared-shared-shared d\n",            // 9
      "tokens");
  ASSERT_EQ(t.problems.size(), 7u);
  EXPECT_EQ(t.problems[0], "tokens:1: expected `TOKEN TENANT [operator]` (line skipped)");
  EXPECT_EQ(t.problems[1],
            "tokens:3: unknown role 'admin' (the only role is `operator`) (line skipped)");
  EXPECT_EQ(t.problems[2], "tokens:4: expected `TOKEN TENANT [operator]` (line skipped)");
  EXPECT_EQ(t.problems[3], "tokens:5: token shorter than 16 characters (line skipped)");
  EXPECT_EQ(t.problems[4], "tokens:6: duplicate token (line skipped)");
  EXPECT_EQ(t.problems[5],
            "tokens:8: duplicate token given to another tenant: revoked for both (line skipped)");
  EXPECT_EQ(t.problems[6].substr(0, 9), "tokens:9:");
  ASSERT_EQ(t.tokens.size(), 1u);
  EXPECT_EQ(t.tokens.at("ok-ok-ok-ok-ok-ok").tenant, "a");
}

TEST(Tokens, RevocationAndFailClosed) {
  erg::test_support::TempDir d("tokens");
  const fs::path f = d.path() / "tokens";
  { std::ofstream(f) << "abcdefghijklmnop alice\nqrstuvwxyz012345 bob\n"; }
  Logged logged;
  Tokens t(f.string(), logged.log());
  EXPECT_EQ(t.tenant_of_header("Bearer abcdefghijklmnop"), "alice");
  EXPECT_FALSE(t.tenant_of_header("abcdefghijklmnop"));
  EXPECT_FALSE(t.tenant_of_header("Bearer abcdefghijklmno"));  // a prefix is not the token
  EXPECT_FALSE(t.tenant_of_header("Bearer "));
  // Alice's line removed in an edit that also has a bad line: the removal
  // applies, the bad line is logged with its number.
  rewrite(f, "qrstuvwxyz012345 bob\nbroken-line-without-tenant\n");
  EXPECT_FALSE(t.tenant_of_token("abcdefghijklmnop"));
  EXPECT_EQ(t.tenant_of_token("qrstuvwxyz012345"), "bob");
  EXPECT_TRUE(logged.has(f.string() + ":2: expected `TOKEN TENANT [operator]`"));
  // Gone: every token is revoked, and that is logged.
  fs::remove(f);
  std::this_thread::sleep_for(std::chrono::milliseconds(150));
  EXPECT_FALSE(t.tenant_of_token("qrstuvwxyz012345"));
  EXPECT_TRUE(logged.has("every token is revoked"));
  // Back: it applies again.
  rewrite(f, "qrstuvwxyz012345 bob operator\n");
  auto id = t.identity_of_token("qrstuvwxyz012345");
  ASSERT_TRUE(id);
  EXPECT_TRUE(id->is_operator);
  EXPECT_TRUE(logged.has("can be read again"));
  // Unreadable (a directory in its place): fail closed too.
  fs::remove(f);
  fs::create_directory(f);
  std::this_thread::sleep_for(std::chrono::milliseconds(150));
  EXPECT_FALSE(t.tenant_of_token("qrstuvwxyz012345"));
}

TEST(Tokens, AFileWithoutAValidTokenDoesNotStart) {
  erg::test_support::TempDir d("tokens");
  const fs::path f = d.path() / "tokens";
  { std::ofstream(f) << "short alice\n"; }
  Logged logged;
  EXPECT_THROW(Tokens(f.string(), logged.log()), std::runtime_error);
  EXPECT_TRUE(logged.has(":1: token shorter than 16 characters"));
  EXPECT_THROW(Tokens((d.path() / "missing").string(), logged.log()), std::runtime_error);
}

TEST(Sessions, RandomIdsBoundToTheirTokenAndRevokedWithIt) {
  erg::test_support::TempDir d("sessions");
  const fs::path f = d.path() / "tokens";
  { std::ofstream(f) << "abcdefghijklmnop alice\nqrstuvwxyz012345 bob\n"; }
  Tokens t(f.string(), [](const std::string&) {});
  Sessions s(t);
  EXPECT_FALSE(s.open("wrong-wrong-wrong-wrong"));
  auto a = s.open("abcdefghijklmnop");
  auto a2 = s.open("abcdefghijklmnop");
  auto b = s.open("qrstuvwxyz012345");
  ASSERT_TRUE(a && a2 && b);
  EXPECT_EQ(a->size(), 64u);
  EXPECT_NE(*a, *a2);
  EXPECT_EQ(a->find("abcdefghijklmnop"), std::string::npos);
  EXPECT_EQ(s.identity(*a)->tenant, "alice");
  EXPECT_EQ(s.identity(*b)->tenant, "bob");
  EXPECT_FALSE(s.identity(std::string(64, '0')));
  // Sign-out ends one session.
  s.close(*a2);
  EXPECT_FALSE(s.identity(*a2));
  // Revoking the token ends its sessions; the others live.
  rewrite(f, "qrstuvwxyz012345 bob\n");
  EXPECT_FALSE(s.identity(*a));
  EXPECT_EQ(s.identity(*b)->tenant, "bob");
  // A token keeps at most kPerToken sessions.
  for (size_t i = 0; i < Sessions::kPerToken + 5; ++i) ASSERT_TRUE(s.open("qrstuvwxyz012345"));
  EXPECT_LE(s.size(), Sessions::kPerToken);
}

TEST(SignInThrottle, BurstThenRefusedPerAddress) {
  SignInThrottle th;
  for (int i = 0; i < static_cast<int>(SignInThrottle::kBurst); ++i) {
    EXPECT_EQ(th.wait_s("10.0.0.1"), 0.0);
    th.failed("10.0.0.1");
  }
  EXPECT_GT(th.wait_s("10.0.0.1"), 0.0);
  EXPECT_LE(th.wait_s("10.0.0.1"), SignInThrottle::kRefillS);
  EXPECT_EQ(th.wait_s("10.0.0.2"), 0.0);  // another address is not affected
}

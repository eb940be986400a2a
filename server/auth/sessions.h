// SPDX-License-Identifier: Apache-2.0
// Dashboard sessions: a browser that signs in with a token gets a random
// session id (256 bits) in its cookie, never the token. The session is bound
// to the token: every use re-checks the token against the tokens file, so a
// revoked token ends its sessions at once. Sessions end at sign-out, after
// 12 h unused, or 7 days after sign-in; a token holds at most 32 of them
// (the oldest goes). ergd keeps them in memory: a restart signs everyone out.
#pragma once

#include <chrono>
#include <map>
#include <mutex>
#include <optional>
#include <string>

#include "auth/tokens.h"

namespace erg::server {

class Sessions {
 public:
  explicit Sessions(Tokens& tokens) : tokens_(tokens) {}
  // A new session for a valid token (nullopt for an unknown one).
  std::optional<std::string> open(const std::string& token);
  // The identity behind a session id, if the session and its token live.
  std::optional<Identity> identity(const std::string& session_id);
  void close(const std::string& session_id);
  size_t size();

  static constexpr auto kIdle = std::chrono::hours(12);
  static constexpr auto kLifetime = std::chrono::hours(24 * 7);
  static constexpr size_t kPerToken = 32;
  static constexpr size_t kMax = 100000;

 private:
  using Clock = std::chrono::steady_clock;
  struct Session {
    std::string token;
    Clock::time_point opened, used;
  };
  void expire_locked(Clock::time_point now);
  Tokens& tokens_;
  std::mutex mu_;
  std::map<std::string, Session> by_key_;  // key: SHA-256 of the session id
};

}  // namespace erg::server

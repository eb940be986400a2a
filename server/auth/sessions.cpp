// SPDX-License-Identifier: Apache-2.0
#include "auth/sessions.h"

#include <stdexcept>
#include <vector>

#include "auth/random_hex.h"
#include "util/sha256.h"

namespace erg::server {

namespace {

// 256-bit session ids.
std::string random_id() {
  return random_hex(32);
}

}  // namespace

void Sessions::expire_locked(Clock::time_point now) {
  for (auto it = by_key_.begin(); it != by_key_.end();)
    if (now - it->second.used > kIdle || now - it->second.opened > kLifetime)
      it = by_key_.erase(it);
    else
      ++it;
}

std::optional<std::string> Sessions::open(const std::string& token) {
  if (!tokens_.identity_of_token(token)) return std::nullopt;
  const auto now = Clock::now();
  const std::string id = random_id();
  std::lock_guard lock(mu_);
  expire_locked(now);
  // At most kPerToken sessions per token, kMax in all: the oldest go.
  auto drop_oldest = [&](bool same_token) {
    auto oldest = by_key_.end();
    size_t n = 0;
    for (auto it = by_key_.begin(); it != by_key_.end(); ++it) {
      if (same_token && it->second.token != token) continue;
      ++n;
      if (oldest == by_key_.end() || it->second.opened < oldest->second.opened) oldest = it;
    }
    if (n >= (same_token ? kPerToken : kMax) && oldest != by_key_.end()) by_key_.erase(oldest);
  };
  drop_oldest(true);
  drop_oldest(false);
  by_key_[sha256_hex(id)] = {token, now, now};
  return id;
}

std::optional<Identity> Sessions::identity(const std::string& session_id) {
  if (session_id.size() != 64) return std::nullopt;
  const std::string key = sha256_hex(session_id);
  std::string token;
  {
    std::lock_guard lock(mu_);
    auto it = by_key_.find(key);
    if (it == by_key_.end()) return std::nullopt;
    const auto now = Clock::now();
    if (now - it->second.used > kIdle || now - it->second.opened > kLifetime) {
      by_key_.erase(it);
      return std::nullopt;
    }
    it->second.used = now;
    token = it->second.token;
  }
  auto id = tokens_.identity_of_token(token);
  if (!id) {
    // The token was revoked: so are all its sessions.
    std::lock_guard lock(mu_);
    for (auto it = by_key_.begin(); it != by_key_.end();)
      it = it->second.token == token ? by_key_.erase(it) : std::next(it);
  }
  return id;
}

void Sessions::close(const std::string& session_id) {
  std::lock_guard lock(mu_);
  by_key_.erase(sha256_hex(session_id));
}

size_t Sessions::size() {
  std::lock_guard lock(mu_);
  return by_key_.size();
}

}  // namespace erg::server

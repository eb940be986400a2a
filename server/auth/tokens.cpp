// SPDX-License-Identifier: Apache-2.0
#include "auth/tokens.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <iostream>
#include <set>
#include <sstream>
#include <stdexcept>

namespace erg::server {

namespace {

// Compares without an early exit, so the time taken does not tell an
// attacker how many leading characters of a token were right.
bool equal_constant_time(const std::string& a, const std::string& b) {
  unsigned diff = a.size() == b.size() ? 0u : 1u;
  for (size_t i = 0; i < a.size(); ++i)
    diff |= static_cast<unsigned>(a[i] ^ (i < b.size() ? b[i] : 0));
  return diff == 0;
}

bool same_time(const struct timespec& a, const struct timespec& b) {
  return a.tv_sec == b.tv_sec && a.tv_nsec == b.tv_nsec;
}

constexpr auto kCheckEvery = std::chrono::milliseconds(100);

}  // namespace

Tokens::Parsed Tokens::parse(const std::string& text, const std::string& origin) {
  Parsed out;
  std::set<std::string> ambiguous;  // one token given to two tenants: neither gets it
  std::istringstream in(text);
  std::string line;
  int n = 0;
  while (std::getline(in, line)) {
    ++n;
    auto bad = [&](const std::string& why) {
      out.problems.push_back(origin + ":" + std::to_string(n) + ": " + why + " (line skipped)");
    };
    if (auto h = line.find('#'); h != std::string::npos) line.resize(h);
    std::istringstream fields(line);
    std::string token, tenant, role, extra;
    if (!(fields >> token)) continue;
    if (!(fields >> tenant) || (fields >> role && fields >> extra)) {
      bad("expected `TOKEN TENANT [operator]`");
      continue;
    }
    if (!role.empty() && role != "operator") {
      bad("unknown role '" + role.substr(0, 32) + "' (the only role is `operator`)");
      continue;
    }
    if (token.size() < 16) {
      bad("token shorter than 16 characters");
      continue;
    }
    Identity id{tenant, role == "operator"};
    if (auto it = out.tokens.find(token); it != out.tokens.end() || ambiguous.count(token)) {
      if (it != out.tokens.end() && it->second.tenant == tenant) {
        bad("duplicate token");
        it->second.is_operator = it->second.is_operator || id.is_operator;
      } else {
        bad("duplicate token given to another tenant: revoked for both");
        if (it != out.tokens.end()) out.tokens.erase(it);
        ambiguous.insert(token);
      }
      continue;
    }
    out.tokens[token] = id;
  }
  return out;
}

Tokens::Tokens(std::string path, Log log) : path_(std::move(path)), log_(std::move(log)) {
  if (!log_) log_ = [](const std::string& m) { std::cerr << "ergd: " << m << std::endl; };
  std::lock_guard lock(mu_);
  reload_if_changed();
  if (!readable_) throw std::runtime_error("cannot read tokens file " + path_ + ": " + unreadable_);
  if (tokens_.empty()) throw std::runtime_error(path_ + ": no valid token");
}

void Tokens::apply(const std::string& text) {
  if (readable_ && text == text_) return;  // touched, not changed
  const bool first = text_.empty() && !readable_ && unreadable_.empty();
  Parsed p = parse(text, path_);
  for (const auto& problem : p.problems) log_(problem);
  const size_t before = tokens_.size();
  tokens_ = std::move(p.tokens);
  text_ = text;
  if (!readable_ && !unreadable_.empty())
    log_("tokens file " + path_ + " can be read again: " + std::to_string(tokens_.size()) +
         " tokens");
  else if (!first)
    log_("tokens file " + path_ + " changed: " + std::to_string(tokens_.size()) + " tokens (" +
         std::to_string(before) + " before)");
  readable_ = true;
  unreadable_.clear();
}

void Tokens::reload_if_changed() {
  const auto now = std::chrono::steady_clock::now();
  if (last_check_ != std::chrono::steady_clock::time_point{} && now - last_check_ < kCheckEvery)
    return;
  last_check_ = now;
  auto fail_closed = [&](const std::string& why) {
    if (!tokens_.empty() || why != unreadable_)
      log_("tokens file " + path_ + ": " + why + ": every token is revoked until it can be read");
    tokens_.clear();
    readable_ = false;
    unreadable_ = why;
    text_.clear();
    stamp_ = Stamp{};
  };
  const int fd = ::open(path_.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return fail_closed(std::strerror(errno));
  struct stat st {};
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
    const std::string why = S_ISREG(st.st_mode) ? std::strerror(errno) : "not a regular file";
    ::close(fd);
    return fail_closed(why);
  }
  // Unchanged unless the stamp moved. A file modified within the last two
  // seconds is read again anyway: a rewrite within the file system's
  // timestamp granularity leaves the stamp as it was.
  const bool recent = std::time(nullptr) - st.st_mtim.tv_sec < 2;
  if (readable_ && !recent && st.st_dev == stamp_.dev && st.st_ino == stamp_.ino &&
      st.st_size == stamp_.size && same_time(st.st_mtim, stamp_.mtime) &&
      same_time(st.st_ctim, stamp_.ctime)) {
    ::close(fd);
    return;
  }
  std::string text;
  char buf[4096];
  for (;;) {
    const ssize_t got = ::read(fd, buf, sizeof buf);
    if (got < 0 && errno == EINTR) continue;
    if (got < 0) {
      const std::string why = std::strerror(errno);
      ::close(fd);
      return fail_closed(why);
    }
    if (got == 0) break;
    text.append(buf, static_cast<size_t>(got));
    if (text.size() > (16u << 20)) {
      ::close(fd);
      return fail_closed("larger than 16 MiB");
    }
  }
  ::close(fd);
  stamp_ = {st.st_dev, st.st_ino, st.st_size, st.st_mtim, st.st_ctim};
  apply(text);
}

std::optional<Identity> Tokens::identity_of_token(const std::string& token) {
  std::lock_guard lock(mu_);
  reload_if_changed();
  std::optional<Identity> found;
  for (const auto& [t, id] : tokens_)
    if (equal_constant_time(t, token)) found = id;
  return found;
}

std::optional<Identity> Tokens::identity_of_header(const std::string& authorization) {
  static const std::string kBearer = "Bearer ";
  if (authorization.size() <= kBearer.size() || authorization.compare(0, kBearer.size(), kBearer))
    return std::nullopt;
  return identity_of_token(authorization.substr(kBearer.size()));
}

std::optional<std::string> Tokens::tenant_of_token(const std::string& token) {
  if (auto id = identity_of_token(token)) return id->tenant;
  return std::nullopt;
}

std::optional<std::string> Tokens::tenant_of_header(const std::string& authorization) {
  if (auto id = identity_of_header(authorization)) return id->tenant;
  return std::nullopt;
}

}  // namespace erg::server

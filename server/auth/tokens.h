// SPDX-License-Identifier: Apache-2.0
// Bearer tokens: ergd's tokens file holds lines `TOKEN TENANT [ROLE]` (`#`
// starts a comment). TOKEN is at least 16 characters; ROLE, when present, is
// `operator` (may read every tenant's /metrics; README "Tokens").
//
// The file is re-read when it changes (checked at most every 100 ms, on
// the calls that authenticate and on open streams, which re-check their
// token): tokens are added and revoked without a restart, within a second.
// A bad line is skipped and logged with its line number; the others apply,
// so a typo never keeps a revoked token alive. A file that is gone or cannot
// be read revokes every token (fail closed) until it can be read again.
#pragma once

#include <sys/types.h>

#include <chrono>
#include <ctime>
#include <functional>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

namespace erg::server {

struct Identity {
  std::string tenant;
  bool is_operator = false;
  bool operator==(const Identity&) const = default;
};

class Tokens {
 public:
  using Log = std::function<void(const std::string&)>;
  // Throws std::runtime_error when the file cannot be read or holds no valid
  // token (ergd does not start so). `log` gets one line per event (default:
  // stderr, "ergd: ...").
  explicit Tokens(std::string path, Log log = {});

  // The identity of an `authorization` header value ("Bearer T"), if T is known.
  std::optional<Identity> identity_of_header(const std::string& authorization);
  std::optional<Identity> identity_of_token(const std::string& token);
  std::optional<std::string> tenant_of_header(const std::string& authorization);
  std::optional<std::string> tenant_of_token(const std::string& token);

  struct Parsed {
    std::map<std::string, Identity> tokens;
    std::vector<std::string> problems;  // "ORIGIN:LINE: what is wrong" per skipped line
  };
  static Parsed parse(const std::string& text, const std::string& origin);

 private:
  void reload_if_changed();  // mu_ held
  void apply(const std::string& text);
  std::string path_;
  Log log_;
  std::mutex mu_;
  std::map<std::string, Identity> tokens_;
  struct Stamp {
    dev_t dev = 0;
    ino_t ino = 0;
    off_t size = -1;
    struct timespec mtime {};
    struct timespec ctime {};
  } stamp_;
  bool readable_ = false;
  std::string text_;        // the text the tokens were parsed from
  std::string unreadable_;  // why the file could not be read (logged once per reason)
  std::chrono::steady_clock::time_point last_check_{};
};

}  // namespace erg::server

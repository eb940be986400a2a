// Bearer tokens: ergd's tokens file holds lines `TOKEN TENANT` (`#` starts a
// comment). The file is read again when its modification time changes, so
// tokens are added or revoked without a restart.
#pragma once

#include <ctime>
#include <map>
#include <mutex>
#include <optional>
#include <string>

namespace erg::server {

class Tokens {
 public:
  // Throws std::runtime_error naming the file and line on a malformed file.
  explicit Tokens(std::string path);
  // The tenant of an `authorization` header value ("Bearer T"), if T is known.
  std::optional<std::string> tenant_of_header(const std::string& authorization);
  std::optional<std::string> tenant_of_token(const std::string& token);
  static std::map<std::string, std::string> parse(const std::string& text,
                                                  const std::string& origin);

 private:
  void reload_if_changed();
  std::string path_;
  std::mutex mu_;
  std::map<std::string, std::string> tenants_;  // token -> tenant
  struct timespec mtime_ {};
};

}  // namespace erg::server

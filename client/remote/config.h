// SPDX-License-Identifier: Apache-2.0
// Where the remote commands find ergd, and with which token.
//
// Each setting is resolved on its own, the first found winning:
//   1. a flag:  --server HOST:PORT, --token T, --ca FILE (anywhere in the
//      arguments of a remote command)
//   2. the environment: ERG_SERVER, ERG_TOKEN, ERG_CA
//   3. the config file: $ERG_CONFIG, else ~/.config/erg/config, lines
//        server = host:port
//        token = T
//        ca = /path/ca.pem        (TLS; relative to the config file's folder)
//      and blank lines; `#` starts a comment at the start of a line or after
//      a blank (so a token may hold a `#`)
//   4. the default: server 127.0.0.1:7117, no token, no TLS.
// The config file is read only when a flag or the environment leaves a
// setting open. Part of erg_client_lib (no gRPC), unit-tested.
#pragma once

#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace erg::client {

inline constexpr const char* kDefaultServer = "127.0.0.1:7117";
inline constexpr int kDefaultPort = 7117;

// The connection flags given on a command line.
struct ConnectionFlags {
  std::optional<std::string> server;  // --server HOST:PORT
  std::optional<std::string> token;   // --token T
  std::optional<std::string> ca;      // --ca FILE
  bool any() const { return server || token || ca; }
};

// Removes --server/--token/--ca and their values from `args`, wherever they
// are, and returns them. Throws std::invalid_argument on a flag without a
// value. Everything else is left in order.
ConnectionFlags extract_connection_flags(std::vector<std::string>& args);

// The settings of a config file. Throws std::invalid_argument naming
// origin:line on a line that is not `key = value` or an unknown key.
std::map<std::string, std::string> parse_config(const std::string& text, const std::string& origin);

// "host" -> "host:7117"; "host:port", "[v6]:port" and gRPC target URIs
// ("dns:///host:port", "unix:/path") unchanged. Throws std::invalid_argument
// on an empty address.
std::string normalize_server(const std::string& address);

struct ConnectionSettings {
  std::string server;  // normalized
  std::string token;   // empty: none
  std::string ca;      // PEM root certificate file; empty: insecure channel
  // Where each came from, for messages: "--server", "ERG_SERVER",
  // "/home/me/.config/erg/config", "default".
  std::string server_origin, token_origin, ca_origin;
  std::vector<std::string> warnings;  // e.g. a token in a world-readable file
};

// Reads an environment variable; nullptr when unset. Tests pass their own.
using EnvLookup = std::function<const char*(const char*)>;

// The config file to read: $ERG_CONFIG (must exist) or
// $HOME/.config/erg/config (may be absent); second: true when it was named
// by $ERG_CONFIG.
std::pair<std::string, bool> config_path(const EnvLookup& env);

// Resolves every setting (see the top of this file). Throws
// std::invalid_argument on an unreadable $ERG_CONFIG or a bad config file.
ConnectionSettings resolve_connection(const ConnectionFlags& flags, const EnvLookup& env);

// The process environment.
EnvLookup process_env();

}  // namespace erg::client

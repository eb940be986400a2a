// SPDX-License-Identifier: Apache-2.0
// `ergd token new TENANT [--operator] [--tokens FILE]`: makes a random
// token, appends `TOKEN TENANT [operator]` to the tokens file (README,
// "Tokens and tenants") and prints the token, so that a new ergd or a new
// tenant needs no hand-made secret.
#pragma once

#include <string>
#include <vector>

namespace erg::server {

// The tokens file ergd's systemd unit reads (deploy/systemd/ergd.service.in).
inline constexpr const char* kDefaultTokensPath = "/etc/ergd/tokens";

// 24 bytes from getrandom(2) as 48 lowercase hex characters (192 bits).
std::string new_token();

// Appends `token tenant [operator]` to `path` atomically: the new file is
// written beside it and renamed over it, so ergd (which re-reads the file
// when it changes) sees the old or the new file, never half a line. A new
// file gets mode 0600; an existing one keeps its mode, owner and group (a
// `root:ergd 0640` file stays readable by ergd). Concurrent appends are
// serialised with flock(2) on the file's directory. Throws
// std::runtime_error naming the path and the system's reason.
void append_token(const std::string& path, const std::string& token, const std::string& tenant,
                  bool is_operator);

// The subcommand: args are what follows `ergd token`. Prints the token on
// stdout (and one line on stderr saying where it went); returns the exit
// status (0, 2 for bad arguments, 1 when the file cannot be written).
int token_command(const std::vector<std::string>& args);

}  // namespace erg::server

// SPDX-License-Identifier: Apache-2.0
// Arguments of the remote commands: positionals, flags with a value and
// switches, in any order. Part of erg_client_lib, unit-tested.
#pragma once

#include <map>
#include <set>
#include <string>
#include <vector>

namespace erg::client {

struct ParsedArgs {
  std::vector<std::string> positional;
  std::map<std::string, std::string> values;  // --flag VALUE (the last one wins)
  std::set<std::string> switches;             // --flag
  bool has(const std::string& flag) const { return values.count(flag) || switches.count(flag); }
};

// Throws std::invalid_argument naming the flag: an unknown flag, a flag
// without its value.
ParsedArgs parse_args(const std::vector<std::string>& args,
                      const std::set<std::string>& value_flags,
                      const std::set<std::string>& switch_flags);

// An integer in [lo, hi]; throws std::invalid_argument naming the flag.
long long parse_int_flag(const std::string& flag, const std::string& value, long long lo,
                         long long hi);

}  // namespace erg::client

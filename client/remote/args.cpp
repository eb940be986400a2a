// SPDX-License-Identifier: Apache-2.0
#include "remote/args.h"

#include <stdexcept>

namespace erg::client {

ParsedArgs parse_args(const std::vector<std::string>& args,
                      const std::set<std::string>& value_flags,
                      const std::set<std::string>& switch_flags) {
  ParsedArgs p;
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    if (a.size() > 1 && a[0] == '-') {
      if (value_flags.count(a)) {
        if (i + 1 >= args.size()) throw std::invalid_argument(a + ": missing value");
        p.values[a] = args[++i];
      } else if (switch_flags.count(a)) {
        p.switches.insert(a);
      } else {
        throw std::invalid_argument(a + ": unknown flag");
      }
    } else {
      p.positional.push_back(a);
    }
  }
  return p;
}

long long parse_int_flag(const std::string& flag, const std::string& value, long long lo,
                         long long hi) {
  size_t used = 0;
  long long x = 0;
  try {
    x = std::stoll(value, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (value.empty() || used != value.size() || x < lo || x > hi)
    throw std::invalid_argument(flag + " " + value + ": expected an integer in [" +
                                std::to_string(lo) + ", " + std::to_string(hi) + "]");
  return x;
}

}  // namespace erg::client

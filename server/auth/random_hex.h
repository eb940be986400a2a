// SPDX-License-Identifier: Apache-2.0
// Secrets ergd makes itself (tokens from `ergd token new`, dashboard session
// ids): `bytes` random bytes from getrandom(2), the kernel's CSPRNG, as
// 2 x bytes lowercase hex characters.
#pragma once

#include <sys/random.h>

#include <cerrno>
#include <cstddef>
#include <stdexcept>
#include <string>
#include <system_error>
#include <vector>

namespace erg::server {

inline std::string random_hex(std::size_t bytes) {
  std::vector<unsigned char> b(bytes);
  std::size_t got = 0;
  while (got < bytes) {
    const ssize_t n = ::getrandom(b.data() + got, bytes - got, 0);
    if (n < 0) {
      if (errno == EINTR) continue;
      throw std::runtime_error("getrandom: no random bytes: " +
                               std::generic_category().message(errno));
    }
    got += static_cast<std::size_t>(n);
  }
  static const char* hex = "0123456789abcdef";
  std::string s;
  s.reserve(2 * bytes);
  for (unsigned char c : b) {
    s += hex[c >> 4];
    s += hex[c & 15];
  }
  return s;
}

}  // namespace erg::server

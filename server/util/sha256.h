// SPDX-License-Identifier: Apache-2.0
// SHA-256 of files (OpenSSL), cached by (path, size, mtime): snapshots are
// written once and never change, so a file is hashed once however often it
// is fetched.
#pragma once

#include <string>

namespace erg::server {

std::string sha256_hex_of_file(const std::string& path);  // throws on I/O errors
std::string sha256_hex(const std::string& bytes);

}  // namespace erg::server

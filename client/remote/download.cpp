// SPDX-License-Identifier: Apache-2.0
#include "remote/download.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <vector>

#include "io/atomic_file.h"
#include "io/run_files.h"

namespace erg::client {

namespace fs = std::filesystem;

namespace {

std::string lower(std::string s) {
  for (auto& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

std::string errno_text() {
  return std::strerror(errno);
}

std::int64_t file_size_or_zero(const std::string& path) {
  std::error_code ec;
  const auto n = fs::file_size(path, ec);
  return ec ? 0 : static_cast<std::int64_t>(n);
}

}  // namespace

Sha256::Sha256() : ctx_(EVP_MD_CTX_new()) {
  if (!ctx_ || EVP_DigestInit_ex(ctx_, EVP_sha256(), nullptr) != 1)
    throw std::runtime_error("sha256: cannot initialise OpenSSL");
}

Sha256::~Sha256() {
  EVP_MD_CTX_free(ctx_);
}

void Sha256::update(const void* data, size_t n) {
  if (n > 0 && EVP_DigestUpdate(ctx_, data, n) != 1)
    throw std::runtime_error("sha256: update failed");
}

std::string Sha256::hex() {
  unsigned char md[EVP_MAX_MD_SIZE];
  unsigned int len = 0;
  if (EVP_DigestFinal_ex(ctx_, md, &len) != 1) throw std::runtime_error("sha256: final failed");
  static const char* const kHex = "0123456789abcdef";
  std::string out;
  for (unsigned int i = 0; i < len; ++i) {
    out += kHex[md[i] >> 4];
    out += kHex[md[i] & 15];
  }
  return out;
}

std::string sha256_of_file(const std::string& path, std::int64_t limit) {
  FILE* f = std::fopen(path.c_str(), "rb");
  if (!f) throw std::runtime_error("cannot read " + path + ": " + errno_text());
  Sha256 h;
  std::vector<char> buf(1 << 20);
  std::int64_t left = limit;
  for (;;) {
    size_t want = buf.size();
    if (left >= 0) want = static_cast<size_t>(std::min<std::int64_t>(left, want));
    if (want == 0) break;
    const size_t n = std::fread(buf.data(), 1, want, f);
    if (n == 0) break;
    h.update(buf.data(), n);
    if (left >= 0) left -= static_cast<std::int64_t>(n);
  }
  const bool bad = std::ferror(f) != 0 || left > 0;
  std::fclose(f);
  if (bad) throw std::runtime_error("cannot read " + path + " to the end");
  return h.hex();
}

bool is_plain_file_name(const std::string& name) {
  if (name.empty() || name == "." || name == ".." || name.size() > 255) return false;
  for (const char c : name)
    if (c == '/' || c == '\\' || static_cast<unsigned char>(c) < 0x20 || c == 0x7f) return false;
  return true;
}

std::string snapshot_file_name(std::int64_t step) {
  return step_name(step) + ".h5";
}

bool file_has_sha256(const std::string& path, const std::string& sha256) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) return false;
  try {
    return sha256_of_file(path) == lower(sha256);
  } catch (const std::exception&) {
    return false;
  }
}

PartialDownload::PartialDownload(std::string dir, std::string name)
    : dir_(std::move(dir)), name_(std::move(name)) {
  if (!is_plain_file_name(name_))
    throw std::invalid_argument("refusing the file name '" + name_ +
                                "' (it must be a plain name inside the output folder)");
}

PartialDownload::~PartialDownload() {
  close_part();
}

std::string PartialDownload::final_path() const {
  return (fs::path(dir_) / name_).string();
}
std::string PartialDownload::part_path() const {
  return final_path() + ".part";
}
std::string PartialDownload::sha_path() const {
  return part_path() + ".sha256";
}

std::int64_t PartialDownload::resume_offset() const {
  return file_size_or_zero(part_path());
}

void PartialDownload::close_part() {
  if (part_) std::fclose(part_);
  part_ = nullptr;
}

PartialDownload::Start PartialDownload::start(std::int64_t requested_offset, std::int64_t size,
                                              const std::string& sha256) {
  close_part();
  size_ = size;
  sha256_ = lower(sha256);
  discarded_ = false;
  std::error_code ec;
  const bool had_part = fs::exists(part_path(), ec);
  std::int64_t held = file_size_or_zero(part_path());
  std::string recorded;
  if (std::ifstream in(sha_path()); in) in >> recorded;
  if (had_part && ((!recorded.empty() && lower(recorded) != sha256_) || held > size)) {
    fs::remove(part_path(), ec);  // another file's, or longer than this one
    held = 0;
    discarded_ = true;
  }
  if (requested_offset != held) {
    if (requested_offset != 0) return Start::kRestart;
    held = 0;  // the server sends everything anyway
  }
  {
    std::ofstream out(sha_path(), std::ios::trunc);
    out << sha256_ << "\n";
    if (!out) throw std::runtime_error("cannot write " + sha_path());
  }
  hash_ = std::make_unique<Sha256>();
  if (held > 0) {
    // Hash the bytes already here, so the digest covers the whole file.
    FILE* f = std::fopen(part_path().c_str(), "rb");
    if (!f) throw std::runtime_error("cannot read " + part_path() + ": " + errno_text());
    std::vector<char> buf(1 << 20);
    std::int64_t left = held;
    while (left > 0) {
      const size_t n = std::fread(buf.data(), 1,
                                  static_cast<size_t>(std::min<std::int64_t>(left, buf.size())), f);
      if (n == 0) break;
      hash_->update(buf.data(), n);
      left -= static_cast<std::int64_t>(n);
    }
    std::fclose(f);
    if (left != 0) throw std::runtime_error("cannot read " + part_path() + " to the end");
  }
  // Append at `held`: truncate anything beyond it (nothing, unless the
  // server was asked for 0 with a .part present).
  part_ = std::fopen(part_path().c_str(), held > 0 ? "r+b" : "wb");
  if (!part_) throw std::runtime_error("cannot write " + part_path() + ": " + errno_text());
  if (held > 0 && ::fseeko(part_, static_cast<off_t>(held), SEEK_SET) != 0)
    throw std::runtime_error("cannot seek in " + part_path() + ": " + errno_text());
  bytes_ = held;
  return Start::kGo;
}

void PartialDownload::append(std::int64_t offset, const void* data, size_t n) {
  if (!part_) throw std::runtime_error("internal: append before start");
  if (offset != bytes_)
    throw std::runtime_error("the server sent bytes at offset " + std::to_string(offset) + " of " +
                             name_ + ", expected " + std::to_string(bytes_));
  if (bytes_ + static_cast<std::int64_t>(n) > size_)
    throw std::runtime_error("the server sent more than the announced " + std::to_string(size_) +
                             " bytes of " + name_);
  if (n == 0) return;
  if (std::fwrite(data, 1, n, part_) != n)
    throw std::runtime_error("cannot write " + part_path() + ": " + errno_text());
  hash_->update(data, n);
  bytes_ += static_cast<std::int64_t>(n);
}

void PartialDownload::finish() {
  if (!part_) throw std::runtime_error("internal: finish before start");
  if (!complete())
    throw std::runtime_error(name_ + ": have " + std::to_string(bytes_) + " of " +
                             std::to_string(size_) + " bytes");
  const bool flushed = std::fflush(part_) == 0;  // synced by replace_durably below
  close_part();
  if (!flushed) throw std::runtime_error("cannot write " + part_path() + ": " + errno_text());
  const std::string got = hash_->hex();
  std::error_code ec;
  if (got != sha256_) {
    fs::remove(part_path(), ec);
    fs::remove(sha_path(), ec);
    throw std::runtime_error("sha256 mismatch for " + name_ + ": the server announced " + sha256_ +
                             ", the " + std::to_string(bytes_) + " bytes received hash to " + got +
                             "; deleted " + part_path() + " (run erg fetch again)");
  }
  io::replace_durably(part_path(), final_path());
  fs::remove(sha_path(), ec);
}

}  // namespace erg::client

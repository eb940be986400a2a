// SPDX-License-Identifier: Apache-2.0
// The bookkeeping of `erg fetch`: a snapshot is downloaded into DIR/NAME.part
// next to DIR/NAME.part.sha256 (the sha256 the server announced), resumed
// from the .part's size after an interruption, checked against the sha256
// and renamed to DIR/NAME when complete, so DIR/NAME is always a whole,
// verified file. Part of erg_client_lib (no gRPC), unit-tested.
#pragma once

#include <openssl/evp.h>

#include <cstdint>
#include <cstdio>
#include <memory>
#include <string>

namespace erg::client {

// Incremental sha256 (OpenSSL EVP); hex() ends it.
class Sha256 {
 public:
  Sha256();
  ~Sha256();
  Sha256(const Sha256&) = delete;
  Sha256& operator=(const Sha256&) = delete;
  void update(const void* data, size_t n);
  std::string hex();  // lowercase hex digest

 private:
  EVP_MD_CTX* ctx_;
};

// The sha256 of the first `limit` bytes of a file (all of it when
// limit < 0), lowercase hex. Throws std::runtime_error when unreadable.
std::string sha256_of_file(const std::string& path, std::int64_t limit = -1);

// True for a name that stays inside its folder: not empty, no '/', not "."
// or "..", no NUL or control characters. A server's file names are checked
// with it before anything is written.
bool is_plain_file_name(const std::string& name);

// The name ergd gives the snapshot of `step`: "step_00000100.h5" (README,
// Outputs). Used to find a .part before the server has named the file.
std::string snapshot_file_name(std::int64_t step);

// True when DIR/NAME exists and has this sha256 (hex, any case).
bool file_has_sha256(const std::string& path, const std::string& sha256);

class PartialDownload {
 public:
  // Throws std::invalid_argument when `name` is not a plain file name.
  PartialDownload(std::string dir, std::string name);
  ~PartialDownload();
  PartialDownload(const PartialDownload&) = delete;
  PartialDownload& operator=(const PartialDownload&) = delete;

  const std::string& name() const { return name_; }
  std::string final_path() const;
  std::string part_path() const;
  std::string sha_path() const;  // NAME.part.sha256

  // Bytes already in DIR/NAME.part (0 when there is none): the offset to ask
  // the server for.
  std::int64_t resume_offset() const;

  enum class Start {
    kGo,       // append from `requested_offset`
    kRestart,  // the .part cannot be continued from that offset; ask again
               // from resume_offset() (0 when the .part was discarded)
  };
  // The server's first message announced a file of `size` bytes with this
  // sha256, sending from `requested_offset`. Discards a .part of another file
  // (its recorded sha256 differs) or longer than `size`; opens the .part for
  // appending and hashes what it holds. Throws std::runtime_error on I/O
  // errors.
  Start start(std::int64_t requested_offset, std::int64_t size, const std::string& sha256);
  // True when start() threw away an old .part.
  bool discarded() const { return discarded_; }

  // Appends data that the server says starts at `offset`; throws
  // std::runtime_error when that is not where the .part ends or the data
  // runs past the announced size.
  void append(std::int64_t offset, const void* data, size_t n);
  std::int64_t bytes() const { return bytes_; }
  std::int64_t size() const { return size_; }
  bool complete() const { return size_ >= 0 && bytes_ == size_; }

  // With every byte here: checks the sha256 and renames DIR/NAME.part to
  // DIR/NAME (atomically, replacing an older DIR/NAME). On a mismatch the
  // .part is deleted and std::runtime_error says so.
  void finish();

 private:
  void close_part();
  std::string dir_, name_;
  FILE* part_ = nullptr;
  std::unique_ptr<Sha256> hash_;
  std::int64_t bytes_ = 0;
  std::int64_t size_ = -1;
  std::string sha256_;
  bool discarded_ = false;
};

}  // namespace erg::client

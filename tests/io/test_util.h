// SPDX-License-Identifier: Apache-2.0
// Helpers shared by the erg_io tests: a scratch directory per test, file
// bytes, a file-size limit that makes writes fail midway, and a PNG decoder
// independent of the code under test (libpng's simplified API).
#pragma once

#include <gtest/gtest.h>
#include <png.h>
#include <sys/resource.h>
#include <unistd.h>

#include <csignal>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <set>
#include <string>
#include <vector>

#include "../common/temp_dir.h"

namespace erg::io::testing {

namespace fs = std::filesystem;

struct TempDir : erg::test_support::TempDir {
  TempDir() : erg::test_support::TempDir("erg_io_test") {}
};

inline std::string read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

inline void write_bytes(const std::string& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

// While alive, files this process writes cannot grow past `bytes`: a write
// beyond fails with EFBIG (SIGXFSZ, which would kill us, is ignored). This
// makes a writer fail for real in the middle of its output.
class FileSizeLimit {
 public:
  explicit FileSizeLimit(rlim_t bytes) {
    getrlimit(RLIMIT_FSIZE, &old_);
    old_handler_ = std::signal(SIGXFSZ, SIG_IGN);
    rlimit r = old_;
    r.rlim_cur = bytes;
    setrlimit(RLIMIT_FSIZE, &r);
  }
  ~FileSizeLimit() {
    setrlimit(RLIMIT_FSIZE, &old_);
    std::signal(SIGXFSZ, old_handler_);
  }
  FileSizeLimit(const FileSizeLimit&) = delete;
  FileSizeLimit& operator=(const FileSizeLimit&) = delete;

 private:
  rlimit old_{};
  void (*old_handler_)(int) = SIG_DFL;
};

// A decoded PNG: `format` is what the file holds (PNG_FORMAT_RGB for 8-bit
// RGB, PNG_FORMAT_LINEAR_Y for 16-bit grey, ...); pixels are in `format`.
struct DecodedPng {
  bool ok = false;
  std::uint32_t width = 0, height = 0, format = 0;
  std::vector<std::uint8_t> bytes;  // row-major, top row first
};

inline DecodedPng decode_png(const std::string& path) {
  DecodedPng out;
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_file(&image, path.c_str())) return out;
  out.width = image.width;
  out.height = image.height;
  out.format = image.format;
  out.bytes.resize(PNG_IMAGE_SIZE(image));
  if (!png_image_finish_read(&image, nullptr, out.bytes.data(), 0, nullptr)) return out;
  out.ok = true;
  return out;
}

}  // namespace erg::io::testing

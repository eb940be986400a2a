// SPDX-License-Identifier: Apache-2.0
// A fresh scratch directory for one test, removed with everything in it
// afterwards. The name carries the pid and the test's name, so ctest -j runs
// never collide. Shared by every test folder.
#pragma once

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <set>
#include <string>

namespace erg::test_support {

class TempDir {
 public:
  explicit TempDir(const std::string& prefix = "erg_test") {
    namespace fs = std::filesystem;
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    std::string name = prefix + "_" + std::to_string(::getpid()) + "_" +
                       (info ? std::string(info->test_suite_name()) + "_" + info->name() : "x");
    for (auto& c : name)
      if (c == '/') c = '_';
    path_ = fs::temp_directory_path() / name;
    fs::remove_all(path_);
    fs::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;

  std::string file(const std::string& name) const { return (path_ / name).string(); }
  std::string operator/(const std::string& name) const { return file(name); }
  const std::filesystem::path& path() const { return path_; }
  std::string str() const { return path_.string(); }

  // Names of the directory's entries, sorted.
  std::set<std::string> entries() const {
    std::set<std::string> names;
    for (const auto& e : std::filesystem::directory_iterator(path_))
      names.insert(e.path().filename().string());
    return names;
  }
  // True when some entry looks like an erg temporary ("<name>.tmp-<pid>").
  bool has_temporaries() const {
    for (const auto& n : entries())
      if (n.find(".tmp-") != std::string::npos) return true;
    return false;
  }

 private:
  std::filesystem::path path_;
};

}  // namespace erg::test_support

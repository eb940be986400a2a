// SPDX-License-Identifier: Apache-2.0
// Where a program finds the files erg ships beside it. `cmake --install
// --prefix P` puts the programs in P/bin and their data (the Slurm script
// template, the validation scenes, the examples) in P/share/erg, so an
// installed program looks there first, next to itself: it must not read the
// source tree it was built from, which may have changed or be gone. A
// program run from the build tree has no share/erg beside it and uses the
// source-tree path compiled into it.
#pragma once

#include <filesystem>
#include <string>

namespace erg::io {

// The running program's own path (/proc/self/exe), empty if unknown.
inline std::filesystem::path program_path() {
  std::error_code ec;
  const std::filesystem::path self = std::filesystem::read_symlink("/proc/self/exe", ec);
  return ec ? std::filesystem::path() : self;
}

// The directory of the running program, empty if unknown.
inline std::filesystem::path program_dir() {
  return program_path().parent_path();
}

// The program NAME installed beside the running one (erg and ergd start
// erg-worker from there), else NAME alone, for PATH to find.
inline std::string sibling_program(const std::string& name) {
  const std::filesystem::path dir = program_dir();
  std::error_code ec;
  if (!dir.empty() && std::filesystem::exists(dir / name, ec)) return (dir / name).string();
  return name;
}

// PROGRAM_DIR/../share/erg/RELATIVE when it exists, else BUILD_TREE_PATH.
inline std::string shipped_file(const std::string& relative, const std::string& build_tree_path) {
  const std::filesystem::path dir = program_dir();
  if (!dir.empty()) {
    const std::filesystem::path p = dir.parent_path() / "share" / "erg" / relative;
    std::error_code ec;
    if (std::filesystem::exists(p, ec)) return p.string();
  }
  return build_tree_path;
}

}  // namespace erg::io

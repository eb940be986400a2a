// SPDX-License-Identifier: Apache-2.0
// erg validate: runs the fixed scenes of client/validate/scenes/ with
// erg-worker and measures laws of geomorphology on their heightfields
// (barchan speed and shape, slip faces, transverse dunes, mass, migration
// rate), writing DIR/report.md with plots. The suite itself lives in Python
// (client/validate/validate.py, measure.py: numpy, scipy, h5py,
// matplotlib from Debian's /usr/bin/python3); this command finds it and the
// worker and hands over.
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

#include "commands.h"
#include "io/install_paths.h"

namespace erg::client {

namespace {

namespace fs = std::filesystem;

// $ERG_VALIDATE_DIR, else the installed share/erg/validate next to the
// binary, else the source tree's client/validate (compiled in, for a build
// tree's erg, as the tests find examples/).
std::string validate_dir() {
  if (const char* env = std::getenv("ERG_VALIDATE_DIR"); env && *env) return env;
  return io::shipped_file("validate", ERG_VALIDATE_DIR);
}

}  // namespace

int cmd_validate(const std::vector<std::string>& args) {
  bool has_out = false;
  for (size_t i = 0; i < args.size(); ++i) {
    if (args[i] == "--out" && i + 1 < args.size()) has_out = true;
    if (args[i] == "--help" || args[i] == "-h") {
      std::cout << usage_of("validate");
      return 0;
    }
  }
  if (!has_out) {
    std::cerr << "erg validate: --out DIR is required\n" << usage_of("validate");
    return 2;
  }
  const std::string dir = validate_dir();
  const std::string script = (fs::path(dir) / "validate.py").string();
  if (!fs::exists(script)) {
    std::cerr << "erg validate: cannot find " << script << " (set ERG_VALIDATE_DIR)\n";
    return 1;
  }
  // Debian's interpreter owns python3-h5py/-scipy/-matplotlib (docs/design.md,
  // "Platform notes").
  const char* py_env = std::getenv("ERG_PYTHON");
  std::string python = py_env ? py_env : "/usr/bin/python3";
  const std::string self = io::program_path().string();
  std::vector<std::string> argv_s = {python, script, "--worker", worker_path()};
  if (!self.empty()) argv_s.insert(argv_s.end(), {"--erg", self});
  argv_s.insert(argv_s.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (auto& a : argv_s) argv.push_back(a.data());
  argv.push_back(nullptr);
  ::execv(argv[0], argv.data());
  std::fprintf(stderr, "erg validate: cannot start %s: %s\n", argv[0], std::strerror(errno));
  return 1;
}

}  // namespace erg::client

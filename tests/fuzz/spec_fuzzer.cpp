// SPDX-License-Identifier: Apache-2.0
// libFuzzer target: random bytes as a job file, through everything a job file
// meets before a run starts (erg check, erg run, erg-worker, later ergd):
// parse_json, apply_defaults, validate, to_json.
//
// What must hold for every input:
//   * parse_json either returns a spec or throws SpecError (with at least one
//     problem); no other exception, no crash, no undefined behaviour;
//   * apply_defaults is idempotent;
//   * validate and to_json never throw;
//   * every parsed spec survives the round trip: parse_json(to_json(spec)) is
//     the same message; a spec that validates validates again.
// AddressSanitizer, UndefinedBehaviorSanitizer and libFuzzer's leak, timeout
// and RSS checks catch the rest (tests/fuzz/CMakeLists.txt).
//
// No file is read: map paths are resolved against a directory that does not
// exist, and the two map readers spec.cpp calls are replaced below by ones
// that only report an error, so a path like "/dev/stdin" or "/dev/zero" in a
// fuzzed spec can neither block nor allocate without bound.
#include <google/protobuf/util/field_comparator.h>
#include <google/protobuf/util/message_differencer.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <string>
#include <vector>

#include "io/io.h"
#include "job/spec.h"

namespace erg::io {

// The readers validate() calls for a map file that exists. They stand in for
// erg_io's (which are not linked into the fuzzer); the problem they cause is
// the one an unreadable file would.
Map read_hdf5_map(const std::string& path, const std::string& dataset) {
  throw IoError(path + ": dataset " + dataset + ": map files are not read by the spec fuzzer");
}

Map read_png_map(const std::string& path) {
  throw IoError(path + ": map files are not read by the spec fuzzer");
}

Map read_gdal_map(const std::string& path) {
  throw IoError(path + ": map files are not read by the spec fuzzer");
}

Map read_exr_map(const std::string& path) {
  throw IoError(path + ": map files are not read by the spec fuzzer");
}

}  // namespace erg::io

namespace {

using erg::job::JobSpec;
using google::protobuf::util::MessageDifferencer;

// Relative map paths resolve under here; nothing is ever created there.
constexpr const char* kNoDir = "/nonexistent/erg-spec-fuzzer";

[[noreturn]] void fail(const std::string& what, const std::string& detail) {
  std::fprintf(stderr, "spec_fuzzer: %s\n%s\n", what.c_str(), detail.c_str());
  std::abort();
}

// Equal field by field, presence included; NaN equals NaN (a spec with a
// NaN is invalid, but must still print and read back).
bool same(const JobSpec& a, const JobSpec& b) {
  google::protobuf::util::DefaultFieldComparator numbers;
  numbers.set_treat_nan_as_equal(true);
  MessageDifferencer diff;
  diff.set_field_comparator(&numbers);
  return diff.Compare(a, b);
}

std::string join(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& p : v) s += p + "\n";
  return s;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);

  JobSpec spec;
  try {
    spec = erg::job::parse_json(text, "fuzz");
  } catch (const erg::job::SpecError& e) {
    if (e.problems().empty()) fail("parse_json threw a SpecError without a problem", text);
    return 0;
  }
  // Any other exception leaves this function: libFuzzer reports it as a crash.

  erg::job::apply_defaults(spec);
  JobSpec twice = spec;
  erg::job::apply_defaults(twice);
  if (!same(spec, twice)) fail("apply_defaults is not idempotent", erg::job::to_json(spec));

  const std::vector<std::string> problems = erg::job::validate(spec, kNoDir);
  const std::string json = erg::job::to_json(spec);

  // What `erg check` prints, and what a snapshot or a checkpoint records,
  // must read back as the same job (valid or not: NaN equals NaN here).
  if (json.empty()) fail("to_json printed nothing", text);
  JobSpec back;
  try {
    back = erg::job::parse_json(json, "round trip");
  } catch (const erg::job::SpecError& e) {
    fail("the canonical JSON does not parse: " + std::string(e.what()), json);
  }
  if (!same(spec, back))
    fail("parse_json(to_json(spec)) != spec", json + "\nread back as\n" + erg::job::to_json(back));
  if (!problems.empty()) return 0;
  const std::vector<std::string> again = erg::job::validate(back, kNoDir);
  if (!again.empty())
    fail("a valid spec is invalid after the round trip", json + "\n" + join(again));
  return 0;
}

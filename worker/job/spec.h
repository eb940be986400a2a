// SPDX-License-Identifier: Apache-2.0
// Job specs: parse the protobuf-JSON job file, fill defaults, validate.
//
// Defaults, ranges and units come from the (erg.v1.spec) options in
// proto/erg/v1/job.proto; this code only walks them. The CLI, the server and
// the worker call the same functions, so a spec means the same everywhere.
#pragma once

#include <stdexcept>
#include <string>
#include <vector>

#include "erg/v1/job.pb.h"

namespace erg::job {

using erg::v1::JobSpec;

// A spec that cannot be used. what() lists every problem, one per line, each
// naming the field (as a path like "wind.rose.entries[1].probability"), its
// value and the allowed range.
class SpecError : public std::runtime_error {
 public:
  explicit SpecError(std::vector<std::string> problems);
  const std::vector<std::string>& problems() const { return problems_; }

 private:
  std::vector<std::string> problems_;
};

// Parses JSON text (no defaults, no validation). `origin` names the text in
// error messages (a file name). Throws SpecError on syntax errors, unknown
// fields and unknown enum names.
JobSpec parse_json(const std::string& text, const std::string& origin = "job");

// Same, collecting every problem (unknown fields with the closest name, enum
// values not in the schema with the allowed ones, values of the wrong type)
// instead of throwing: the spec returned holds what could be parsed.
JobSpec parse_json_collect(const std::string& text, std::vector<std::string>& problems);

// Fills every absent field that has a default (recursively). Idempotent.
void apply_defaults(JobSpec& spec);

// Every problem with a defaults-filled spec; empty when it is valid. Relative
// map paths are resolved against base_dir (the job file's directory); map
// files are opened to check they exist and have the domain's size.
std::vector<std::string> validate(const JobSpec& spec, const std::string& base_dir = ".");

// Reads, parses, fills defaults and validates a job file; throws SpecError.
JobSpec load_job_file(const std::string& path);

// Directory of a job file (for relative map paths).
std::string base_dir_of(const std::string& job_path);

// Canonical JSON (proto field names, defaults included, indented).
std::string to_json(const JobSpec& spec);

// The same for people to read (erg check): 64-bit integers as JSON numbers
// (protobuf's JSON writes them as strings); parses back to the same spec.
std::string to_readable_json(const JobSpec& spec);

// Overrides shared by `erg run`, `erg submit` and erg-worker.
struct Overrides {
  long long steps = -1;           // --steps
  long long snapshot_every = -1;  // --snapshot-every
  long long checkpoint_every = -1;
};
void apply_overrides(JobSpec& spec, const Overrides& o);

// Resolved path of a map file named in the spec.
std::string resolve_path(const std::string& path, const std::string& base_dir);

// Human-readable table of every parameter (field path, default, range, unit,
// source): `erg params`, and the README table.
std::string parameter_table_markdown();

}  // namespace erg::job

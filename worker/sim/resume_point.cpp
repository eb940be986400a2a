// SPDX-License-Identifier: Apache-2.0
#include "sim/resume_point.h"

#include <google/protobuf/util/field_comparator.h>
#include <google/protobuf/util/message_differencer.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>

#include "io/io.h"
#include "job/spec.h"

namespace erg {

namespace fs = std::filesystem;
namespace pb = google::protobuf;

namespace {

// The first difference as a field path with both values; the differencer's
// report is one line per difference ("modified: model.x: 50 --> 54").
std::string first_difference(const pb::Message& a, const pb::Message& b) {
  std::string report;
  pb::util::MessageDifferencer d;
  d.ReportDifferencesToString(&report);
  if (d.Compare(a, b)) return "";
  std::string line = report.substr(0, report.find('\n'));
  if (line.size() > 300) line = line.substr(0, 300) + "...";
  return line;
}

std::string read_text(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read " + path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

}  // namespace

std::string spec_difference(const erg::v1::JobSpec& checkpoint, const erg::v1::JobSpec& recorded) {
  for (int k = 0; k < checkpoint.events_size(); ++k) {
    if (k >= recorded.events_size())
      return "events: the checkpoint has " + std::to_string(checkpoint.events_size()) +
             ", job.json only " + std::to_string(recorded.events_size());
    const std::string d = first_difference(checkpoint.events(k), recorded.events(k));
    if (!d.empty()) return "events[" + std::to_string(k) + "] (checkpoint vs job.json): " + d;
  }
  erg::v1::JobSpec a = checkpoint, b = recorded;
  for (erg::v1::JobSpec* s : {&a, &b}) {
    s->clear_events();
    s->mutable_run()->clear_steps();
    s->mutable_run()->clear_snapshot_every();
    s->mutable_run()->clear_checkpoint_every();
  }
  const std::string d = first_difference(a, b);
  return d.empty() ? "" : d + " (checkpoint vs job.json)";
}

ResumePoint choose_resume_point(const std::string& out_dir) {
  ResumePoint out;
  const fs::path dir = fs::path(out_dir) / "checkpoints";
  std::vector<std::string> all;
  std::error_code ec;
  for (auto it = fs::directory_iterator(dir, ec); !ec && it != fs::end(it); it.increment(ec)) {
    const fs::path& p = it->path();
    if (p.extension() == ".h5" && p.filename().string().rfind("step_", 0) == 0)
      all.push_back(p.string());
  }
  std::sort(all.rbegin(), all.rend());
  if (all.empty()) return out;

  // The run's record. Without one (a directory copied without it) there is
  // nothing to compare with and the checksums alone decide.
  const std::string job_json = out_dir + "/job.json";
  std::optional<erg::v1::JobSpec> recorded;
  std::string record_problem;
  if (fs::exists(job_json)) {
    try {
      recorded = job::parse_json(read_text(job_json), job_json);
      job::apply_defaults(*recorded);
    } catch (const std::exception& e) {
      record_problem = std::string("the run's record ") + job_json + " is unreadable: " + e.what();
    }
  }
  for (const std::string& p : all) {
    const std::string name = fs::path(p).filename().string();
    try {
      if (!record_problem.empty()) throw std::runtime_error(record_problem);
      const io::Checkpoint c = io::read_checkpoint(p);  // verifies the checksums
      erg::v1::JobSpec spec = job::parse_json(c.job_spec_json, p + " (job_spec)");
      job::apply_defaults(spec);
      if (recorded) {
        const std::string diff = spec_difference(spec, *recorded);
        if (!diff.empty())
          throw std::runtime_error("its spec disagrees with the run's job.json: " + diff);
        *spec.mutable_events() = recorded->events();
      }
      out.path = p;
      out.step = c.step;
      out.spec = std::move(spec);
      return out;
    } catch (const std::exception& e) {
      std::string why = e.what();
      // The file's path is in the message already; say it once.
      if (why.rfind(p + ": ", 0) == 0) why = why.substr(p.size() + 2);
      out.skipped.push_back(name + ": " + why);
    }
  }
  return out;
}

}  // namespace erg

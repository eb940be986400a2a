// SPDX-License-Identifier: Apache-2.0
#include "remote/common.h"

#include <google/protobuf/util/json_util.h>

#include <cctype>
#include <cstdio>
#include <ctime>
#include <iostream>

#include "commands.h"
#include "core/units.h"
#include "progress_bar.h"

namespace erg::client {

int usage_error(const std::string& command, const std::string& problem) {
  std::cerr << "erg: " << command << ": " << problem << "\n" << usage_of(command);
  return 2;
}

std::string state_name(erg::v1::JobState s) {
  return erg::v1::JobState_Name(s);
}

bool is_final(erg::v1::JobState s) {
  return s == erg::v1::SUCCEEDED || s == erg::v1::FAILED || s == erg::v1::CANCELLED;
}

bool parse_state(const std::string& text, erg::v1::JobState* out) {
  std::string up;
  for (const char c : text) up += static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  erg::v1::JobState s{};
  if (!erg::v1::JobState_Parse(up, &s) || s == erg::v1::JOB_STATE_UNSPECIFIED) return false;
  *out = s;
  return true;
}

std::string fmt_time_ms(std::int64_t unix_ms) {
  if (unix_ms <= 0) return "-";
  const std::time_t t = static_cast<std::time_t>(unix_ms / 1000);
  std::tm tm{};
  localtime_r(&t, &tm);
  char buf[64];
  std::strftime(buf, sizeof buf, "%Y-%m-%d %H:%M:%S", &tm);
  return buf;
}

std::string to_json(const google::protobuf::Message& m, bool indent, bool all_fields) {
  google::protobuf::util::JsonPrintOptions opts;
  opts.add_whitespace = indent;
  opts.preserve_proto_field_names = true;
  opts.always_print_primitive_fields = all_fields;
  std::string out;
  (void)google::protobuf::util::MessageToJsonString(m, &out, opts);
  while (!out.empty() && out.back() == '\n') out.pop_back();
  return out;
}

std::string progress_text(const erg::v1::Progress& p) {
  const double frac = p.total_steps() > 0
                          ? static_cast<double>(p.step()) / static_cast<double>(p.total_steps())
                          : 0.0;
  char buf[200];
  std::snprintf(buf, sizeof buf, "step %lld/%lld (%d%%), %.2f steps/s, ETA %s",
                static_cast<long long>(p.step()), static_cast<long long>(p.total_steps()),
                static_cast<int>(frac * 100), p.steps_per_s(), fmt_duration(p.eta_s()).c_str());
  std::string out = buf;
  if (p.time_years() > 0) {
    std::snprintf(buf, sizeof buf, ", %.3g simulated years", p.time_years());
    out += buf;
  }
  return out;
}

std::string sand_volume_text(const std::string& units, double cell_size_m) {
  // The total may exceed 2^63 units; m³ need no more than a double's digits.
  const double v = std::strtod(units.c_str(), nullptr) * erg::kUnitM * cell_size_m * cell_size_m;
  char buf[64];
  std::snprintf(buf, sizeof buf, v >= 1e6 || (v > 0 && v < 0.01) ? "%.3e m³" : "%.2f m³", v);
  return buf;
}

std::string sand_text(const erg::v1::Progress& p, double cell_size_m) {
  if (p.sand_units_total().empty()) return "";
  if (!(cell_size_m > 0)) return p.sand_units_total() + " units of 2^-32 m x cell area";
  std::string t = sand_volume_text(p.sand_units_total(), cell_size_m) + " on the ground";
  std::string exact = p.sand_units_total();
  if (!p.airborne_units_total().empty()) {
    t += " + " + sand_volume_text(p.airborne_units_total(), cell_size_m) + " airborne";
    exact += " + " + p.airborne_units_total();
  }
  return t + " [" + exact + " units of 2^-32 m x cell area]";
}

std::string steps_text(const google::protobuf::RepeatedField<std::int64_t>& steps) {
  if (steps.empty()) return "none yet";
  const int n = steps.size();
  std::string t = n == 1 ? "at step " : "at steps ";
  for (int k = 0; k < n; ++k) {
    if (n > 8 && k == 4) {
      t += ", ...";
      k = n - 3;  // the last three follow
    }
    t += (k == 0 ? "" : ", ") + std::to_string(steps[k]);
  }
  if (n > 8) t += " (" + std::to_string(n) + " in all)";
  return t;
}

std::string worker_text(const erg::v1::Job& job) {
  if (job.launcher_id().empty()) return "";
  if (job.launcher() == "slurm")
    return "Slurm job " + job.launcher_id() +
           (job.launcher_state().empty() ? "" : " (" + job.launcher_state() + ")");
  return "pid " + job.launcher_id() + " on " +
         (job.launcher_host().empty() ? std::string("ergd's machine") : job.launcher_host());
}

}  // namespace erg::client

#include "remote/common.h"

#include <google/protobuf/util/json_util.h>

#include <cctype>
#include <cstdio>
#include <ctime>
#include <iostream>

#include "commands.h"
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
  return buf;
}

}  // namespace erg::client

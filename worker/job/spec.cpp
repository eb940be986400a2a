// SPDX-License-Identifier: Apache-2.0
#include "job/spec.h"

#include <google/protobuf/descriptor.h>
#include <google/protobuf/struct.pb.h>
#include <google/protobuf/util/json_util.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <system_error>

#include "io/io.h"
#include "job/map_file.h"
#include "stages/wind_warping.h"

namespace erg::job {

namespace pb = google::protobuf;
namespace fs = std::filesystem;

namespace {

std::string join_lines(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& p : v) s += (s.empty() ? "" : "\n") + p;
  return s;
}

// Whole numbers in full ("10", "1000000000", not "1e+01"), anything else as
// the shortest text that reads back as the same double. std::to_chars never
// throws (std::stod did, on subnormal values).
std::string num(double v) {
  if (std::isnan(v)) return "nan";
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  char buf[64];
  const bool whole = v == std::trunc(v) && std::fabs(v) < 1e16;
  const auto res = whole ? std::to_chars(buf, buf + sizeof buf, v, std::chars_format::fixed)
                         : std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, res.ptr);
}

const erg::v1::FieldSpec& spec_of(const pb::FieldDescriptor* f) {
  return f->options().GetExtension(erg::v1::spec);
}

bool is_numeric(const pb::FieldDescriptor* f) {
  switch (f->cpp_type()) {
    case pb::FieldDescriptor::CPPTYPE_DOUBLE:
    case pb::FieldDescriptor::CPPTYPE_FLOAT:
    case pb::FieldDescriptor::CPPTYPE_INT32:
    case pb::FieldDescriptor::CPPTYPE_INT64:
    case pb::FieldDescriptor::CPPTYPE_UINT32:
    case pb::FieldDescriptor::CPPTYPE_UINT64:
      return true;
    default:
      return false;
  }
}

double get_number(const pb::Message& m, const pb::FieldDescriptor* f) {
  const pb::Reflection* r = m.GetReflection();
  switch (f->cpp_type()) {
    case pb::FieldDescriptor::CPPTYPE_DOUBLE:
      return r->GetDouble(m, f);
    case pb::FieldDescriptor::CPPTYPE_FLOAT:
      return r->GetFloat(m, f);
    case pb::FieldDescriptor::CPPTYPE_INT32:
      return r->GetInt32(m, f);
    case pb::FieldDescriptor::CPPTYPE_INT64:
      return static_cast<double>(r->GetInt64(m, f));
    case pb::FieldDescriptor::CPPTYPE_UINT32:
      return r->GetUInt32(m, f);
    case pb::FieldDescriptor::CPPTYPE_UINT64:
      return static_cast<double>(r->GetUInt64(m, f));
    default:
      return 0;
  }
}

void set_default(pb::Message& m, const pb::FieldDescriptor* f, double v) {
  const pb::Reflection* r = m.GetReflection();
  switch (f->cpp_type()) {
    case pb::FieldDescriptor::CPPTYPE_DOUBLE:
      r->SetDouble(&m, f, v);
      break;
    case pb::FieldDescriptor::CPPTYPE_FLOAT:
      r->SetFloat(&m, f, static_cast<float>(v));
      break;
    case pb::FieldDescriptor::CPPTYPE_INT32:
      r->SetInt32(&m, f, static_cast<int32_t>(v));
      break;
    case pb::FieldDescriptor::CPPTYPE_INT64:
      r->SetInt64(&m, f, static_cast<int64_t>(v));
      break;
    case pb::FieldDescriptor::CPPTYPE_UINT32:
      r->SetUInt32(&m, f, static_cast<uint32_t>(v));
      break;
    case pb::FieldDescriptor::CPPTYPE_UINT64:
      r->SetUInt64(&m, f, static_cast<uint64_t>(v));
      break;
    case pb::FieldDescriptor::CPPTYPE_BOOL:
      r->SetBool(&m, f, v != 0);
      break;
    default:
      break;
  }
}

void defaults_rec(pb::Message& m) {
  const pb::Descriptor* d = m.GetDescriptor();
  const pb::Reflection* r = m.GetReflection();
  for (int i = 0; i < d->field_count(); ++i) {
    const pb::FieldDescriptor* f = d->field(i);
    if (f->cpp_type() == pb::FieldDescriptor::CPPTYPE_MESSAGE) {
      if (f->is_repeated()) {
        for (int k = 0; k < r->FieldSize(m, f); ++k)
          defaults_rec(*r->MutableRepeatedMessage(&m, f, k));
      } else if (r->HasField(m, f)) {
        // Only messages the user wrote: the presence of a layer source or a
        // wind regime is meaningful and must not be invented here.
        defaults_rec(*r->MutableMessage(&m, f));
      }
      continue;
    }
    if (f->is_repeated()) continue;
    const auto& s = spec_of(f);
    // An enum at 0 (*_UNSPECIFIED) or an empty string outside a oneof means
    // the value the proto names (FieldSpec.default_text).
    if (!s.default_text().empty() && !f->real_containing_oneof()) {
      if (f->cpp_type() == pb::FieldDescriptor::CPPTYPE_ENUM && r->GetEnumValue(m, f) == 0) {
        if (const auto* v = f->enum_type()->FindValueByName(s.default_text())) r->SetEnum(&m, f, v);
      } else if (f->cpp_type() == pb::FieldDescriptor::CPPTYPE_STRING && r->GetString(m, f).empty())
        r->SetString(&m, f, s.default_text());
      continue;
    }
    if (!f->has_presence()) continue;
    if (s.has_default_value() && !r->HasField(m, f)) set_default(m, f, s.default_value());
  }
}

std::string range_text(const erg::v1::FieldSpec& s) {
  // Built by appending: GCC 12 warns falsely (-Wrestrict) on "(" + string.
  std::string t;
  if (s.has_min())
    t.append(s.min_exclusive() ? "(" : "[").append(num(s.min()));
  else
    t.append("(-inf");
  t.append(", ");
  if (s.has_max())
    t.append(num(s.max())).append(s.max_exclusive() ? ")" : "]");
  else
    t.append("inf)");
  if (!s.unit().empty()) t += " " + s.unit();
  return t;
}

// "CONE, GAUSSIAN, CYLINDER": the names an enum field may take (its
// *_UNSPECIFIED value is allowed too, and means the documented default).
std::string enum_names(const pb::EnumDescriptor* e) {
  std::string t;
  for (int i = 0; i < e->value_count(); ++i) {
    const std::string& n = e->value(i)->name();
    if (n.size() >= 12 && n.compare(n.size() - 12, 12, "_UNSPECIFIED") == 0) continue;
    t.append(t.empty() ? "" : ", ").append(n);
  }
  return t;
}

// Fields a message carries that this schema does not know (a binary
// message from a newer client: gRPC keeps them as unknown fields).
void unknown_fields_rec(const pb::Message& m, const std::string& path,
                        std::vector<std::string>& out) {
  const pb::UnknownFieldSet& u = m.GetReflection()->GetUnknownFields(m);
  for (int k = 0; k < u.field_count(); ++k)
    out.push_back((path.empty() ? std::string("spec") : path) + ": unknown field number " +
                  std::to_string(u.field(k).number()) + " (not in " +
                  m.GetDescriptor()->full_name() + " of this erg)");
  const pb::Descriptor* d = m.GetDescriptor();
  const pb::Reflection* r = m.GetReflection();
  for (int i = 0; i < d->field_count(); ++i) {
    const pb::FieldDescriptor* f = d->field(i);
    if (f->cpp_type() != pb::FieldDescriptor::CPPTYPE_MESSAGE) continue;
    const std::string name = path.empty() ? f->name() : path + "." + f->name();
    if (f->is_repeated()) {
      for (int k = 0; k < r->FieldSize(m, f); ++k)
        unknown_fields_rec(r->GetRepeatedMessage(m, f, k), name + "[" + std::to_string(k) + "]",
                           out);
    } else if (r->HasField(m, f)) {
      unknown_fields_rec(r->GetMessage(m, f), name, out);
    }
  }
}

// Whether v lies in the field's range.
bool in_range(const erg::v1::FieldSpec& s, double v) {
  return std::isfinite(v) && !(s.has_min() && (s.min_exclusive() ? v <= s.min() : v < s.min())) &&
         !(s.has_max() && (s.max_exclusive() ? v >= s.max() : v > s.max()));
}

// A value in the field's range: its default, else the bound it crossed
// (moved inside for an exclusive bound), for the checks that span several
// fields to run on (their messages about this field are then dropped).
double in_range_value(const pb::FieldDescriptor* f, double v) {
  const auto& s = spec_of(f);
  if (s.has_default_value() && in_range(s, s.default_value())) return s.default_value();
  const bool integral = f->cpp_type() != pb::FieldDescriptor::CPPTYPE_DOUBLE &&
                        f->cpp_type() != pb::FieldDescriptor::CPPTYPE_FLOAT;
  auto inside = [&](double bound, bool exclusive, double towards) {
    if (!exclusive) return bound;
    return integral ? bound + (towards > bound ? 1 : -1) : std::nextafter(bound, towards);
  };
  const double lo = s.has_min() ? s.min() : -1e300, hi = s.has_max() ? s.max() : 1e300;
  if (!std::isfinite(v) || (s.has_min() && v <= s.min()))
    return s.has_min() ? inside(s.min(), s.min_exclusive(), hi) : (s.has_max() ? hi : 0);
  return inside(s.max(), s.max_exclusive(), lo);
}

void validate_rec(const pb::Message& m, const std::string& path, std::vector<std::string>& out,
                  pb::Message* repaired = nullptr) {
  const pb::Descriptor* d = m.GetDescriptor();
  const pb::Reflection* r = m.GetReflection();
  for (int i = 0; i < d->field_count(); ++i) {
    const pb::FieldDescriptor* f = d->field(i);
    const std::string name = path.empty() ? f->name() : path + "." + f->name();
    if (f->cpp_type() == pb::FieldDescriptor::CPPTYPE_MESSAGE) {
      if (f->is_repeated()) {
        for (int k = 0; k < r->FieldSize(m, f); ++k)
          validate_rec(r->GetRepeatedMessage(m, f, k), name + "[" + std::to_string(k) + "]", out,
                       repaired ? repaired->GetReflection()->MutableRepeatedMessage(repaired, f, k)
                                : nullptr);
      } else if (r->HasField(m, f)) {
        validate_rec(r->GetMessage(m, f), name, out,
                     repaired ? repaired->GetReflection()->MutableMessage(repaired, f) : nullptr);
      }
      continue;
    }
    if (f->cpp_type() == pb::FieldDescriptor::CPPTYPE_ENUM && !f->is_repeated()) {
      // JSON may give an enum as a number; proto3 keeps numbers it has no
      // name for, which no part of erg knows how to run.
      const int v = r->GetEnumValue(m, f);
      if (f->enum_type()->FindValueByNumber(v) == nullptr) {
        out.push_back(name + " = " + std::to_string(v) + " is not a known value; allowed " +
                      enum_names(f->enum_type()));
        if (repaired) repaired->GetReflection()->SetEnumValue(repaired, f, 0);
      }
      continue;
    }
    if (f->is_repeated() || !is_numeric(f)) continue;
    const auto& s = spec_of(f);
    const bool present = !f->has_presence() || r->HasField(m, f);
    if (!present) {
      if (s.required()) {
        out.push_back(name + " is required" + (s.doc().empty() ? "" : " (" + s.doc() + ")") +
                      "; allowed " + range_text(s));
        if (repaired) set_default(*repaired, f, in_range_value(f, NAN));
      }
      continue;
    }
    const double v = get_number(m, f);
    if (!in_range(s, v)) {
      out.push_back(name + " = " + num(v) + " is out of range; allowed " + range_text(s));
      if (repaired) set_default(*repaired, f, in_range_value(f, v));
    }
  }
}

// ---- JSON that protobuf's parser refuses: every problem, named --------------

// Levenshtein distance, for "did you mean".
size_t edit_distance(const std::string& a, const std::string& b) {
  std::vector<size_t> row(b.size() + 1);
  for (size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (size_t i = 1; i <= a.size(); ++i) {
    size_t diag = row[0];
    row[0] = i;
    for (size_t j = 1; j <= b.size(); ++j) {
      const size_t up = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diag + (a[i - 1] != b[j - 1] ? 1 : 0)});
      diag = up;
    }
  }
  return row[b.size()];
}

// "unknown field; did you mean 'snapshot_every'?" or the fields there are.
std::string unknown_field_text(const pb::Descriptor* d, const std::string& key) {
  std::string best, all;
  size_t best_d = 4;  // at most 3 edits
  for (int i = 0; i < d->field_count(); ++i) {
    const std::string& n = d->field(i)->name();
    all.append(all.empty() ? "" : ", ").append(n);
    if (const size_t e = edit_distance(key, n); e < best_d) {
      best_d = e;
      best = n;
    }
  }
  if (!best.empty()) return "unknown field; did you mean '" + best + "'?";
  if (d->field_count() <= 12) return "unknown field; allowed " + all;
  return "unknown field (erg params lists every field)";
}

std::string json_text(const pb::Value& v) {
  std::string t;
  (void)pb::util::MessageToJsonString(v, &t);
  return t.size() > 40 ? t.substr(0, 40) + "..." : t;
}

bool json_number(const pb::Value& v, double* out) {
  if (v.kind_case() == pb::Value::kNumberValue) {
    *out = v.number_value();
    return true;
  }
  if (v.kind_case() != pb::Value::kStringValue) return false;
  // Protobuf's JSON takes numbers as strings too ("384", "NaN", "Infinity").
  const std::string& t = v.string_value();
  if (t == "NaN" || t == "Infinity" || t == "-Infinity") {
    *out = t == "NaN" ? NAN : (t[0] == '-' ? -INFINITY : INFINITY);
    return true;
  }
  char* end = nullptr;
  *out = std::strtod(t.c_str(), &end);
  return !t.empty() && end == t.c_str() + t.size();
}

// Whether one (non-repeated) value fits field f; a problem for it if not.
bool json_value_matches(const pb::Value& v, const pb::FieldDescriptor* f, const std::string& name,
                        std::vector<std::string>& problems);

// Checks the JSON object `v` against message type d, removing (and naming
// in `problems`) every key it cannot hold. False when v is no object.
bool json_matches(pb::Value& v, const pb::Descriptor* d, const std::string& path,
                  std::vector<std::string>& problems) {
  if (v.kind_case() != pb::Value::kStructValue) return false;
  auto& fields = *v.mutable_struct_value()->mutable_fields();
  std::vector<std::string> keys;
  for (const auto& [k, _] : fields) keys.push_back(k);
  std::sort(keys.begin(), keys.end());
  std::map<const pb::OneofDescriptor*, std::string> oneof_taken;
  for (const std::string& key : keys) {
    pb::Value& value = fields[key];
    const std::string name = path.empty() ? key : path + "." + key;
    const pb::FieldDescriptor* f = d->FindFieldByName(key);
    if (!f) f = d->FindFieldByCamelcaseName(key);
    bool keep = true;
    const pb::OneofDescriptor* oneof = f ? f->real_containing_oneof() : nullptr;
    if (!f) {
      problems.push_back(name + ": " + unknown_field_text(d, key));
      keep = false;
    } else if (oneof && oneof_taken.count(oneof)) {
      problems.push_back((path.empty() ? std::string("spec") : path) + ": " + oneof_taken[oneof] +
                         " and " + key + " exclude each other; give one of them");
      keep = false;
    } else if (value.kind_case() == pb::Value::kNullValue) {
      // null: the field is absent.
    } else if (f->is_repeated()) {
      if (value.kind_case() != pb::Value::kListValue) {
        problems.push_back(name + " = " + json_text(value) + " is not a list");
        keep = false;
      } else {
        auto& list = *value.mutable_list_value()->mutable_values();
        for (int k = 0; k < list.size(); ++k) {
          const std::string item = name + "[" + std::to_string(k) + "]";
          if (f->cpp_type() == pb::FieldDescriptor::CPPTYPE_MESSAGE) {
            if (!json_matches(list[k], f->message_type(), item, problems)) {
              problems.push_back(item + " = " + json_text(list[k]) + " is not an object");
              list[k].mutable_struct_value();  // an empty one, to keep the indices
            }
          } else if (!json_value_matches(list[k], f, item, problems)) {
            keep = false;  // the list cannot be parsed without it
          }
        }
      }
    } else if (f->cpp_type() == pb::FieldDescriptor::CPPTYPE_MESSAGE) {
      if (!json_matches(value, f->message_type(), name, problems)) {
        problems.push_back(name + " = " + json_text(value) + " is not an object");
        keep = false;
      }
    } else {
      keep = json_value_matches(value, f, name, problems);
    }
    if (!keep)
      fields.erase(key);
    else if (oneof)
      oneof_taken[oneof] = key;
  }
  return true;
}

bool json_value_matches(const pb::Value& v, const pb::FieldDescriptor* f, const std::string& name,
                        std::vector<std::string>& problems) {
  double x = 0;
  switch (f->cpp_type()) {
    case pb::FieldDescriptor::CPPTYPE_ENUM: {
      if (v.kind_case() == pb::Value::kNumberValue) return true;  // checked by validate
      std::string given = v.kind_case() == pb::Value::kStringValue ? v.string_value() : "";
      std::transform(given.begin(), given.end(), given.begin(),
                     [](unsigned char c) { return static_cast<char>(std::toupper(c)); });
      if (!given.empty() && f->enum_type()->FindValueByName(given)) return true;
      problems.push_back(name + " = " + json_text(v) + " is not a known value; allowed " +
                         enum_names(f->enum_type()));
      return false;
    }
    case pb::FieldDescriptor::CPPTYPE_BOOL:
      if (v.kind_case() == pb::Value::kBoolValue) return true;
      problems.push_back(name + " = " + json_text(v) + " is not true or false");
      return false;
    case pb::FieldDescriptor::CPPTYPE_STRING:
      if (v.kind_case() == pb::Value::kStringValue) return true;
      problems.push_back(name + " = " + json_text(v) + " is not a string");
      return false;
    case pb::FieldDescriptor::CPPTYPE_DOUBLE:
    case pb::FieldDescriptor::CPPTYPE_FLOAT:
      if (json_number(v, &x)) return true;
      problems.push_back(name + " = " + json_text(v) + " is not a number; allowed " +
                         range_text(spec_of(f)));
      return false;
    default:  // integers
      if (json_number(v, &x) && std::isfinite(x) && x == std::floor(x)) return true;
      problems.push_back(name + " = " + json_text(v) + " is not a whole number; allowed " +
                         range_text(spec_of(f)));
      return false;
  }
}

// ---- checks that span several fields ---------------------------------------

void check_wind(const erg::v1::WindRegime& w, const std::string& path,
                std::vector<std::string>& out) {
  using R = erg::v1::WindRegime;
  switch (w.regime_case()) {
    case R::REGIME_NOT_SET:
      out.push_back(path + " has no regime; set one of constant, rose, series, bidirectional");
      break;
    case R::kRose: {
      const auto& rose = w.rose();
      if (rose.entries_size() == 0) {
        out.push_back(path + ".rose.entries is empty; a wind rose needs at least one entry");
        break;
      }
      double sum = 0;
      for (const auto& e : rose.entries()) sum += e.probability();
      if (std::isfinite(sum) && std::fabs(sum - 1.0) > 1e-6)
        out.push_back(path + ".rose.entries[*].probability sum to " + num(sum) +
                      "; they must sum to 1 (within 1e-6)");
      break;
    }
    case R::kSeries: {
      const auto& s = w.series();
      if (s.keyframes_size() == 0) {
        out.push_back(path +
                      ".series.keyframes is empty; a wind series needs at least one keyframe");
        break;
      }
      for (int k = 1; k < s.keyframes_size(); ++k)
        if (s.keyframes(k).step() <= s.keyframes(k - 1).step())
          out.push_back(path + ".series.keyframes[" + std::to_string(k) +
                        "].step = " + std::to_string(s.keyframes(k).step()) +
                        " must be greater than the previous keyframe's step " +
                        std::to_string(s.keyframes(k - 1).step()));
      if (s.period_steps() > 0 && s.keyframes(s.keyframes_size() - 1).step() >= s.period_steps())
        out.push_back(path + ".series.period_steps = " + std::to_string(s.period_steps()) +
                      " must exceed the last keyframe's step " +
                      std::to_string(s.keyframes(s.keyframes_size() - 1).step()));
      break;
    }
    default:
      break;
  }
}

// Physical wind speeds (WindRegime.speed_is): one kind for the whole job,
// and a measuring height above the roughness length.
void check_wind_units(const JobSpec& spec, std::vector<std::string>& out) {
  using R = erg::v1::WindRegime;
  const auto phys = [](const R& w) {
    return w.speed_is() == R::SHEAR_VELOCITY || w.speed_is() == R::WIND_AT_HEIGHT;
  };
  const auto kind = [](const R& w) {
    return w.speed_is() == R::SHEAR_VELOCITY   ? std::string("SHEAR_VELOCITY")
           : w.speed_is() == R::WIND_AT_HEIGHT ? std::string("WIND_AT_HEIGHT")
                                               : std::string("MODEL");
  };
  const double d =
      spec.physics().has_grain_diameter_m() ? spec.physics().grain_diameter_m() : 0.00025;
  const auto check_height = [&](const R& w, const std::string& path) {
    if (w.speed_is() != R::WIND_AT_HEIGHT) return;
    const double z0 = w.roughness_m() > 0 ? w.roughness_m() : d / 30.0;
    if (w.height_m() <= z0)
      out.push_back(path + ".height_m = " + num(w.height_m()) +
                    " m must be above the roughness length z0 = " + num(z0) +
                    " m (law of the wall, u* = kappa U / ln(z / z0))");
  };
  check_height(spec.wind(), "wind");
  for (int k = 0; k < spec.events_size(); ++k) {
    const auto& e = spec.events(k);
    if (!e.has_wind()) continue;
    const std::string p = "events[" + std::to_string(k) + "].wind";
    check_height(e.wind(), p);
    if (phys(e.wind()) != phys(spec.wind()))
      out.push_back(p + ".speed_is = " + kind(e.wind()) +
                    " but wind.speed_is = " + kind(spec.wind()) +
                    "; every regime of a job gives its speeds in model units, or every one in "
                    "physical units (SHEAR_VELOCITY or WIND_AT_HEIGHT)");
  }
}

// A wind primitive [P19 4.4] (stages/wind_primitives.h).
void check_wind_primitive(const erg::v1::WindPrimitive& w, const std::string& path,
                          const JobSpec& spec, std::vector<std::string>& out) {
  const double l = spec.domain().cell_size_m();
  const double lmin =
      std::min(static_cast<double>(spec.domain().nx()), static_cast<double>(spec.domain().ny())) *
      l;
  if (w.has_end_step() && w.end_step() <= w.start_step())
    out.push_back(path + ".end_step = " + std::to_string(w.end_step()) +
                  " must be greater than start_step = " + std::to_string(w.start_step()));
  else if (w.has_end_step() && 2 * w.ramp_steps() > w.end_step() - w.start_step())
    out.push_back(path + ".ramp_steps = " + std::to_string(w.ramp_steps()) +
                  " is more than half of end_step - start_step = " +
                  std::to_string(w.end_step() - w.start_step()) + "; allowed [0, " +
                  std::to_string((w.end_step() - w.start_step()) / 2) + "]");
  switch (w.kind_case()) {
    case erg::v1::WindPrimitive::KIND_NOT_SET:
      out.push_back(path + " has no kind; set one of vortex, turbulence");
      break;
    case erg::v1::WindPrimitive::kVortex: {
      const auto& v = w.vortex();
      // Resolved by the grid, and small enough that only the nearest
      // periodic images reach the domain (wind_primitives::vortex_psi).
      if (v.radius_m() < 2 * l || v.radius_m() > 3.0 * lmin / 10.0)
        out.push_back(path + ".vortex.radius_m = " + num(v.radius_m()) +
                      " m is out of range for this domain; allowed [" + num(2 * l) + ", " +
                      num(3.0 * lmin / 10.0) + "] m (2 cells to 0.3 of the shorter side)");
      break;
    }
    case erg::v1::WindPrimitive::kTurbulence: {
      const auto& t = w.turbulence();
      if (t.wavelength_m() < 4 * l)
        out.push_back(path + ".turbulence.wavelength_m = " + num(t.wavelength_m()) +
                      " m is under 4 cells; allowed >= " + num(4 * l) + " m");
      if (t.has_radius_m()) {
        if (t.radius_m() > 0.5 * lmin)
          out.push_back(path + ".turbulence.radius_m = " + num(t.radius_m()) +
                        " m exceeds half the shorter side of the domain, " + num(0.5 * lmin) +
                        " m; leave radius_m out for the whole domain");
        if (t.falloff_m() > t.radius_m())
          out.push_back(path + ".turbulence.falloff_m = " + num(t.falloff_m()) +
                        " exceeds radius_m = " + num(t.radius_m()) + "; allowed (0, radius_m]");
      }
      break;
    }
  }
}

void check_layer(const erg::v1::Layer& layer, const std::string& path, const JobSpec& spec,
                 const std::string& base_dir, std::vector<std::string>& out) {
  if (layer.has_uniform() && layer.uniform().min() > layer.uniform().max())
    out.push_back(path + ".uniform.min = " + num(layer.uniform().min()) +
                  " exceeds max = " + num(layer.uniform().max()) + "; allowed min <= max");
  if (!layer.has_map()) return;
  const auto& map = layer.map();
  const std::string mp = path + ".map";
  if (map.path().empty()) {
    out.push_back(mp + ".path is empty; name an HDF5, 16-bit PNG, GeoTIFF or EXR file");
    return;
  }
  if (map.path().find('\0') != std::string::npos) {
    // The C calls below would stop at the NUL and open another file.
    out.push_back(mp +
                  ".path contains a NUL character; name an HDF5, 16-bit PNG, GeoTIFF or EXR file");
    return;
  }
  const std::string file = resolve_path(map.path(), base_dir);
  // The error_code overload: a name too long, a loop of links or a directory
  // we may not search is a problem with the spec, not an exception.
  std::error_code ec;
  const fs::file_status st = fs::status(file, ec);
  if (st.type() == fs::file_type::not_found) {
    out.push_back(mp + ".path = \"" + map.path() + "\": file not found (looked at " + file + ")");
    return;
  }
  if (ec) {
    out.push_back(mp + ".path = \"" + map.path() + "\" cannot be read: " + ec.message() +
                  " (looked at " + file + ")");
    return;
  }
  if (!fs::is_regular_file(st)) {
    // A directory, a device or a FIFO (which would block the reader).
    out.push_back(mp + ".path = \"" + map.path() + "\" is not a regular file (looked at " + file +
                  ")");
    return;
  }
  if (map_format(map, file) == erg::v1::MapFile::FORMAT_UNSPECIFIED) {
    out.push_back(mp + ".format is unset and the extension of \"" + map.path() +
                  "\" is not .h5/.hdf5/.png/.tif/.tiff/.exr; set format to HDF5, PNG16, GEOTIFF "
                  "or EXR");
    return;
  }
  // The same reader, tileability test and resampling as the generator's.
  try {
    load_map(map, spec, base_dir);
  } catch (const MapError& e) {
    out.push_back(mp + e.what());
  } catch (const std::exception& e) {
    out.push_back(mp + ".path = \"" + map.path() + "\" cannot be read: " + e.what());
  }
}

}  // namespace

SpecError::SpecError(std::vector<std::string> problems)
    : std::runtime_error(join_lines(problems)), problems_(std::move(problems)) {}

JobSpec parse_json(const std::string& text, const std::string& origin) {
  std::vector<std::string> problems;
  JobSpec spec = parse_json_collect(text, problems);
  if (!problems.empty()) {
    for (auto& p : problems) p = origin + ": " + p;
    throw SpecError(problems);
  }
  return spec;
}

JobSpec parse_json_collect(const std::string& text, std::vector<std::string>& problems) {
  JobSpec spec;
  pb::util::JsonParseOptions opt;
  opt.ignore_unknown_fields = false;
  opt.case_insensitive_enum_parsing = true;
  // A good job is parsed exactly as protobuf parses it; only a bad one is
  // walked, to name every problem rather than the parser's first.
  if (pb::util::JsonStringToMessage(text, &spec, opt).ok()) return spec;
  spec.Clear();
  pb::Value tree;
  if (auto st = pb::util::JsonStringToMessage(text, &tree); !st.ok()) {
    problems.push_back("not a valid job spec: " + std::string(st.message()));
    return spec;
  }
  const size_t before = problems.size();
  if (!json_matches(tree, JobSpec::descriptor(), "", problems)) {
    problems.push_back("a job spec is a JSON object");
    return spec;
  }
  std::string cleaned;
  (void)pb::util::MessageToJsonString(tree, &cleaned);
  if (auto st = pb::util::JsonStringToMessage(cleaned, &spec, opt); !st.ok()) {
    // Something the walk does not know about: the parser's own words.
    problems.push_back("not a valid job spec: " + std::string(st.message()));
    spec.Clear();
  }
  if (problems.size() == before) problems.push_back("not a valid job spec");
  return spec;
}

void apply_defaults(JobSpec& spec) {
  // Groups that always exist, so their parameters get their defaults even
  // when the job does not mention them.
  spec.mutable_domain();
  spec.mutable_run();
  spec.mutable_model();
  spec.mutable_amplify();
  spec.mutable_layers();
  // The physical modes read the sand's properties (wind/physics.h).
  if (spec.wind().speed_is() == erg::v1::WindRegime::SHEAR_VELOCITY ||
      spec.wind().speed_is() == erg::v1::WindRegime::WIND_AT_HEIGHT)
    spec.mutable_physics();
  defaults_rec(spec);
}

namespace {

// The rules that span several fields (and the map files); they assume every
// field is in range.
std::vector<std::string> cross_field_problems(const JobSpec& spec, const std::string& base_dir) {
  std::vector<std::string> out;
  const auto& d = spec.domain();
  const auto& m = spec.model();
  const double l = d.cell_size_m();

  if (!spec.has_wind())
    out.push_back("wind is required: the high-altitude wind regime");
  else
    check_wind(spec.wind(), "wind", out);
  check_wind_units(spec, out);

  // The hop is bounded by the saltation halo (docs/design.md, "Tiling").
  constexpr double kMaxHopCells = 16;
  if (m.max_hop_m() > kMaxHopCells * l)
    out.push_back("model.max_hop_m = " + num(m.max_hop_m()) + " m is " + num(m.max_hop_m() / l) +
                  " cells at domain.cell_size_m = " + num(l) + " m; a hop may span at most " +
                  num(kMaxHopCells) + " cells, so allowed max_hop_m <= " + num(kMaxHopCells * l) +
                  " m");
  constexpr double kMaxShadowCells = 128;
  if (m.shadow_radius_m() > kMaxShadowCells * l)
    out.push_back("model.shadow_radius_m = " + num(m.shadow_radius_m()) + " m is " +
                  num(m.shadow_radius_m() / l) + " cells at domain.cell_size_m = " + num(l) +
                  " m; allowed shadow_radius_m <= " + num(kMaxShadowCells * l) + " m (128 cells)");
  if (m.echo_dunes() && m.echo_reach_m() > kMaxShadowCells * l)
    out.push_back("model.echo_reach_m = " + num(m.echo_reach_m()) + " m is " +
                  num(m.echo_reach_m() / l) + " cells at domain.cell_size_m = " + num(l) +
                  " m; allowed echo_reach_m <= " + num(kMaxShadowCells * l) + " m (128 cells)");
  if (m.echo_sticky_ratio() < m.echo_gap_ratio())
    out.push_back("model.echo_sticky_ratio = " + num(m.echo_sticky_ratio()) +
                  " is below model.echo_gap_ratio = " + num(m.echo_gap_ratio()) +
                  "; allowed echo_sticky_ratio >= echo_gap_ratio");
  if (m.shadow_angle_min_deg() >= m.shadow_angle_max_deg())
    out.push_back("model.shadow_angle_min_deg = " + num(m.shadow_angle_min_deg()) +
                  " must be below model.shadow_angle_max_deg = " + num(m.shadow_angle_max_deg()));
  // The wind-warping coarse cells (stages/wind_warping.h, coarse_factor)
  // depend on the model's lengths only; each side must hold whole ones.
  if (l > 0 && m.warp_large_radius_m() > 0 && m.warp_small_radius_m() > 0) {
    const double max_coarse_m =
        wind_warping::max_coarse_m(wind_warping::sigma_of_radius(m.warp_large_radius_m()),
                                   wind_warping::sigma_of_radius(m.warp_small_radius_m()));
    const long long c = wind_warping::coarse_factor(l, max_coarse_m);
    for (const auto& [name, n] :
         {std::pair<const char*, long long>{"domain.nx", d.nx()}, {"domain.ny", d.ny()}})
      if (n > 0 && n % c != 0)
        out.push_back(std::string(name) + " = " + std::to_string(n) +
                      " is not a multiple of the wind-warping coarse cell, " + std::to_string(c) +
                      " cells (the largest power of two <= min(model.warp_large_radius_m, "
                      "model.warp_small_radius_m) / 8 / domain.cell_size_m = " +
                      num(max_coarse_m / l) + "); allowed " + name + " = multiples of " +
                      std::to_string(c) + ", e.g. " + std::to_string(std::max(c, n / c * c)) +
                      " or " + std::to_string((n / c + 1) * c));
  }
  if (m.warp_large_weight() + m.warp_small_weight() <= 0)
    out.push_back("model.warp_large_weight + model.warp_small_weight = 0; allowed > 0");

  const auto& layers = spec.layers();
  check_layer(layers.bedrock(), "layers.bedrock", spec, base_dir, out);
  check_layer(layers.sand(), "layers.sand", spec, base_dir, out);
  check_layer(layers.vegetation(), "layers.vegetation", spec, base_dir, out);
  check_layer(layers.resistance(), "layers.resistance", spec, base_dir, out);
  if (layers.obstacles().has_map()) {
    erg::v1::Layer map_only;  // the same checks as a layer's map
    *map_only.mutable_map() = layers.obstacles().map();
    check_layer(map_only, "layers.obstacles", spec, base_dir, out);
  }
  auto check_obstacle = [&](const erg::v1::Obstacle& o, const std::string& p) {
    if (o.shape_case() == erg::v1::Obstacle::SHAPE_NOT_SET)
      out.push_back(p + " has no shape; set one of disk, rect, road");
    else if (o.has_road() && o.road().points_size() < 2)
      out.push_back(p + ".road.points has " + std::to_string(o.road().points_size()) +
                    " points; allowed at least 2");
  };
  for (int k = 0; k < layers.obstacles().shapes_size(); ++k)
    check_obstacle(layers.obstacles().shapes(k),
                   "layers.obstacles.shapes[" + std::to_string(k) + "]");

  for (int k = 0; k < spec.wind_primitives_size(); ++k)
    check_wind_primitive(spec.wind_primitives(k), "wind_primitives[" + std::to_string(k) + "]",
                         spec, out);

  // Where each wind primitive name first appears on the timeline (step, then
  // file order), for the removals.
  std::set<std::string> in_job;
  for (const auto& w : spec.wind_primitives()) in_job.insert(w.name());
  std::map<std::string, std::pair<std::int64_t, int>> first_added;
  for (int k = 0; k < spec.events_size(); ++k) {
    const auto& e = spec.events(k);
    if (e.action_case() != erg::v1::Event::kWindPrimitive) continue;
    const auto key = std::make_pair(static_cast<std::int64_t>(e.step()), k);
    auto [it, inserted] = first_added.emplace(e.wind_primitive().name(), key);
    if (!inserted && key < it->second) it->second = key;
  }

  for (int k = 0; k < spec.events_size(); ++k) {
    const auto& e = spec.events(k);
    const std::string p = "events[" + std::to_string(k) + "]";
    switch (e.action_case()) {
      case erg::v1::Event::ACTION_NOT_SET:
        out.push_back(p +
                      " has no action; set one of sand, bedrock, vegetation, wind, add_obstacle, "
                      "remove_obstacle, wind_primitive, remove_wind_primitive");
        break;
      case erg::v1::Event::kAddObstacle:
        check_obstacle(e.add_obstacle(), p + ".add_obstacle");
        break;
      case erg::v1::Event::kRemoveObstacle:
        check_obstacle(e.remove_obstacle(), p + ".remove_obstacle");
        break;
      case erg::v1::Event::kWindPrimitive:
        check_wind_primitive(e.wind_primitive(), p + ".wind_primitive", spec, out);
        break;
      case erg::v1::Event::kRemoveWindPrimitive: {
        // It must name a primitive of the job or of an event before it on
        // the timeline (an earlier step, or the same step earlier in the list).
        const std::string& name = e.remove_wind_primitive();
        const auto first = first_added.find(name);
        const bool found = in_job.count(name) > 0 || (first != first_added.end() &&
                                                      first->second < std::make_pair(e.step(), k));
        if (name.empty() || !found)
          out.push_back(p + ".remove_wind_primitive = \"" + name +
                        "\" names no wind primitive of the job or of an earlier event");
        break;
      }
      case erg::v1::Event::kWind:
        check_wind(e.wind(), p + ".wind", out);
        break;
      case erg::v1::Event::kVegetation: {
        const auto& v = e.vegetation();
        const bool rect = v.has_width_m() || v.has_height_m();
        const bool disk = v.has_radius_m();
        if (rect == disk)
          out.push_back(p +
                        ".vegetation must give either width_m and height_m (a rectangle) or "
                        "radius_m (a disk)");
        else if (rect && !(v.has_width_m() && v.has_height_m()))
          out.push_back(p + ".vegetation rectangle needs both width_m and height_m");
        break;
      }
      case erg::v1::Event::kSand:
      case erg::v1::Event::kBedrock: {
        const auto& b = e.action_case() == erg::v1::Event::kSand ? e.sand() : e.bedrock();
        if (b.falloff_m() > b.radius_m())
          out.push_back(p + (e.action_case() == erg::v1::Event::kSand ? ".sand" : ".bedrock") +
                        ".falloff_m = " + num(b.falloff_m()) +
                        " exceeds radius_m = " + num(b.radius_m()) + "; allowed [0, radius_m]");
        break;
      }
    }
  }
  return out;
}

}  // namespace

std::vector<std::string> validate(const JobSpec& spec, const std::string& base_dir) {
  std::vector<std::string> out;
  unknown_fields_rec(spec, "", out);
  // Every field's own problems, then the cross-field rules on a copy whose
  // bad fields are put in range (so that they run at all); a rule's message
  // that names a field already reported would only repeat it, and is dropped.
  JobSpec repaired = spec;
  repaired.DiscardUnknownFields();
  std::vector<std::string> own;
  validate_rec(spec, "", own, &repaired);
  out.insert(out.end(), own.begin(), own.end());
  for (const std::string& p : cross_field_problems(repaired, base_dir)) {
    const bool repeats = std::any_of(own.begin(), own.end(), [&](const std::string& o) {
      const std::string field = o.substr(0, o.find_first_of(" "));
      return p.find(field) != std::string::npos;
    });
    if (!repeats) out.push_back(p);
  }
  return out;
}

std::string base_dir_of(const std::string& job_path) {
  fs::path p(job_path);
  return p.has_parent_path() ? p.parent_path().string() : std::string(".");
}

std::string resolve_path(const std::string& path, const std::string& base_dir) {
  fs::path p(path);
  if (p.is_absolute()) return p.string();
  return (fs::path(base_dir) / p).lexically_normal().string();
}

JobSpec load_job_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    const int err = errno;
    throw SpecError({path + ": cannot open the job file: " + std::generic_category().message(err)});
  }
  std::stringstream ss;
  ss << in.rdbuf();
  // The problems of parsing and of validation, in one list.
  std::vector<std::string> problems;
  JobSpec spec = parse_json_collect(ss.str(), problems);
  const bool parsed = problems.empty() || spec.ByteSizeLong() > 0;
  apply_defaults(spec);
  if (parsed) {
    auto more = validate(spec, base_dir_of(path));
    // A field removed as unparseable is reported once, not again as missing.
    for (auto& p : more) {
      const std::string field = p.substr(0, p.find_first_of(" :"));
      const bool repeats = std::any_of(problems.begin(), problems.end(), [&](const auto& q) {
        return q.compare(0, field.size() + 1, field + " ") == 0;
      });
      if (!repeats) problems.push_back(std::move(p));
    }
  }
  if (!problems.empty()) {
    for (auto& p : problems) p = path + ": " + p;
    throw SpecError(problems);
  }
  return spec;
}

std::string to_json(const JobSpec& spec) {
  std::string out;
  pb::util::JsonPrintOptions opt;
  opt.add_whitespace = true;
  opt.preserve_proto_field_names = true;
  (void)pb::util::MessageToJsonString(spec, &out, opt);
  return out;
}

namespace {

// The names of every 64-bit integer field in d and the messages under it.
void int64_names(const pb::Descriptor* d, std::set<std::string>& names,
                 std::set<const pb::Descriptor*>& seen) {
  if (!seen.insert(d).second) return;
  for (int i = 0; i < d->field_count(); ++i) {
    const pb::FieldDescriptor* f = d->field(i);
    if (f->cpp_type() == pb::FieldDescriptor::CPPTYPE_INT64 ||
        f->cpp_type() == pb::FieldDescriptor::CPPTYPE_UINT64)
      names.insert(f->name());
    if (f->cpp_type() == pb::FieldDescriptor::CPPTYPE_MESSAGE)
      int64_names(f->message_type(), names, seen);
  }
}

}  // namespace

std::string to_readable_json(const JobSpec& spec) {
  static const std::set<std::string> names = [] {
    std::set<std::string> n;
    std::set<const pb::Descriptor*> seen;
    int64_names(JobSpec::descriptor(), n, seen);
    return n;
  }();
  // to_json writes one field a line: `  "nx": "384",` becomes `  "nx": 384,`.
  std::istringstream in(to_json(spec));
  std::string out;
  for (std::string line; std::getline(in, line);) {
    const size_t q0 = line.find('"');
    const size_t q1 = q0 == std::string::npos ? q0 : line.find('"', q0 + 1);
    if (q1 != std::string::npos && line.compare(q1, 4, "\": \"") == 0 &&
        names.count(line.substr(q0 + 1, q1 - q0 - 1))) {
      const size_t v0 = q1 + 4, v1 = line.find('"', v0);
      const std::string v = line.substr(v0, v1 - v0);
      if (v1 != std::string::npos && !v.empty() &&
          v.find_first_not_of("-0123456789") == std::string::npos)
        line = line.substr(0, v0 - 1) + v + line.substr(v1 + 1);
    }
    out += line + "\n";
  }
  if (!out.empty()) out.pop_back();
  return out;
}

void apply_overrides(JobSpec& spec, const Overrides& o) {
  if (o.steps >= 0) spec.mutable_run()->set_steps(o.steps);
  if (o.snapshot_every >= 0) spec.mutable_run()->set_snapshot_every(o.snapshot_every);
  if (o.checkpoint_every >= 0) spec.mutable_run()->set_checkpoint_every(o.checkpoint_every);
}

namespace {
void table_rec(const pb::Descriptor* d, const std::string& path, std::string& out, int depth) {
  if (depth > 4) return;
  for (int i = 0; i < d->field_count(); ++i) {
    const pb::FieldDescriptor* f = d->field(i);
    const std::string name = path.empty() ? f->name() : path + "." + f->name();
    if (f->cpp_type() == pb::FieldDescriptor::CPPTYPE_MESSAGE) {
      if (f->message_type()->full_name() == "erg.v1.WindRegime" && !path.empty()) continue;
      // An event's primitive has the fields of wind_primitives[].
      if (f->message_type()->full_name() == "erg.v1.WindPrimitive" && path == "events[]") continue;
      table_rec(f->message_type(), name + (f->is_repeated() ? "[]" : ""), out, depth + 1);
      continue;
    }
    const auto& s = spec_of(f);
    std::string def = s.has_default_value()       ? num(s.default_value())
                      : !s.default_text().empty() ? s.default_text()
                      : s.required()              ? "required"
                                                  : "-";
    std::string range;
    switch (f->cpp_type()) {
      case pb::FieldDescriptor::CPPTYPE_BOOL:
        if (s.has_default_value()) def = s.default_value() != 0 ? "true" : "false";
        range = "true, false";
        break;
      case pb::FieldDescriptor::CPPTYPE_ENUM:
        range = enum_names(f->enum_type());
        break;
      case pb::FieldDescriptor::CPPTYPE_STRING:
        range = "text";
        break;
      default:  // the numbers (messages recurse above)
        range = range_text(s);
    }
    std::string note = s.source().empty()
                           ? s.doc()
                           : (s.doc().empty() ? s.source() : s.doc() + " (" + s.source() + ")");
    out += "| `" + name + "` | " + def + " | " + range + " | " + note + " |\n";
  }
}
}  // namespace

std::string parameter_table_markdown() {
  std::string out = "| field | default | allowed | meaning (source) |\n|---|---|---|---|\n";
  table_rec(JobSpec::descriptor(), "", out, 0);
  return out;
}

}  // namespace erg::job

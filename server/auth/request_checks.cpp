// SPDX-License-Identifier: Apache-2.0
#include "auth/request_checks.h"

#include "erg/v1/job.pb.h"
#include "scheduler/job_manager.h"

namespace erg::server {

namespace {

using google::protobuf::FieldDescriptor;
using google::protobuf::Message;

void walk(const Message& m, const std::string& prefix, std::vector<std::string>& out) {
  const auto* r = m.GetReflection();
  std::vector<const FieldDescriptor*> fields;
  r->ListFields(m, &fields);  // the fields that are set (oneof members included)
  for (const FieldDescriptor* f : fields) {
    if (f->cpp_type() != FieldDescriptor::CPPTYPE_MESSAGE) continue;
    const std::string name = prefix.empty() ? f->name() : prefix + "." + f->name();
    auto visit = [&](const Message& sub, const std::string& where) {
      if (sub.GetDescriptor() == erg::v1::MapFile::descriptor())
        out.push_back(where);
      else
        walk(sub, where, out);  // depth is bounded by the parser's (100)
    };
    if (f->is_repeated()) {
      const int n = r->FieldSize(m, f);
      for (int i = 0; i < n; ++i)
        visit(r->GetRepeatedMessage(m, f, i), name + "[" + std::to_string(i) + "]");
    } else {
      visit(r->GetMessage(m, f), name);
    }
  }
}

}  // namespace

std::vector<std::string> map_fields_set(const Message& m, const std::string& prefix) {
  std::vector<std::string> out;
  walk(m, prefix, out);
  return out;
}

void refuse_map_files(const Message& m, const std::string& prefix) {
  const auto fields = map_fields_set(m, prefix);
  if (fields.empty()) return;
  std::string msg;
  for (const auto& f : fields)
    msg += (msg.empty() ? "" : "\n") + f +
           ": map files are not accepted by ergd (it reads no file of its own file system for "
           "a tenant); use a generator or shapes, or `erg run` on your own machine";
  throw ApiError(grpc::StatusCode::PERMISSION_DENIED, msg);
}

std::string echo_id(const std::string& s) {
  std::string out = "'";
  for (size_t i = 0; i < s.size() && i < kMaxEchoedId; ++i) {
    const unsigned char c = static_cast<unsigned char>(s[i]);
    out += (c >= 0x20 && c < 0x7f) ? static_cast<char>(c) : '?';
  }
  out += "'";
  if (s.size() > kMaxEchoedId) out += "... (" + std::to_string(s.size()) + " bytes)";
  return out;
}

void check_job_id(const std::string& id) {
  bool printable = true;
  for (char c : id) {
    const auto u = static_cast<unsigned char>(c);
    if (u < 0x20 || u >= 0x7f) printable = false;
  }
  if (id.size() > kMaxEchoedId || !printable)
    throw ApiError(grpc::StatusCode::NOT_FOUND, "job " + echo_id(id) + " not found");
}

}  // namespace erg::server

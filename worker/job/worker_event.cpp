// SPDX-License-Identifier: Apache-2.0
#include "job/worker_event.h"

#include <google/protobuf/util/json_util.h>

namespace erg::job {

std::string worker_event_line(const erg::v1::WorkerEvent& event) {
  google::protobuf::util::JsonPrintOptions opt;
  opt.preserve_proto_field_names = true;     // the names of worker.proto
  opt.always_print_primitive_fields = true;  // step 0, a "" preview: all keys present
  std::string out;
  if (!google::protobuf::util::MessageToJsonString(event, &out, opt).ok()) {
    // Only invalid UTF-8 can fail, and the writers pass strings through
    // valid_utf8(); say so rather than write half an event.
    erg::v1::WorkerEvent plain;
    plain.set_step(event.step());
    plain.mutable_failed()->set_reason("erg-worker: an event could not be written as JSON");
    out.clear();
    (void)google::protobuf::util::MessageToJsonString(plain, &out, opt);
  }
  out += '\n';
  return out;
}

std::optional<erg::v1::WorkerEvent> parse_worker_event(std::string_view line, std::string* error) {
  while (!line.empty() && (line.back() == '\n' || line.back() == '\r')) line.remove_suffix(1);
  google::protobuf::util::JsonParseOptions opt;
  opt.ignore_unknown_fields = true;
  erg::v1::WorkerEvent event;
  const auto status = google::protobuf::util::JsonStringToMessage(
      google::protobuf::StringPiece(line.data(), line.size()), &event, opt);
  if (!status.ok()) {
    if (error) *error = std::string(status.message());
    return std::nullopt;
  }
  return event;
}

std::string valid_utf8(std::string_view s) {
  std::string out;
  out.reserve(s.size());
  const auto* p = reinterpret_cast<const unsigned char*>(s.data());
  const size_t n = s.size();
  for (size_t i = 0; i < n;) {
    const unsigned char c = p[i];
    size_t len = 0;
    unsigned cp = 0;
    if (c < 0x80) {
      len = 1;
      cp = c;
    } else if ((c & 0xE0) == 0xC0) {
      len = 2;
      cp = c & 0x1Fu;
    } else if ((c & 0xF0) == 0xE0) {
      len = 3;
      cp = c & 0x0Fu;
    } else if ((c & 0xF8) == 0xF0) {
      len = 4;
      cp = c & 0x07u;
    }
    bool ok = len > 0 && i + len <= n;
    for (size_t k = 1; ok && k < len; ++k) {
      ok = (p[i + k] & 0xC0) == 0x80;
      cp = (cp << 6) | (p[i + k] & 0x3Fu);
    }
    // Overlong forms, surrogates and values past U+10FFFF are not UTF-8.
    static constexpr unsigned kMin[5] = {0, 0, 0x80, 0x800, 0x10000};
    if (ok && (cp < kMin[len] || cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF))) ok = false;
    if (ok) {
      out.append(s.substr(i, len));
      i += len;
    } else {
      out += "\xEF\xBF\xBD";  // U+FFFD
      ++i;
    }
  }
  return out;
}

}  // namespace erg::job

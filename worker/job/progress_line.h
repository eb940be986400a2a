// The worker's progress events: one flat JSON object per line, written by
// rank 0 to --progress-fd (worker/sim/runner.cpp emits them; `erg run` and
// ergd read them). Kinds ("event"): start, progress, snapshot, steered,
// steer_rejected, stopped, failed, done.
#pragma once

#include <map>
#include <string>

namespace erg::job {

// Parses one event line into key -> value. Strings are unescaped; nested
// objects and arrays are kept as their raw JSON text; numbers as written.
// Never throws: a malformed line gives whatever keys parsed before the fault.
inline std::map<std::string, std::string> parse_progress_line(const std::string& line) {
  std::map<std::string, std::string> out;
  size_t i = 0;
  auto skip = [&] {
    while (i < line.size() &&
           (line[i] == ' ' || line[i] == ',' || line[i] == '{' || line[i] == '}'))
      ++i;
  };
  while (i < line.size()) {
    skip();
    if (i >= line.size() || line[i] != '"') break;
    size_t k = line.find('"', i + 1);
    if (k == std::string::npos) break;
    std::string key = line.substr(i + 1, k - i - 1);
    i = k + 1;
    if (i < line.size() && line[i] == ':') ++i;
    std::string value;
    if (i < line.size() && line[i] == '"') {
      ++i;
      while (i < line.size() && line[i] != '"') {
        if (line[i] == '\\' && i + 1 < line.size()) ++i;
        value += line[i++];
      }
      ++i;
    } else if (i < line.size() && (line[i] == '{' || line[i] == '[')) {
      // Raw text of the nested value, strings inside it skipped over.
      int depth = 0;
      const size_t start = i;
      bool in_string = false;
      do {
        const char c = line[i];
        if (in_string) {
          if (c == '\\')
            ++i;
          else if (c == '"')
            in_string = false;
        } else if (c == '"') {
          in_string = true;
        } else if (c == '{' || c == '[') {
          ++depth;
        } else if (c == '}' || c == ']') {
          --depth;
        }
        ++i;
      } while (i < line.size() && depth > 0);
      value = line.substr(start, i - start);
    } else {
      while (i < line.size() && line[i] != ',' && line[i] != '}') value += line[i++];
    }
    out[key] = value;
  }
  return out;
}

}  // namespace erg::job

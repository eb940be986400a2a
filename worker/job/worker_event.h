// SPDX-License-Identifier: Apache-2.0
// The worker protocol (proto/erg/v1/worker.proto): one erg.v1.WorkerEvent per
// line of protobuf JSON. erg-worker writes the lines (rank 0, --progress-fd);
// ergd's launchers and `erg run` read them. Both sides use these two
// functions, so what is written is what is read.
#pragma once

#include <optional>
#include <string>
#include <string_view>

#include "erg/v1/worker.pb.h"

namespace erg::job {

// The event as one line of JSON, ending in '\n' (strings escaped by protobuf:
// a newline in a reason is "\n" inside the line, never a line break).
std::string worker_event_line(const erg::v1::WorkerEvent& event);

// Parses one line (with or without its '\n'). Fields this build does not know
// are skipped (a newer worker may add some); anything that is not a
// WorkerEvent gives nullopt, with protobuf's reason in *error.
std::optional<erg::v1::WorkerEvent> parse_worker_event(std::string_view line,
                                                       std::string* error = nullptr);

// `s` with every byte that is not part of valid UTF-8 replaced by U+FFFD:
// protobuf strings must be UTF-8, and a reason may quote a file name or an
// error message in any bytes.
std::string valid_utf8(std::string_view s);

}  // namespace erg::job

// SPDX-License-Identifier: Apache-2.0
// What a tenant may ask of ergd, checked before anything else looks at a
// request: no file of the server's own file system is read for a tenant,
// and ids echoed back in errors are bounded and printable.
#pragma once

#include <google/protobuf/message.h>

#include <string>
#include <vector>

namespace erg::server {

// Every erg.v1.MapFile present anywhere in `m` (any depth, singular,
// repeated, oneof and map fields alike), as field paths such as
// "layers.obstacles.map" or "events[3].…". Derived from the
// message's descriptor, so a MapFile field added to the schema later is
// found without a change here.
std::vector<std::string> map_fields_set(const google::protobuf::Message& m,
                                        const std::string& prefix = "");

// Throws ApiError(PERMISSION_DENIED) naming every map field of `m` that is
// set. The message names fields only: never the path, and never whether
// it exists, so it tells a tenant nothing about the server's files.
void refuse_map_files(const google::protobuf::Message& m, const std::string& prefix = "");

// Longest id echoed back in an error; real job ids are "j-" + 16 hex digits.
constexpr size_t kMaxEchoedId = 64;

// `s` as it may be echoed in an error: printable ASCII only (others become
// '?'), at most kMaxEchoedId characters, then the full length in bytes.
std::string echo_id(const std::string& s);

// Throws ApiError(NOT_FOUND) for an id no job can have (too long, or not
// printable ASCII), echoing it through echo_id.
void check_job_id(const std::string& id);

}  // namespace erg::server

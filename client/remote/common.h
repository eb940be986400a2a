// SPDX-License-Identifier: Apache-2.0
// Helpers shared by the remote commands (remote/*.cpp).
#pragma once

#include <google/protobuf/message.h>

#include <cstdint>
#include <string>

#include "erg/v1/service.pb.h"

namespace erg::client {

// Prints "erg: COMMAND: PROBLEM" and the command's usage; returns 2.
int usage_error(const std::string& command, const std::string& problem);

// "RUNNING", ...
std::string state_name(erg::v1::JobState s);
// SUCCEEDED, FAILED or CANCELLED.
bool is_final(erg::v1::JobState s);
// Parses "running", "RUNNING", ...; false when it names no state.
bool parse_state(const std::string& text, erg::v1::JobState* out);

// Local time "2024-05-01 12:03:04"; "-" for 0.
std::string fmt_time_ms(std::int64_t unix_ms);

// Protobuf JSON: proto field names (as in job files), enums by name.
// `indent`: multi-line; `all_fields`: zero-valued fields too.
std::string to_json(const google::protobuf::Message& m, bool indent, bool all_fields = false);

// "step 120/2000 (6%), 3.21 steps/s, ETA 9:47"
std::string progress_text(const erg::v1::Progress& p);

// Sand in m³ from an exact total of units of 2^-32 m summed over cells of
// cell_size_m: "1234.5 m³".
std::string sand_volume_text(const std::string& units, double cell_size_m);

// "486 m³ on the ground + 0.01 m³ airborne [486035157178871 + 9 units of
// 2^-32 m x cell area]"; "" when the record has no totals yet.
std::string sand_text(const erg::v1::Progress& p, double cell_size_m);

// "at steps 0, 500, 1000" (a long list shortened in the middle).
std::string steps_text(const google::protobuf::RepeatedField<std::int64_t>& steps);

// Where the worker runs: "pid 2880 on HOST", "Slurm job 123 (RUNNING)".
std::string worker_text(const erg::v1::Job& job);

}  // namespace erg::client

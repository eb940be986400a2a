// SPDX-License-Identifier: Apache-2.0
// The commands of `erg`, one function each; main.cpp dispatches to them.
// Each takes the arguments after the command name and returns the exit code.
#pragma once

#include <string>
#include <vector>

namespace erg::client {

// Local runs (local_run.cpp): erg-worker on this machine.
int cmd_run(const std::vector<std::string>& args);
int cmd_check(const std::vector<std::string>& args);
int cmd_calibrate(const std::vector<std::string>& args);
// A snapshot to GeoTIFF, PNG16, EXR or OBJ (export_cmd.cpp, worker/export/).
int cmd_export(const std::vector<std::string>& args);

// Amplified heightmap of a snapshot region (amplify.cpp; worker/amplify/).
int cmd_amplify(const std::vector<std::string>& args);

// erg wind import (wind_import.cpp): a measured wind record as a job's wind.
int cmd_wind(const std::vector<std::string>& args);

// erg validate (validate.cpp): the geomorphology suite of client/validate/.
int cmd_validate(const std::vector<std::string>& args);

// erg-worker: $ERG_WORKER, else next to this erg binary, else on PATH.
std::string worker_path();

class Remote;  // remote/connection.h

// Remote jobs on ergd (remote/*.cpp).
int cmd_submit(Remote& remote, const std::vector<std::string>& args);
int cmd_jobs(Remote& remote, const std::vector<std::string>& args);
int cmd_status(Remote& remote, const std::vector<std::string>& args);
int cmd_watch(Remote& remote, const std::vector<std::string>& args);
int cmd_cancel(Remote& remote, const std::vector<std::string>& args);
int cmd_resume(Remote& remote, const std::vector<std::string>& args);
int cmd_steer(Remote& remote, const std::vector<std::string>& args);
int cmd_fetch(Remote& remote, const std::vector<std::string>& args);
int cmd_preview(Remote& remote, const std::vector<std::string>& args);

// Watches job `id` until it ends (erg watch, erg submit --watch); the exit
// code follows the final state: 0 SUCCEEDED, 1 FAILED, 3 CANCELLED.
// `connected`: ergd has answered this command already, so a first failure
// to reach it is a lost connection worth retrying, not a wrong address.
int watch_job(Remote& remote, const std::string& id, const std::string& command, bool connected);

// The usage of one command (lines ending in a newline), from the table in
// main.cpp that `erg help` prints.
std::string usage_of(const std::string& command);

}  // namespace erg::client

// SPDX-License-Identifier: Apache-2.0
// erg: the command line for users.
// On this machine (local_run.cpp):
//   erg run JOB.json --out DIR [--steps N] [--snapshot-every K] [--checkpoint-every C]
//           [--threads T] [--backend B] [--ranks P] [--tiles PXxPY]
//   erg run --resume DIR [--steps N]
//   erg check JOB.json      validate a job and print it with every default filled in
//   erg params              every job field: default, allowed values, unit, source
//   erg export DIR --format F --out FILE [--step S] [--layer L] [--region X0,Y0,W,H]
//              [--upsample K [--no-amplify]] [--tiles NxM] [--normals]   GeoTIFF, PNG16, EXR, OBJ
//   erg amplify DIR [--step S] [--region X0,Y0,W,H] [--upsample K] --out FILE.h5
//                           a region upsampled with ripples and sand bumps (+ FILE.png)
//   erg validate --out DIR [--quick]   measured laws of geomorphology (validate.cpp)
// On ergd, the job service (remote/*.cpp; proto/erg/v1/service.proto):
//   erg submit JOB.json [--watch] [--key K] [--steps N] [--snapshot-every K]
//              [--checkpoint-every C] [--ranks P] [--threads T]   prints the job id
//              [--partition P] [--account A] [--nodes N] [--gpus-per-node G]
//              [--time-limit MINUTES]      the Slurm request (ergd --launcher slurm)
//   erg jobs [--state S] [--all-pages]      the tenant's jobs, newest first
//   erg status ID [--json]                  one job's record
//   erg watch ID                            progress until the job ends
//   erg cancel ID
//   erg resume ID                           a FAILED job continues from its checkpoint
//   erg steer ID EVENTS.json                timeline events applied to a running job
//   erg fetch ID [--step S | --all] --out DIR    snapshots, resumable, sha256-checked
//   erg preview ID [--step S] --out FILE.png
// Every remote command takes --server HOST:PORT, --token T and --ca FILE
// anywhere in its arguments; else ERG_SERVER, ERG_TOKEN, ERG_CA; else the
// config file $ERG_CONFIG or ~/.config/erg/config (remote/config.h).
// Exit codes: 0 ok; 1 error (watch: the job FAILED); 2 usage, invalid job or
// INVALID_ARGUMENT; 3 watch: the job was CANCELLED; 4 UNAUTHENTICATED or
// PERMISSION_DENIED; 5 NOT_FOUND.
#include <iostream>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "commands.h"
#include "job/spec.h"
#include "remote/config.h"
#include "remote/connection.h"

namespace erg::client {

namespace {

struct CommandUsage {
  const char* name;
  const char* text;  // lines, each ending in a newline
};

// The one usage table: `erg help` prints it all, a command's mistakes print
// its own entry.
const CommandUsage kUsage[] = {
    {"run",
     "  erg run JOB.json --out DIR [--steps N] [--snapshot-every K] [--checkpoint-every C]\n"
     "                   [--threads T] [--backend auto|cpu|cuda] [--ranks P [--tiles PXxPY]]\n"
     "  erg run --resume DIR [--steps N] [...]\n"},
    {"check", "  erg check JOB.json   validate a job; print it with all defaults\n"},
    {"calibrate",
     "  erg calibrate JOB.json [--ratios R,R,...] [--drift-steps N]\n"
     "                     the time per step measured, the flat-bed flux against the flux law\n"
     "                     at u* = R u_t, the wind regime's drift against DP/RDP/RDD (JSON)\n"},
    {"params", "  erg params           every job field: default, allowed values, source\n"},
    {"export",
     "  erg export DIR --format geotiff|png16|exr|obj --out FILE [--step S]\n"
     "             [--layer height|sand|bedrock|vegetation] [--region X0,Y0,W,H]\n"
     "             [--upsample K [--no-amplify]] [--tiles NxM] [--normals]\n"
     "                       a snapshot (latest by default) for GIS and game engines;\n"
     "                       heights upsampled K times get ripples and sand bumps\n"
     "                       (amplify.* of the job) unless --no-amplify\n"},
    {"amplify",
     "  erg amplify DIR [--step S] [--region X0,Y0,W,H] [--upsample K] --out FILE.h5\n"
     "                       a snapshot region upsampled K times (default 4) with ripples\n"
     "                       and sand bumps: HDF5 /height and a FILE.png preview\n"},
    {"wind",
     "  erg wind import FILE --format csv|netcdf [--point LAT,LON | --x I --y J]\n"
     "                  [--height 10] [--roughness Z0] [--rose [--sectors 16] [--speed-bin 1]]\n"
     "                  [--job JOB.json | --step-hours H] [--out FILE] [--png ROSE.png]\n"
     "                       an hourly wind record (CSV time,u,v or time,speed,direction;\n"
     "                       ERA5 netCDF u10/v10) as {\"wind\": ...} for a job: a series (or\n"
     "                       a rose); prints its rose and DP/RDP/RDD, draws the sand rose\n"},
    {"validate",
     "  erg validate --out DIR [--quick] [--threads T] [--reuse] [--skip GLOB]...\n"
     "                       run the geomorphology scenes, write DIR/report.md (laws, plots);\n"
     "                       --reuse keeps DIR's runs and resumes interrupted ones;\n"
     "                       --skip leaves out the scenes matching GLOB (e.g. 'transverse_fin*'),\n"
     "                       and the laws that need them read NOT RUN\n"},
    {"submit",
     "  erg submit JOB.json [--watch] [--key IDEMPOTENCY_KEY] [--steps N] [--snapshot-every K]\n"
     "             [--checkpoint-every C] [--ranks P] [--threads T]\n"
     "             [--partition P] [--account A] [--nodes N] [--gpus-per-node G]\n"
     "             [--time-limit MINUTES]   (Slurm: ergd --launcher slurm)\n"
     "                       queue the job on ergd; prints its id on stdout\n"},
    {"jobs", "  erg jobs [--state queued|running|succeeded|failed|cancelled] [--all-pages]\n"},
    {"status", "  erg status ID [--json]\n"},
    {"watch",
     "  erg watch ID         progress until the job ends (exit 0, 1 FAILED, 3 CANCELLED)\n"},
    {"cancel", "  erg cancel ID\n"},
    {"resume", "  erg resume ID        a FAILED job continues from its newest intact checkpoint\n"},
    {"steer", "  erg steer ID EVENTS.json   apply an erg.v1.Event (or a JSON array) now\n"},
    {"fetch", "  erg fetch ID [--step S | --all] --out DIR   snapshots (latest by default)\n"},
    {"preview", "  erg preview ID [--step S] --out FILE.png\n"},
};

void usage(std::ostream& out) {
  out << "erg " << ERG_VERSION << ": desert landscape simulation\n"
      << "on this machine:\n";
  for (const auto& u : kUsage) {
    if (std::string(u.name) == "submit")
      out << "on ergd, the job service (any of these also takes --server HOST:PORT --token T "
             "--ca FILE):\n";
    out << u.text;
  }
  out << "ergd is found from --server/--token/--ca, else ERG_SERVER/ERG_TOKEN/ERG_CA, else\n"
         "the config file $ERG_CONFIG or ~/.config/erg/config (lines `server = HOST:PORT`,\n"
         "`token = T`, `ca = FILE`); by default 127.0.0.1:7117 without TLS.\n"
         "exit codes: 0 ok; 1 error, or the watched job FAILED; 2 usage, invalid job or\n"
         "INVALID_ARGUMENT; 3 the watched job was CANCELLED; 4 UNAUTHENTICATED or\n"
         "PERMISSION_DENIED; 5 NOT_FOUND\n";
}

using RemoteCommand = int (*)(Remote&, const std::vector<std::string>&);

const std::map<std::string, RemoteCommand>& remote_commands() {
  static const std::map<std::string, RemoteCommand> m = {
      {"submit", cmd_submit}, {"jobs", cmd_jobs},       {"status", cmd_status},
      {"watch", cmd_watch},   {"cancel", cmd_cancel},   {"steer", cmd_steer},
      {"fetch", cmd_fetch},   {"preview", cmd_preview}, {"resume", cmd_resume}};
  return m;
}

int run_remote(const std::string& cmd, RemoteCommand fn, std::vector<std::string> args) {
  ConnectionSettings settings;
  try {
    const ConnectionFlags flags = extract_connection_flags(args);
    settings = resolve_connection(flags, process_env());
  } catch (const std::invalid_argument& e) {
    std::cerr << "erg: " << cmd << ": " << e.what() << "\n";
    return 2;
  }
  for (const auto& w : settings.warnings) std::cerr << "erg: warning: " << w << "\n";
  try {
    Remote remote(settings);
    return fn(remote, args);
  } catch (const std::exception& e) {
    std::cerr << "erg: " << cmd << ": " << e.what() << "\n";
    return 1;
  }
}

}  // namespace

std::string usage_of(const std::string& command) {
  for (const auto& u : kUsage)
    if (command == u.name) return std::string("usage:\n") + u.text;
  return "";
}

}  // namespace erg::client

int main(int argc, char** argv) {
  using namespace erg::client;
  if (argc < 2) {
    usage(std::cerr);
    return 2;
  }
  // The command is the first argument that is not a connection flag, so
  // `erg --server H:P jobs` works too.
  std::vector<std::string> args(argv + 1, argv + argc);
  size_t at = 0;
  while (at + 1 < args.size() &&
         (args[at] == "--server" || args[at] == "--token" || args[at] == "--ca"))
    at += 2;
  const std::string cmd = at < args.size() ? args[at] : "";
  if (at < args.size()) args.erase(args.begin() + static_cast<std::ptrdiff_t>(at));
  if (const auto it = remote_commands().find(cmd); it != remote_commands().end())
    return run_remote(cmd, it->second, std::move(args));
  if (at > 0) {
    std::cerr << "erg: " << args[0] << " is for the remote commands\n";
    usage(std::cerr);
    return 2;
  }
  if (cmd == "run") return cmd_run(args);
  if (cmd == "check") return cmd_check(args);
  if (cmd == "calibrate") return cmd_calibrate(args);
  if (cmd == "export") return cmd_export(args);
  if (cmd == "amplify") return cmd_amplify(args);
  if (cmd == "validate") return cmd_validate(args);
  if (cmd == "wind") return cmd_wind(args);
  if (cmd == "params") {
    std::cout << erg::job::parameter_table_markdown();
    return 0;
  }
  if (cmd == "version" || cmd == "--version") {
    std::cout << "erg " << ERG_VERSION << "\n";
    return 0;
  }
  if (cmd == "help" || cmd == "--help" || cmd == "-h") {
    usage(std::cout);
    return 0;
  }
  std::cerr << "erg: unknown command '" << cmd << "'\n";
  usage(std::cerr);
  return 2;
}

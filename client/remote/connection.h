// SPDX-License-Identifier: Apache-2.0
// The connection of the remote commands to ergd: one channel (TLS when a CA
// is configured), the JobService stub, per-call contexts carrying the bearer
// token and a deadline, and the one-line error reports.
#pragma once

#include <grpcpp/grpcpp.h>

#include <chrono>
#include <memory>
#include <string>

#include "erg/v1/service.grpc.pb.h"
#include "remote/config.h"

namespace erg::client {

// Deadlines of unary calls. SteerJob answers once the worker has applied the
// events at its next step boundary, which on a large domain takes a while.
inline constexpr std::chrono::seconds kUnaryDeadline{30};
inline constexpr std::chrono::seconds kSteerDeadline{300};
inline constexpr std::chrono::seconds kPreviewDeadline{120};

class Remote {
 public:
  // Throws std::runtime_error when the CA file cannot be read.
  explicit Remote(ConnectionSettings settings);

  const ConnectionSettings& settings() const { return settings_; }
  erg::v1::JobService::Stub& stub() { return *stub_; }

  // Adds `authorization: Bearer T` and, unless zero, a deadline.
  void prepare(grpc::ClientContext& ctx,
               std::chrono::seconds deadline = std::chrono::seconds{0}) const;

  // Prints the failure of `command` on stderr, one line:
  //   erg: COMMAND: CODE_NAME: message
  // or, when the server cannot be reached (UNAVAILABLE),
  //   erg: cannot reach ergd at ADDR (message)
  // and returns the exit code for it.
  int fail(const std::string& command, const grpc::Status& status) const;

 private:
  ConnectionSettings settings_;
  std::shared_ptr<grpc::Channel> channel_;
  std::unique_ptr<erg::v1::JobService::Stub> stub_;
};

// Sleeps `s` seconds (between reconnects).
void sleep_seconds(double s);

// From now on Ctrl-C (SIGINT) or SIGTERM prints "erg: TEXT" on its own line
// and exits with 130: what a watch or a download leaves behind ("the job
// goes on", "the .part is kept"). An empty text restores the default.
void set_interrupt_note(const std::string& text);

// GetJob for `command`; on failure reports the error and returns false with
// the exit code in `code`.
bool get_job(Remote& remote, const std::string& command, const std::string& id, erg::v1::Job* job,
             int* code);

}  // namespace erg::client

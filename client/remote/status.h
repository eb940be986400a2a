// SPDX-License-Identifier: Apache-2.0
// gRPC status codes as the remote commands report them: names, exit codes,
// which failures are worth a reconnect, and the reconnect schedule. Part of
// erg_client_lib (plain ints, no gRPC headers), unit-tested.
#pragma once

#include <string>

namespace erg::client {

// Exit codes of the remote commands (documented in `erg help`).
inline constexpr int kExitOk = 0;
inline constexpr int kExitError = 1;      // any other failure; watch: the job FAILED
inline constexpr int kExitUsage = 2;      // bad arguments, invalid job, INVALID_ARGUMENT
inline constexpr int kExitCancelled = 3;  // watch: the job was CANCELLED
inline constexpr int kExitAuth = 4;       // UNAUTHENTICATED, PERMISSION_DENIED
inline constexpr int kExitNotFound = 5;   // NOT_FOUND

// "UNAVAILABLE" for 14, ...; "CODE_<n>" for a number gRPC does not define.
std::string status_code_name(int code);

// The exit code of a command that failed with gRPC status `code`.
int exit_code_for_status(int code);

// True when a stream (WatchJob, StreamSnapshot) that ended with this status
// should be opened again, resuming: the server or the connection went away
// (UNAVAILABLE, a reset or removed stream, a server-side cancel), not a
// refusal.
bool is_stream_break(int code, const std::string& message);

// When to try again after a lost connection: waits of `first_s`, doubling,
// at most `cap_s`, until `give_up_s` have passed since the first failure in
// a row; reset() after any success.
class RetryBudget {
 public:
  explicit RetryBudget(double give_up_s = 30, double first_s = 0.25, double cap_s = 4)
      : give_up_s_(give_up_s), first_s_(first_s), cap_s_(cap_s) {}
  // The wait before the next attempt, or a negative number to give up.
  // `now_s` is a monotonic clock in seconds.
  double next_delay(double now_s);
  void reset() { failing_since_ = -1; }
  // Seconds since the first failure in a row (0 when not failing).
  double failing_for(double now_s) const { return failing_since_ < 0 ? 0 : now_s - failing_since_; }

 private:
  double give_up_s_, first_s_, cap_s_;
  double failing_since_ = -1;
  double next_ = 0;
};

// Monotonic seconds (steady_clock).
double monotonic_seconds();

}  // namespace erg::client

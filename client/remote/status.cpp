// SPDX-License-Identifier: Apache-2.0
#include "remote/status.h"

#include <algorithm>
#include <chrono>

namespace erg::client {

std::string status_code_name(int code) {
  static const char* const kNames[] = {"OK",
                                       "CANCELLED",
                                       "UNKNOWN",
                                       "INVALID_ARGUMENT",
                                       "DEADLINE_EXCEEDED",
                                       "NOT_FOUND",
                                       "ALREADY_EXISTS",
                                       "PERMISSION_DENIED",
                                       "RESOURCE_EXHAUSTED",
                                       "FAILED_PRECONDITION",
                                       "ABORTED",
                                       "OUT_OF_RANGE",
                                       "UNIMPLEMENTED",
                                       "INTERNAL",
                                       "UNAVAILABLE",
                                       "DATA_LOSS",
                                       "UNAUTHENTICATED"};
  if (code >= 0 && code < static_cast<int>(sizeof kNames / sizeof kNames[0])) return kNames[code];
  return "CODE_" + std::to_string(code);
}

int exit_code_for_status(int code) {
  switch (code) {
    case 0:
      return kExitOk;
    case 3:  // INVALID_ARGUMENT
      return kExitUsage;
    case 5:  // NOT_FOUND
      return kExitNotFound;
    case 7:   // PERMISSION_DENIED
    case 16:  // UNAUTHENTICATED
      return kExitAuth;
    default:
      return kExitError;
  }
}

bool is_stream_break(int code, const std::string& message) {
  switch (code) {
    case 14:  // UNAVAILABLE: no connection, or the server went away
    case 1:   // CANCELLED by the server (shutting down); the client never cancels a live one
    case 10:  // ABORTED
      return true;
    case 2:   // UNKNOWN
    case 13:  // INTERNAL: a connection reset mid-stream reads as one of these
      return message.find("RST_STREAM") != std::string::npos ||
             message.find("Stream removed") != std::string::npos ||
             message.find("Socket closed") != std::string::npos ||
             message.find("Connection reset") != std::string::npos;
    default:
      return false;
  }
}

double RetryBudget::next_delay(double now_s) {
  if (failing_since_ < 0) {
    failing_since_ = now_s;
    next_ = first_s_;
  }
  const double elapsed = now_s - failing_since_;
  if (elapsed >= give_up_s_) return -1;
  const double wait = std::min({next_, cap_s_, give_up_s_ - elapsed});
  next_ = std::min(next_ * 2, cap_s_);
  return wait;
}

double monotonic_seconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

}  // namespace erg::client

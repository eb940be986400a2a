// SPDX-License-Identifier: Apache-2.0
// Sign-in throttling per client address: a token bucket of failed sign-ins.
// An address may fail kBurst times at once, then once every kRefill; while
// its bucket is empty its sign-ins are refused (429) without looking at the
// token, so guessing tokens through the dashboard runs at 10 a minute.
#pragma once

#include <chrono>
#include <map>
#include <mutex>
#include <string>

namespace erg::server {

class SignInThrottle {
 public:
  static constexpr double kBurst = 10;
  static constexpr double kRefillS = 6;
  static constexpr size_t kMaxAddresses = 100000;
  // 0 when `address` may try now, else the seconds until it may.
  double wait_s(const std::string& address);
  void failed(const std::string& address);

 private:
  using Clock = std::chrono::steady_clock;
  struct Bucket {
    double tokens = kBurst;
    Clock::time_point at;
  };
  Bucket& bucket_locked(const std::string& address, Clock::time_point now);
  std::mutex mu_;
  std::map<std::string, Bucket> buckets_;
};

}  // namespace erg::server

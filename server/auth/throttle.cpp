// SPDX-License-Identifier: Apache-2.0
#include "auth/throttle.h"

#include <algorithm>

namespace erg::server {

SignInThrottle::Bucket& SignInThrottle::bucket_locked(const std::string& address,
                                                      Clock::time_point now) {
  if (buckets_.size() >= kMaxAddresses) {
    // Forget the addresses whose buckets are full again (they lose nothing).
    for (auto it = buckets_.begin(); it != buckets_.end();) {
      const double dt = std::chrono::duration<double>(now - it->second.at).count();
      it = it->second.tokens + dt / kRefillS >= kBurst ? buckets_.erase(it) : std::next(it);
    }
  }
  auto [it, created] = buckets_.try_emplace(address);
  Bucket& b = it->second;
  if (created) b.at = now;
  const double dt = std::chrono::duration<double>(now - b.at).count();
  b.tokens = std::min(kBurst, b.tokens + dt / kRefillS);
  b.at = now;
  return b;
}

double SignInThrottle::wait_s(const std::string& address) {
  std::lock_guard lock(mu_);
  Bucket& b = bucket_locked(address, Clock::now());
  return b.tokens >= 1 ? 0.0 : (1 - b.tokens) * kRefillS;
}

void SignInThrottle::failed(const std::string& address) {
  std::lock_guard lock(mu_);
  Bucket& b = bucket_locked(address, Clock::now());
  b.tokens = std::max(0.0, b.tokens - 1);
}

}  // namespace erg::server

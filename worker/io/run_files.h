// SPDX-License-Identifier: Apache-2.0
// The names of the files a run writes (README, "Outputs"), for every program
// that makes or looks for them: erg-worker, ergd, erg fetch, erg export and
// erg amplify.
//   DIR/snapshots/step_NNNNNNNN.h5 (.xdmf)   DIR/previews/step_NNNNNNNN.png
//   DIR/checkpoints/step_NNNNNNNN.h5
// Eight digits, zero-padded, so that name order is step order.
#pragma once

#include <cstdint>
#include <cstdio>
#include <string>

namespace erg {

// "step_00000042" for step 42 (no extension).
inline std::string step_name(std::int64_t step) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "step_%08lld", static_cast<long long>(step));
  return buf;
}

}  // namespace erg

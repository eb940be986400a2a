// SPDX-License-Identifier: Apache-2.0
// The error every file writer and reader of erg throws (io.h, atomic_file.h).
// On its own so that programs which only write files atomically (ergd, erg's
// downloads) need none of io.h's dependencies (MPI, HDF5).
#pragma once

#include <stdexcept>

namespace erg::io {

// Raised for any I/O failure; the message names the file and the cause.
struct IoError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

}  // namespace erg::io

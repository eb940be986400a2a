// SPDX-License-Identifier: Apache-2.0
// Checksums that let a checkpoint prove its integrity (internal to erg_io).
//
// A checkpoint carries one root attribute "checksums", written after
// everything else: a checksum of each dataset, of the stored job spec and of
// the other root attributes (format, version, step, grid, ledgers). Readers
// recompute them and refuse the file on any difference, naming what differs,
// so a flipped bit anywhere in the state is an error and never a silently
// different run.
//
// The checksum ("sum64") of an array is a sum, modulo 2^64, of one term per
// element: term = mix(mix(key ^ index) ^ bits), where key comes from the
// dataset's name, index is the element's row-major position in the global
// grid, bits its value's bit pattern and mix the SplitMix64 finaliser (a
// bijection of 64-bit words). Why this and not SHA-256 of the bytes:
//   - A sum is independent of who adds which cells: each rank of a parallel
//     write sums its own tile, and one MPI_Allreduce gives the checksum of the
//     whole dataset, with no gather of the grid on one rank and the same value
//     for any tiling, rank count or chunking (a resume may use another tiling).
//   - For a fixed cell the term is a bijection of the value, so any change
//     confined to one cell (every single bit flip) is detected with
//     certainty; changes spread over several cells escape with probability
//     about 2^-64, far below any other failure rate of the machine.
//   - The threat is corruption (a disk, a copy, a truncation), not forgery:
//     checkpoints are written by the worker in its own output directory, so
//     a keyed or cryptographic hash would add cost and no protection.
// Strings are summed the same way over 8-byte words, plus their length.
#pragma once

#include <mpi.h>

#include <array>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "io/io.h"

namespace erg::io::detail {

class Checksums {
 public:
  // The cells of `slab` (row-major [slab.ny][slab.nx]) of a dataset of a
  // global grid `global_nx` wide. Adding the same name again adds to its sum
  // (used by nothing but harmless); names are kept in first-added order.
  void add_cells(const std::string& name, const std::int64_t* v, const TileSlab& slab,
                 int global_nx);
  void add_cells(const std::string& name, const float* v, const TileSlab& slab, int global_nx);
  void add_text(const std::string& name, const std::string& s);

  // Collective: sums every rank's partial checksums (same names, same order
  // on every rank).
  void allreduce(MPI_Comm comm);

  // The attribute text: "erg-sum64\n" then "NAME HEX16\n" per entry.
  std::string record() const;
  // Parses a record; throws IoError naming `path` when it is not one.
  static Checksums parse(const std::string& record, const std::string& path);

  // "" when `stored` lists the same names with the same values as *this;
  // otherwise what differs, e.g. "checksum of dataset 'sand_units' does not
  // match (stored 0x..., computed 0x...)".
  // complete false: names of `stored` that *this lacks are not compared.
  std::string mismatch(const Checksums& stored, bool complete = true) const;

  const std::vector<std::pair<std::string, std::uint64_t>>& entries() const { return entries_; }

 private:
  std::uint64_t& slot(const std::string& name);
  std::vector<std::pair<std::string, std::uint64_t>> entries_;
};

// The root attribute that holds the record.
inline constexpr const char* kChecksumsAttr = "checksums";

// The checksums of a checkpoint's arrays over `slab` (the whole grid for a
// serial file; a rank's tile in a parallel one, to be allreduce()d).
// present[id]: whether the state field's dataset is (to be) in the file.
Checksums checkpoint_cell_checksums(const Checkpoint& c, const TileSlab& slab,
                                    const std::array<bool, fields::kCount>& present);
// Adds the checksums of its spec ("job_spec") and of its other attributes
// ("attributes": format, format_version, step, nx, ny and the ledgers in
// order); after allreduce() in a parallel file (they are the same on every
// rank).
void add_checkpoint_attr_checksums(Checksums& sums, const Checkpoint& c, const std::string& format,
                                   std::int64_t format_version);

}  // namespace erg::io::detail

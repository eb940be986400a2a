// SPDX-License-Identifier: Apache-2.0
// Internal to erg_io: the parts of the snapshot and checkpoint file contracts
// that the serial writers (snapshot.cpp, checkpoint.cpp) and the parallel ones
// (parallel.cpp) share, so that both kinds of writer produce the same files:
// dataset names and element types, deflate levels, root attributes, and the
// validation of a checkpoint's header and ledgers. Defined in snapshot.cpp and
// checkpoint.cpp.
#pragma once

#include <hdf5.h>

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "io/hdf5_util.h"
#include "io/integrity.h"
#include "io/io.h"

namespace erg::io::detail {

// ---- snapshots ----------------------------------------------------------------

// Snapshots are written once and read many times (ParaView, scripts), so a
// middle deflate level is worth its cost.
inline constexpr int kSnapshotDeflate = 4;

// Fails unless nx and ny are positive ("invalid grid ...").
void check_grid(const std::string& path, int nx, int ny);

// One float32 layer of a snapshot: /<name>, [1][ny][nx] (dimensions time, y,
// x; cf.h). Its values in memory are data[stride * c + offset] for the cells c
// in row-major order (io.h LayerValues).
struct SnapshotLayer {
  const char* name;
  const float* data;
  int stride = 1, offset = 0;
};
// The layers `ids` of f (registry snapshot fields, io.h snapshot_layer_ids),
// in that order, their pointers as given (which may be null).
std::vector<SnapshotLayer> snapshot_layers(const SnapshotFields& f,
                                           const std::vector<fields::Id>& ids);
// Fails unless every required layer (not snapshot.optional in the registry)
// is given ("snapshot needs bedrock, sand, vegetation, wind_x, wind_y ...").
void check_required_layers(const std::string& path, const SnapshotFields& f,
                           const std::string& where = "");

// The memory dataspace of a layer's values for `cells` cells (a strided
// selection of cells * stride floats).
Hid layer_memory_space(const SnapshotLayer& l, std::size_t cells, const std::string& path);

// The root attributes of a snapshot (SnapshotMeta plus the fixed "periodic"
// and "units").
void write_snapshot_attrs(hid_t file, const SnapshotMeta& meta, const std::string& path);
// time_s, time_years, the wind state and the calibration (called by the above).
void write_physical_attrs(hid_t file, const SnapshotMeta& meta, const std::string& path);

// ---- checkpoints --------------------------------------------------------------

// Checkpoints are written often and read only on restart: favour speed.
inline constexpr int kCheckpointDeflate = 1;

// Fails unless every state field that is not checkpoint_optional has n values
// ("checkpoint field 'sand_units' has 3 values, expected <expected> = n<suffix>").
void check_checkpoint_sizes(const Checkpoint& c, std::size_t n, const std::string& path,
                            const std::string& expected, const std::string& suffix = "");

// Reads every state field of the registry that the file has (an optional
// one may be missing) with read(name, H5T_NATIVE_INT64 or H5T_NATIVE_FLOAT,
// c.units[id] or c.reals[id]); returns which were there.
template <class Read>
std::array<bool, fields::kCount> read_checkpoint_fields(hid_t fid, Checkpoint& c, Read&& read) {
  std::array<bool, fields::kCount> present{};
  for (int i = 0; i < fields::kCount; ++i) {
    const auto id = static_cast<fields::Id>(i);
    const fields::Info& f = fields::info(id);
    if (!f.state || (f.checkpoint_optional && !link_exists(fid, f.checkpoint))) continue;
    present[id] = true;
    if (f.type == fields::Type::kUnits)
      read(f.checkpoint, H5T_NATIVE_INT64, c.units[id]);
    else
      read(f.checkpoint, H5T_NATIVE_FLOAT, c.reals[id]);
  }
  return present;
}

// Fails on an empty, repeated or non-decimal ledger entry.
void check_checkpoint_ledger(const Checkpoint& c, const std::string& path);

// The file creation properties of a checkpoint: attribute creation order is
// tracked so that the ledger reads back in the order it was written.
Hid checkpoint_fcpl(const std::string& path);

// Root attributes: format, format_version, step, nx, ny, job_spec, ledger_*.
void write_checkpoint_attrs(hid_t file, const Checkpoint& c, const std::string& path);

// Identifies the file as an erg checkpoint of a supported version and reads
// step, nx, ny (validated) and job_spec; the arrays and ledger stay empty.
Checkpoint read_checkpoint_header(hid_t file, const std::string& path);

// Appends the ledgers (in creation order where tracked) to c.ledger.
void read_checkpoint_ledger(hid_t file, const std::string& path, Checkpoint& c);

// Integrity (integrity.h). The cell checksums (summed over ranks when
// parallel) completed with those of the spec and the attributes.
Checksums checkpoint_checksums_done(Checksums cells, const Checkpoint& c);
// Writes the "checksums" attribute: the last thing written to a checkpoint.
void write_checkpoint_checksums(hid_t file, const Checksums& sums, const std::string& path);
// Fails ("checkpoint is corrupt: checksum of dataset 'sand_units' does not
// match ...") unless the file's checksums are those computed from what was
// read. all_cells false: the reader read part of the grid, and `computed`
// holds the spec's and attributes' checksums only (the datasets are not
// verified).
void verify_checkpoint(hid_t file, const Checksums& computed, const std::string& path,
                       bool all_cells = true);

}  // namespace erg::io::detail

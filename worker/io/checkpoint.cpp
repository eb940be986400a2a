// SPDX-License-Identifier: Apache-2.0
// Checkpoints: the exact integer state of a run in one HDF5 file, enough to
// continue bitwise identically. Layout (all [ny][nx], deflate + shuffle):
// one dataset per state field of the registry (core/fields.h), in its order
// and under its checkpoint name: int64 /bedrock_units /sand_units
// /airborne_units, float32 /vegetation /resistance /obstacles (optional:
// files written before obstacles existed lack it);
// root attributes: format = "erg-checkpoint", format_version = 2, step, nx,
// ny (int64), job_spec (string), one string "ledger_<name>" per ledger and,
// written last, "checksums" (integrity.h): readers verify every dataset, the
// spec and the other attributes against it.
#include <array>
#include <climits>
#include <cstdint>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "io/atomic_file.h"
#include "io/formats.h"
#include "io/hdf5_util.h"
#include "io/integrity.h"
#include "io/io.h"

namespace erg::io {
namespace {

using detail::AtomicFile;
using detail::fail;
using detail::Hid;
using detail::kCheckpointDeflate;

constexpr const char* kFormat = "erg-checkpoint";
// 2: with checksums. Version 1 files (no checksums) cannot prove their
// integrity and are refused.
constexpr std::int64_t kFormatVersion = 2;
constexpr const char* kLedgerPrefix = "ledger_";

// A ledger value is an exact decimal integer, optionally negative.
bool is_decimal(const std::string& s) {
  std::size_t i = !s.empty() && s[0] == '-' ? 1 : 0;
  if (i == s.size()) return false;
  for (; i < s.size(); ++i) {
    if (s[i] < '0' || s[i] > '9') return false;
  }
  return true;
}

herr_t collect_ledger_name(hid_t /*loc*/, const char* name, const H5A_info_t* /*info*/,
                           void* data) {
  try {
    std::string n = name;
    if (n.rfind(kLedgerPrefix, 0) == 0) static_cast<std::vector<std::string>*>(data)->push_back(n);
  } catch (...) {
    return -1;  // no exception may cross the C library
  }
  return 0;
}

}  // namespace

// ---- shared with the parallel writer and reader (formats.h) -------------------

void detail::check_checkpoint_sizes(const Checkpoint& c, std::size_t n, const std::string& path,
                                    const std::string& expected, const std::string& suffix) {
  for (int i = 0; i < fields::kCount; ++i) {
    const auto id = static_cast<fields::Id>(i);
    const fields::Info& f = fields::info(id);
    if (!f.state || (f.checkpoint_optional && c.size(id) == 0)) continue;
    if (c.size(id) != n) {
      fail(path, std::string("checkpoint field '") + f.checkpoint + "' has " +
                     std::to_string(c.size(id)) + " values, expected " + expected + " = " +
                     std::to_string(n) + suffix);
    }
  }
}

void detail::check_checkpoint_ledger(const Checkpoint& c, const std::string& path) {
  for (std::size_t i = 0; i < c.ledger.size(); ++i) {
    const auto& [name, value] = c.ledger[i];
    if (name.empty()) fail(path, "ledger entry with an empty name");
    if (!is_decimal(value)) {
      fail(path, "ledger '" + name + "' value '" + value + "' is not a decimal integer");
    }
    for (std::size_t j = 0; j < i; ++j) {
      if (c.ledger[j].first == name) fail(path, "ledger '" + name + "' appears twice");
    }
  }
}

// Track attribute creation order on the root group so the ledger reads back in
// the order it was written.
Hid detail::checkpoint_fcpl(const std::string& path) {
  Hid fcpl = checked(H5Pcreate(H5P_FILE_CREATE), H5Pclose, path, "H5Pcreate(fcpl)");
  check(H5Pset_attr_creation_order(fcpl.get(), H5P_CRT_ORDER_TRACKED | H5P_CRT_ORDER_INDEXED), path,
        "H5Pset_attr_creation_order");
  return fcpl;
}

void detail::write_checkpoint_attrs(hid_t fid, const Checkpoint& c, const std::string& path) {
  write_attr_str(fid, "format", kFormat, path);
  write_attr_i64(fid, "format_version", kFormatVersion, path);
  write_attr_i64(fid, "step", c.step, path);
  write_attr_i64(fid, "nx", c.nx, path);
  write_attr_i64(fid, "ny", c.ny, path);
  write_attr_str(fid, "job_spec", c.job_spec_json, path);
  for (const auto& [name, value] : c.ledger) {
    write_attr_str(fid, kLedgerPrefix + name, value, path);
  }
}

Checkpoint detail::read_checkpoint_header(hid_t fid, const std::string& path) {
  // Identify the file before anything else, so that handing a snapshot or
  // any other HDF5 file to --resume says so plainly.
  if (H5Aexists(fid, "format") <= 0 || read_attr_str(fid, "format", path) != kFormat) {
    fail(path,
         "not an erg checkpoint (root attribute 'format' is not \"" + std::string(kFormat) + "\")");
  }
  std::int64_t version = read_attr_i64(fid, "format_version", path);
  if (version == 1) {
    fail(path,
         "checkpoint format_version 1 carries no checksums (written by an erg before checkpoints "
         "proved their integrity); this build reads format_version " +
             std::to_string(kFormatVersion) + " only");
  }
  if (version != kFormatVersion) {
    fail(path, "checkpoint format_version " + std::to_string(version) +
                   " is not supported (this build reads " + std::to_string(kFormatVersion) + ")");
  }

  Checkpoint c;
  c.step = read_attr_i64(fid, "step", path);
  std::int64_t nx = read_attr_i64(fid, "nx", path);
  std::int64_t ny = read_attr_i64(fid, "ny", path);
  if (nx <= 0 || ny <= 0 || nx > INT_MAX || ny > INT_MAX) {
    fail(path,
         "checkpoint grid " + std::to_string(nx) + " x " + std::to_string(ny) + " is out of range");
  }
  c.nx = static_cast<int>(nx);
  c.ny = static_cast<int>(ny);
  c.job_spec_json = read_attr_str(fid, "job_spec", path);
  return c;
}

void detail::read_checkpoint_ledger(hid_t fid, const std::string& path, Checkpoint& c) {
  // Ledgers in creation order; a file made without creation-order tracking
  // (by another tool) falls back to name order.
  std::vector<std::string> names;
  hsize_t idx = 0;
  if (H5Aiterate2(fid, H5_INDEX_CRT_ORDER, H5_ITER_INC, &idx, collect_ledger_name, &names) < 0) {
    H5Eclear2(H5E_DEFAULT);
    names.clear();
    idx = 0;
    check(H5Aiterate2(fid, H5_INDEX_NAME, H5_ITER_INC, &idx, collect_ledger_name, &names), path,
          "cannot list attributes");
  }
  for (const std::string& attr : names) {
    std::string value = read_attr_str(fid, attr, path);
    std::string name = attr.substr(std::string(kLedgerPrefix).size());
    if (!is_decimal(value)) {
      fail(path, "ledger '" + name + "' value '" + value + "' is not a decimal integer");
    }
    c.ledger.emplace_back(std::move(name), std::move(value));
  }
}

detail::Checksums detail::checkpoint_checksums_done(Checksums cells, const Checkpoint& c) {
  add_checkpoint_attr_checksums(cells, c, kFormat, kFormatVersion);
  return cells;
}

void detail::write_checkpoint_checksums(hid_t fid, const Checksums& sums, const std::string& path) {
  write_attr_str(fid, kChecksumsAttr, sums.record(), path);
}

void detail::verify_checkpoint(hid_t fid, const Checksums& computed, const std::string& path,
                               bool all_cells) {
  if (H5Aexists(fid, kChecksumsAttr) <= 0) {
    H5Eclear2(H5E_DEFAULT);
    fail(path, "checkpoint carries no checksums attribute: it cannot prove its integrity");
  }
  const Checksums stored = Checksums::parse(read_attr_str(fid, kChecksumsAttr, path), path);
  const std::string diff = computed.mismatch(stored, all_cells);
  if (!diff.empty()) fail(path, "checkpoint is corrupt: " + diff);
}

void write_checkpoint(const std::string& path, const Checkpoint& c) {
  // Validate everything before touching the disk.
  if (c.nx <= 0 || c.ny <= 0) {
    fail(path, "invalid grid " + std::to_string(c.nx) + " x " + std::to_string(c.ny) +
                   " (nx and ny must be positive)");
  }
  detail::check_checkpoint_sizes(c, static_cast<std::size_t>(c.nx) * static_cast<std::size_t>(c.ny),
                                 path, "nx * ny");
  detail::check_checkpoint_ledger(c, path);

  AtomicFile out(path);
  std::vector<char> image;
  {
    detail::Hdf5Guard guard;
    Hid fcpl = detail::checkpoint_fcpl(path);
    Hid file = detail::create_hdf5_in_memory(out, fcpl.get());
    const hid_t fid = file.get();
    const std::vector<hsize_t> grid = {static_cast<hsize_t>(c.ny), static_cast<hsize_t>(c.nx)};
    std::array<bool, fields::kCount> present{};
    for (int i = 0; i < fields::kCount; ++i) {
      const auto id = static_cast<fields::Id>(i);
      const fields::Info& f = fields::info(id);
      if (!f.state || (f.checkpoint_optional && c.size(id) == 0)) continue;
      present[id] = true;
      if (f.type == fields::Type::kUnits)
        detail::write_dataset(fid, f.checkpoint, H5T_STD_I64LE, H5T_NATIVE_INT64, grid,
                              c.units[id].data(), kCheckpointDeflate, path);
      else
        detail::write_dataset(fid, f.checkpoint, H5T_IEEE_F32LE, H5T_NATIVE_FLOAT, grid,
                              c.reals[id].data(), kCheckpointDeflate, path);
    }

    detail::write_checkpoint_attrs(fid, c, path);
    const TileSlab all{0, 0, c.nx, c.ny};
    detail::write_checkpoint_checksums(
        fid,
        detail::checkpoint_checksums_done(detail::checkpoint_cell_checksums(c, all, present), c),
        path);

    image = detail::take_hdf5_image(file, path);
  }
  out.write_whole(image.data(), image.size());
  out.commit();
}

Checkpoint read_checkpoint(const std::string& path) {
  detail::Hdf5Guard guard;
  Hid file = detail::open_hdf5_readonly(path, "checkpoint");
  const hid_t fid = file.get();

  Checkpoint c = detail::read_checkpoint_header(fid, path);
  const std::int64_t nx = c.nx, ny = c.ny;

  // Every dataset must be exactly [ny][nx]; read_dataset says which is not.
  const std::vector<hsize_t> grid = {static_cast<hsize_t>(ny), static_cast<hsize_t>(nx)};
  const std::array<bool, fields::kCount> present =
      detail::read_checkpoint_fields(fid, c, [&](const char* name, hid_t mem_type, auto& values) {
        using T = typename std::decay_t<decltype(values)>::value_type;
        values = detail::read_dataset<T>(fid, name, mem_type, grid, path);
      });

  detail::read_checkpoint_ledger(fid, path, c);
  const TileSlab all{0, 0, c.nx, c.ny};
  detail::verify_checkpoint(
      fid, detail::checkpoint_checksums_done(detail::checkpoint_cell_checksums(c, all, present), c),
      path);
  return c;
}

}  // namespace erg::io

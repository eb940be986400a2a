// SPDX-License-Identifier: Apache-2.0
// Snapshots and checkpoints written and read by every rank of a communicator
// through parallel HDF5 (the mpio driver): each rank writes or reads its tile
// as a hyperslab of the global datasets, collectively. The files are the same
// as the serial writers' (formats.h holds what both share); only the chunk
// shape differs (one chunk per tile here, at most 256 x 256 there), which a
// reader does not see.
//
// Failures. Parallel HDF5 calls that create, write or close objects are
// collective: a rank that throws while the others carry on would leave them
// waiting forever in the next collective call. So no HDF5 failure (nor a bad
// argument) throws where it happens; each step records it on its rank
// (Collective::run), and after each step all ranks agree on whether any rank
// failed (Collective::agree, one MPI_Allreduce). If one did, every rank throws
// the same IoError (the first failing rank's message, naming path and cause)
// at the same point, so the HDF5 objects are closed collectively on the way
// out, and rank 0 removes the temporary.
//
// Atomicity: rank 0 picks "<path>.tmp-<rank 0's pid>"; all ranks create it,
// rank 0 reserves its disk space (see reserve_space), all ranks write, flush
// (MPI_File_sync) and close it; once every rank has closed it, rank 0 fsyncs
// it, renames it over <path> and fsyncs the directory; a last agreement means
// no rank returns before <path> names the new file.
//
// HDF5 1.10.8 notes. Compressed (filtered) datasets can only be written
// collectively, and a rank with no cells must still take part in H5Dwrite
// (with an empty selection). Attributes are metadata: every rank must create
// and write each one with identical values, so the writers first check that
// the ranks agree on every value (broadcast from rank 0 and compared).
#include <fcntl.h>
#include <hdf5.h>
#include <mpi.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <string>
#include <utility>
#include <vector>

#include "io/atomic_file.h"
#include "io/cf.h"
#include "io/formats.h"
#include "io/hdf5_util.h"
#include "io/io.h"

namespace erg::io {
namespace {

using detail::fail;
using detail::Hid;

// ---- agreement between ranks ----------------------------------------------------

class Collective {
 public:
  Collective(MPI_Comm comm, const std::string& path) : comm_(comm), path_(path) {
    MPI_Comm_rank(comm_, &rank_);
    MPI_Comm_size(comm_, &size_);
  }

  MPI_Comm comm() const { return comm_; }
  int rank() const { return rank_; }
  int size() const { return size_; }

  // Runs one local step unless this rank has already failed; a failure is
  // recorded, not thrown (agree() throws it on every rank).
  template <class F>
  void run(F&& step) {
    if (!error_.empty()) return;
    try {
      step();
    } catch (const IoError& e) {
      error_ = e.what();
    } catch (const std::exception& e) {
      error_ = path_ + ": " + e.what();
    } catch (...) {
      error_ = path_ + ": unknown error";
    }
  }

  // Collective. Returns when no rank has failed; otherwise throws, on every
  // rank, the message of the lowest failing rank.
  void agree() {
    int mine = error_.empty() ? size_ : rank_;
    int first = size_;
    MPI_Allreduce(&mine, &first, 1, MPI_INT, MPI_MIN, comm_);
    if (first == size_) return;
    int failed = error_.empty() ? 0 : 1;
    MPI_Allreduce(MPI_IN_PLACE, &failed, 1, MPI_INT, MPI_SUM, comm_);
    std::string message = bcast(error_, first);
    const std::string n = std::to_string(size_), r = std::to_string(first);
    if (size_ == 1) {
      // Nothing to add.
    } else if (failed == size_) {
      message += " (on every rank)";
    } else if (failed == 1) {
      message += " (on rank " + r + " of " + n + ")";
    } else {
      message +=
          " (on " + std::to_string(failed) + " of " + n + " ranks; rank " + r + "'s message)";
    }
    throw IoError(message);
  }

  // Collective: `s` as rank `root` has it.
  std::string bcast(const std::string& s, int root) const {
    unsigned long long n = rank_ == root ? s.size() : 0;
    MPI_Bcast(&n, 1, MPI_UNSIGNED_LONG_LONG, root, comm_);
    std::string out = rank_ == root ? s : std::string(static_cast<std::size_t>(n), '\0');
    // In pieces: MPI counts are int.
    constexpr std::size_t kPiece = std::size_t{1} << 30;
    for (std::size_t off = 0; off < out.size(); off += kPiece) {
      const std::size_t len = std::min(kPiece, out.size() - off);
      MPI_Bcast(out.data() + off, static_cast<int>(len), MPI_CHAR, root, comm_);
    }
    return out;
  }

 private:
  MPI_Comm comm_;
  std::string path_;
  int rank_ = 0, size_ = 1;
  std::string error_;
};

// Values every rank must pass identically (attributes, grid and chunk sizes),
// by name. check() fails, on every rank, when some rank's differ from rank 0's.
class SameOnAllRanks {
 public:
  void add(const std::string& name, const std::string& value) { items_.emplace_back(name, value); }
  void add(const std::string& name, std::int64_t v) { add(name, std::to_string(v)); }
  void add(const std::string& name, std::uint64_t v) { add(name, std::to_string(v)); }
  void add(const std::string& name, double v) {
    // The bits, so that -0.0 and NaN payloads count as different values.
    std::uint64_t bits = 0;
    std::memcpy(&bits, &v, sizeof bits);
    add(name, bits);
  }
  // The grid and its chunks, which both files' writers agree on first.
  void add_grid(int nx, int ny, int chunk_nx, int chunk_ny) {
    add("nx", std::int64_t{nx});
    add("ny", std::int64_t{ny});
    add("chunk_nx", std::int64_t{chunk_nx});
    add("chunk_ny", std::int64_t{chunk_ny});
  }

  // Collective: rank 0's values are broadcast and compared on every rank.
  void check(Collective& co, const std::string& path) const {
    std::string mine;
    for (const auto& item : items_) {
      mine += std::to_string(item.second.size());
      mine += ':';
      mine += item.second;
    }
    const std::string root = co.bcast(mine, 0);
    co.run([&] {
      if (root == mine) return;
      // Find the first value that differs, to name it.
      std::size_t pos = 0;
      for (const auto& [name, value] : items_) {
        const std::size_t colon = root.find(':', pos);
        std::size_t len = 0;
        bool same = colon != std::string::npos;
        if (same) {
          len = std::stoull(root.substr(pos, colon - pos));
          same = root.compare(colon + 1, len, value) == 0 && len == value.size();
        }
        if (!same) {
          fail(path, "the ranks disagree on '" + name + "': rank " + std::to_string(co.rank()) +
                         " passed another value than rank 0 (every rank must pass the same)");
        }
        pos = colon + 1 + len;
      }
      fail(path, "the ranks disagree on the file's metadata");
    });
    co.agree();
  }

 private:
  std::vector<std::pair<std::string, std::string>> items_;
};

// ---- tiles ------------------------------------------------------------------------

std::string slab_text(const TileSlab& s) {
  return std::to_string(s.nx) + " x " + std::to_string(s.ny) + " cells at (x " +
         std::to_string(s.x0) + ", y " + std::to_string(s.y0) + ")";
}

std::size_t slab_cells(const TileSlab& s) {
  return static_cast<std::size_t>(s.nx) * static_cast<std::size_t>(s.ny);
}

bool slab_empty(const TileSlab& s) {
  return s.nx == 0 || s.ny == 0;
}

// The slab lies within the global grid (an empty slab anywhere is fine).
void check_slab(const std::string& path, const TileSlab& s, int nx, int ny) {
  if (s.nx < 0 || s.ny < 0) fail(path, "invalid tile " + slab_text(s) + ": negative size");
  if (slab_empty(s)) return;
  if (s.x0 < 0 || s.y0 < 0 || s.x0 > nx - s.nx || s.y0 > ny - s.ny) {
    fail(path, "tile " + slab_text(s) + " is not inside the " + std::to_string(nx) + " x " +
                   std::to_string(ny) + " grid");
  }
}

// Collective: the writers' tiles must cover the grid exactly once, or the file
// would have holes (or cells written twice). Every rank checks its own tile
// against all others, so the cost is O(ranks) per rank.
void check_tiling(Collective& co, const std::string& path, const TileSlab& mine, int nx, int ny) {
  std::vector<int> all(static_cast<std::size_t>(co.size()) * 4);
  int m[4] = {mine.x0, mine.y0, mine.nx, mine.ny};
  MPI_Allgather(m, 4, MPI_INT, all.data(), 4, MPI_INT, co.comm());
  co.run([&] {
    check_slab(path, mine, nx, ny);
    std::size_t cells = 0;
    for (int r = 0; r < co.size(); ++r) {
      const TileSlab t{all[4 * r], all[4 * r + 1], all[4 * r + 2], all[4 * r + 3]};
      if (t.nx > 0 && t.ny > 0) cells += slab_cells(t);
      if (r == co.rank() || slab_empty(t) || slab_empty(mine)) continue;
      const bool overlap = t.x0 < mine.x0 + mine.nx && mine.x0 < t.x0 + t.nx &&
                           t.y0 < mine.y0 + mine.ny && mine.y0 < t.y0 + t.ny;
      if (overlap) {
        fail(path, "the tile of rank " + std::to_string(co.rank()) + " (" + slab_text(mine) +
                       ") overlaps that of rank " + std::to_string(r) + " (" + slab_text(t) + ")");
      }
    }
    const std::size_t want = static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny);
    if (cells != want) {
      fail(path, "the tiles of the " + std::to_string(co.size()) + " ranks cover " +
                     std::to_string(cells) + " cells, not the " + std::to_string(want) +
                     " of the grid");
    }
  });
  co.agree();
}

// Chunks larger than the grid are clamped to it. HDF5 stores a chunk's size
// in 32 bits; 8 bytes per cell is the most either file has (int64 units, or
// the two float32 components of the wind).
void check_chunk(const std::string& path, int chunk_nx, int chunk_ny, int nx, int ny) {
  if (chunk_nx <= 0 || chunk_ny <= 0) {
    fail(path, "invalid chunk " + std::to_string(chunk_nx) + " x " + std::to_string(chunk_ny) +
                   " (both must be positive)");
  }
  const std::uint64_t bytes = std::uint64_t{8} *
                              static_cast<std::uint64_t>(std::min(chunk_nx, nx)) *
                              static_cast<std::uint64_t>(std::min(chunk_ny, ny));
  if (bytes >= (std::uint64_t{1} << 32)) {
    fail(path, "chunk " + std::to_string(chunk_nx) + " x " + std::to_string(chunk_ny) +
                   " is too large: HDF5 chunks must hold less than 4 GiB");
  }
}

// ---- HDF5 ---------------------------------------------------------------------------

// File access through MPI-IO on the communicator.
Hid mpio_fapl(MPI_Comm comm, const std::string& path) {
  Hid fapl = detail::checked(H5Pcreate(H5P_FILE_ACCESS), H5Pclose, path, "H5Pcreate(fapl)");
  detail::check(H5Pset_fapl_mpio(fapl.get(), comm, MPI_INFO_NULL), path, "H5Pset_fapl_mpio");
  return fapl;
}

Hid collective_dxpl(const std::string& path) {
  Hid dxpl = detail::checked(H5Pcreate(H5P_DATASET_XFER), H5Pclose, path, "H5Pcreate(dxpl)");
  detail::check(H5Pset_dxpl_mpio(dxpl.get(), H5FD_MPIO_COLLECTIVE), path, "H5Pset_dxpl_mpio");
  return dxpl;
}

// The selections of rows [y0, y1) of one rank's slab: in the file, the
// hyperslab at (slab.y0 + y0, slab.x0) of [ny][nx], or of [1][ny][nx] for a
// snapshot layer; in memory, the contiguous band. An empty band selects
// nothing on both sides (the rank still joins the collective call).
struct SlabSelection {
  Hid file_space, mem_space;
};

SlabSelection select_band(hid_t dset, const TileSlab& s, int y0, int y1, bool layer,
                          const std::string& path, const std::string& what) {
  SlabSelection sel;
  sel.file_space = detail::checked(H5Dget_space(dset), H5Sclose, path, "dataspace of " + what);
  if (slab_empty(s) || y1 <= y0) {
    const hsize_t one = 1;
    sel.mem_space = detail::checked(H5Screate_simple(1, &one, nullptr), H5Sclose, path,
                                    "memory dataspace for " + what);
    detail::check(H5Sselect_none(sel.file_space.get()), path, "H5Sselect_none");
    detail::check(H5Sselect_none(sel.mem_space.get()), path, "H5Sselect_none");
    return sel;
  }
  std::vector<hsize_t> start = {static_cast<hsize_t>(s.y0 + y0), static_cast<hsize_t>(s.x0)};
  std::vector<hsize_t> count = {static_cast<hsize_t>(y1 - y0), static_cast<hsize_t>(s.nx)};
  if (layer) {
    start.insert(start.begin(), 0);
    count.insert(count.begin(), 1);
  }
  const TileSlab band{s.x0, s.y0 + y0, s.nx, y1 - y0};
  detail::check(H5Sselect_hyperslab(sel.file_space.get(), H5S_SELECT_SET, start.data(), nullptr,
                                    count.data(), nullptr),
                path, "cannot select rows " + slab_text(band) + " of " + what);
  const hsize_t n = static_cast<hsize_t>(slab_cells(band));
  sel.mem_space = detail::checked(H5Screate_simple(1, &n, nullptr), H5Sclose, path,
                                  "memory dataspace for " + what);
  return sel;
}

// The bands of every rank's slab: `band` rows each; the number of
// collective calls is the most any rank needs (the others join with empty
// selections). Collective.
struct Bands {
  int band = 1, count = 0;
};
Bands slab_bands(MPI_Comm comm, const TileSlab& slab, int band) {
  Bands b{std::max(1, band), 0};
  int mine = slab_empty(slab) ? 0 : (slab.ny + b.band - 1) / b.band;
  MPI_Allreduce(&mine, &b.count, 1, MPI_INT, MPI_MAX, comm);
  return b;
}

// Everything the dataset writes of one file share.
struct TileWriter {
  Collective& co;
  hid_t file;
  hid_t dxpl;
  const std::string& path;
  const TileSlab& slab;
  int nx, ny;              // global
  int chunk_nx, chunk_ny;  // requested; clamped to the grid
  Bands bands;             // chunk rows: band_rows(chunk_ny)

  // Creates /<name> ([ny][nx], or [1][ny][nx] for a snapshot `layer`),
  // chunked by tile width and band, and writes this rank's slab band by band:
  // fill(y0, y1, out) puts rows [y0, y1) of the slab, `element` bytes a value,
  // into out; done(y0, y1, out) sees them once written. Collectively; each
  // step is agreed on before the next. One band of the slab in memory.
  template <class Fill, class Done>
  void write(const char* name, hid_t file_type, hid_t mem_type, std::size_t element, Fill&& fill,
             Done&& done, int deflate_level, bool layer) {
    const std::string what = std::string("dataset '") + name + "'";
    std::vector<hsize_t> dims = {static_cast<hsize_t>(ny), static_cast<hsize_t>(nx)};
    std::vector<hsize_t> chunk = {static_cast<hsize_t>(bands.band),
                                  static_cast<hsize_t>(std::min(chunk_nx, nx))};
    if (layer) {
      dims.insert(dims.begin(), 1);
      chunk.insert(chunk.begin(), 1);
    }
    Hid dset;
    co.run([&] {
      Hid space =
          detail::checked(H5Screate_simple(static_cast<int>(dims.size()), dims.data(), nullptr),
                          H5Sclose, path, "dataspace for " + what);
      Hid dcpl = detail::deflate_dcpl(chunk, deflate_level, path);
      dset = detail::checked(
          H5Dcreate2(file, name, file_type, space.get(), H5P_DEFAULT, dcpl.get(), H5P_DEFAULT),
          H5Dclose, path, "cannot create " + what);
    });
    co.agree();
    std::vector<char> buf;
    for (int k = 0; k < bands.count; ++k) {
      const int y0 = std::min(k * bands.band, slab.ny);
      const int y1 = slab_empty(slab) ? y0 : std::min(y0 + bands.band, slab.ny);
      co.run([&] {
        buf.resize(
            std::max<std::size_t>(element, element * static_cast<std::size_t>(y1 - y0) *
                                               static_cast<std::size_t>(std::max(slab.nx, 0))));
        if (y1 > y0) fill(y0, y1, buf.data());
        SlabSelection sel = select_band(dset.get(), slab, y0, y1, layer, path, what);
        detail::check(H5Dwrite(dset.get(), mem_type, sel.mem_space.get(), sel.file_space.get(),
                               dxpl, buf.data()),
                      path, "cannot write " + what);
        if (y1 > y0) done(y0, y1, buf.data());
      });
      co.agree();
    }
    co.run([&] { detail::close_checked(dset, path, "cannot close " + what); });
    co.agree();
  }
};

// An upper bound of a file's size: each dataset as deflate stores it at
// worst (zlib's deflateBound is the raw size plus 0.03% and a few bytes), and
// room for the metadata (superblock, object headers, chunk indexes, the
// attributes' strings in the global heap).
struct SizeBound {
  std::uint64_t bytes = std::uint64_t{1} << 20;

  void add_dataset(int nx, int ny, int components, std::size_t element, int chunk_nx,
                   int chunk_ny) {
    const std::uint64_t raw = static_cast<std::uint64_t>(nx) * static_cast<std::uint64_t>(ny) *
                              static_cast<std::uint64_t>(components) * element;
    const std::uint64_t cx = static_cast<std::uint64_t>(std::min(chunk_nx, nx));
    const std::uint64_t cy = static_cast<std::uint64_t>(std::min(chunk_ny, ny));
    const std::uint64_t chunks = (static_cast<std::uint64_t>(nx) + cx - 1) / cx *
                                 ((static_cast<std::uint64_t>(ny) + cy - 1) / cy);
    bytes += raw + raw / 256 + chunks * 256;
  }
  void add_text(const std::string& s) { bytes += 2 * s.size() + 256; }
};

// Reserves `bytes` of disk for the temporary (rank 0, before any data is
// written). The reason: when a write fails inside HDF5 1.10.8's collective
// I/O or metadata flush (a full disk, say), the ranks end up in different
// collective calls and the job hangs, or the file stays open in the library,
// which then crashes in MPI_Finalize. With the space reserved, a full disk or
// quota shows here, as an ordinary error every rank learns before anything
// collective is at stake. The reservation extends the file; HDF5 sets its size
// to the real end when it flushes. Best effort: where the file system cannot
// reserve (EOPNOTSUPP, e.g. NFSv3), the write goes on without.
void reserve_space(const std::string& path, const std::string& tmp, std::uint64_t bytes) {
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CLOEXEC);
  if (fd < 0) {
    detail::fail_errno(path, "cannot open temporary file '" + tmp + "' to reserve space", errno);
  }
  struct stat st {};
  const off_t before = ::fstat(fd, &st) == 0 ? st.st_size : 0;
  const int err = ::fallocate(fd, 0, 0, static_cast<off_t>(bytes)) == 0 ? 0 : errno;
  if (err == ENOSPC || err == EDQUOT || err == EFBIG) {
    // Gives back what was allocated before the failure.
    (void)!::ftruncate(fd, before);
    ::close(fd);
    detail::fail_errno(
        path, "cannot reserve " + std::to_string(bytes) + " bytes for temporary file '" + tmp + "'",
        err);
  }
  ::close(fd);
}

// Creates the temporary, reserves `bound` bytes for it, runs `body(file)`
// (which agrees after each of its steps), closes the file and publishes it
// under `path`; see the top of the file. Collective.
template <class Body>
void write_atomically(Collective& co, const std::string& path, hid_t fcpl, std::uint64_t bound,
                      Body&& body) {
  std::string tmp;
  if (co.rank() == 0) tmp = path + ".tmp-" + std::to_string(::getpid());
  tmp = co.bcast(tmp, 0);
  bool committed = false;
  try {
    {
      Hid file;
      co.run([&] {
        Hid fapl = mpio_fapl(co.comm(), path);
        file = detail::checked(H5Fcreate(tmp.c_str(), H5F_ACC_TRUNC, fcpl, fapl.get()), H5Fclose,
                               path, "cannot create temporary file '" + tmp + "'");
      });
      co.agree();
      co.run([&] {
        if (co.rank() == 0) reserve_space(path, tmp, bound);
      });
      co.agree();
      body(file.get());
      // The flush ends in MPI_File_sync: every rank's data is durable, on
      // parallel file systems too, before the rename below publishes it.
      co.run([&] {
        detail::check(H5Fflush(file.get(), H5F_SCOPE_GLOBAL), path,
                      "cannot flush temporary file '" + tmp + "'");
      });
      co.agree();
      co.run(
          [&] { detail::close_checked(file, path, "cannot close temporary file '" + tmp + "'"); });
      co.agree();  // every rank has closed the file
    }
    co.run([&] {
      if (co.rank() != 0) return;
      // What the close itself wrote (rank 0 writes the superblock) is
      // synced with the rest.
      replace_durably(tmp, path);
      committed = true;
    });
    co.agree();  // no rank returns before the file is at `path`
  } catch (const IoError&) {
    // Every rank is here, after an agreement, with its HDF5 objects closed.
    // unlink, not remove: a directory at the temporary name is not ours.
    if (co.rank() == 0 && !committed) ::unlink(tmp.c_str());
    MPI_Barrier(co.comm());  // the temporary is gone before any rank returns
    throw;
  }
}

// The overview levels (cf.h write_overview): three float32 layers and two
// coordinates per level, chunks of at most 256 x 256 blocks.
void add_overview_bound(SizeBound& bound, const OverviewPyramid& pyramid) {
  for (const OverviewLevel& l : pyramid) {
    for (int k = 0; k < 3; ++k) bound.add_dataset(l.nx, l.ny, 1, sizeof(float), 256, 256);
    bound.bytes += 8 * (static_cast<std::uint64_t>(l.nx) + static_cast<std::uint64_t>(l.ny)) +
                   (std::uint64_t{16} << 10);
  }
}

}  // namespace

int band_rows(int chunk_ny) {
  for (int b = std::min(chunk_ny, kBandRows); b > 1; --b)
    if (chunk_ny % b == 0) return b;
  return 1;
}

namespace {

// What both snapshot writers check and agree on before writing: this rank's
// arguments, then the values every rank must pass alike, then the tiling.
void agree_on_snapshot(Collective& co, const std::string& path, const SnapshotMeta& meta,
                       const TileSlab& slab, int chunk_nx, int chunk_ny,
                       const std::string& layers) {
  co.run([&] {
    detail::check_grid(path, meta.nx, meta.ny);
    check_chunk(path, chunk_nx, chunk_ny, meta.nx, meta.ny);
  });
  co.agree();
  SameOnAllRanks same;
  same.add_grid(meta.nx, meta.ny, chunk_nx, chunk_ny);
  same.add("step", meta.step);
  same.add("time_days", meta.time_days);
  same.add("cell_size_m", meta.cell_size_m);
  same.add("job_spec", meta.job_spec_json);
  same.add("erg_version", meta.erg_version);
  same.add("unit_m", meta.unit_m);
  same.add("sand_units_total", meta.sand_units_total);
  same.add("bedrock_units_total", meta.bedrock_units_total);
  same.add("airborne_units_total", meta.airborne_units_total);
  same.add("seed", meta.seed);
  same.add("backend", meta.backend);
  same.add("layers", layers);
  same.check(co, path);
  check_tiling(co, path, slab, meta.nx, meta.ny);
}

// The snapshot layers `ids`, each band from rows(id, y0, y1, out) as float
// metres. Collective; the arguments are agreed on.
void write_snapshot_bands(Collective& co, const std::string& path, const SnapshotMeta& meta,
                          const std::vector<fields::Id>& ids, const TileRows& rows,
                          const TileSlab& slab, int chunk_nx, int chunk_ny,
                          const OverviewPyramid* pyramid) {
  SizeBound bound;
  for (std::size_t k = 0; k < ids.size(); ++k) {
    bound.add_dataset(meta.nx, meta.ny, 1, sizeof(float), chunk_nx, band_rows(chunk_ny));
  }
  // The CF coordinates and metadata (cf.h): a few KiB per layer at most.
  bound.bytes +=
      8 * (static_cast<std::uint64_t>(meta.nx) + static_cast<std::uint64_t>(meta.ny) + 1) +
      (std::uint64_t{4} << 10) * std::max<std::uint64_t>(12, ids.size() + 4);
  for (const std::string* s :
       {&meta.job_spec_json, &meta.erg_version, &meta.sand_units_total, &meta.bedrock_units_total,
        &meta.airborne_units_total, &meta.backend}) {
    bound.add_text(*s);
  }
  const Bands bands =
      slab_bands(co.comm(), slab, band_rows(std::min(chunk_ny, std::max(meta.ny, 1))));
  if (pyramid) add_overview_bound(bound, *pyramid);

  detail::Hdf5Guard guard;
  write_atomically(co, path, H5P_DEFAULT, bound.bytes, [&](hid_t file) {
    Hid dxpl;
    co.run([&] { dxpl = collective_dxpl(path); });
    co.agree();
    TileWriter w{co, file, dxpl.get(), path, slab, meta.nx, meta.ny, chunk_nx, chunk_ny, bands};
    std::vector<std::string> names;
    for (const fields::Id id : ids) {
      const char* name = fields::info(id).name;
      w.write(
          name, H5T_IEEE_F32LE, H5T_NATIVE_FLOAT, sizeof(float),
          [&](int y0, int y1, void* out) { rows(id, y0, y1, out); }, [](int, int, const void*) {},
          detail::kSnapshotDeflate, true);
      names.emplace_back(name);
    }
    co.run([&] { detail::write_snapshot_attrs(file, meta, path); });
    co.agree();
    // The coordinates' values from rank 0, the metadata from every rank.
    co.run([&] { detail::write_cf(file, meta, names, dxpl.get(), co.rank() == 0, path); });
    co.agree();
    if (pyramid) {
      co.run(
          [&] { detail::write_overview(file, meta, *pyramid, dxpl.get(), co.rank() == 0, path); });
      co.agree();
    }
  });
}

std::string ids_text(const std::vector<fields::Id>& ids) {
  std::string t;
  for (const fields::Id id : ids) t += std::string(fields::info(id).name) + ",";
  return t;
}

}  // namespace

void write_snapshot_parallel(MPI_Comm comm, const std::string& path, const SnapshotMeta& meta,
                             const SnapshotFields& f, const TileSlab& slab, int chunk_nx,
                             int chunk_ny, const OverviewPyramid* pyramid) {
  Collective co(comm, path);
  co.run([&] {
    if (!slab_empty(slab)) detail::check_required_layers(path, f, " on tile " + slab_text(slab));
  });
  co.agree();
  // A layer is written when every rank that owns cells has it.
  std::array<int, fields::kCount> have{};
  for (const fields::Id id : fields::snapshot_order())
    have[id] = f[id].data || slab_empty(slab) ? 1 : 0;
  MPI_Allreduce(MPI_IN_PLACE, have.data(), fields::kCount, MPI_INT, MPI_LAND, comm);
  std::vector<fields::Id> ids;
  for (const fields::Id id : fields::snapshot_order())
    if (have[id]) ids.push_back(id);
  agree_on_snapshot(co, path, meta, slab, chunk_nx, chunk_ny, ids_text(ids));
  // The values strided as each layer says (io.h LayerValues).
  const TileRows rows = [&](fields::Id id, int y0, int y1, void* out) {
    const LayerValues& l = f[id];
    float* o = static_cast<float*>(out);
    const std::size_t c0 = static_cast<std::size_t>(y0) * static_cast<std::size_t>(slab.nx);
    const std::size_t n = static_cast<std::size_t>(y1 - y0) * static_cast<std::size_t>(slab.nx);
    for (std::size_t c = 0; c < n; ++c)
      o[c] = l.data[static_cast<std::size_t>(l.stride) * (c0 + c) +
                    static_cast<std::size_t>(l.offset)];
  };
  write_snapshot_bands(co, path, meta, ids, rows, slab, chunk_nx, chunk_ny, pyramid);
}

void write_snapshot_parallel(MPI_Comm comm, const std::string& path, const SnapshotMeta& meta,
                             const std::vector<fields::Id>& layers, const TileRows& rows,
                             const TileSlab& slab, int chunk_nx, int chunk_ny,
                             const OverviewPyramid* pyramid) {
  Collective co(comm, path);
  co.run([&] {
    std::string missing;
    for (const fields::Id id : fields::snapshot_order())
      if (!fields::info(id).snapshot.optional &&
          std::find(layers.begin(), layers.end(), id) == layers.end())
        missing += std::string(missing.empty() ? "" : ", ") + fields::info(id).name;
    if (!missing.empty()) fail(path, "snapshot needs the layers " + missing);
  });
  co.agree();
  agree_on_snapshot(co, path, meta, slab, chunk_nx, chunk_ny, ids_text(layers));
  write_snapshot_bands(co, path, meta, layers, rows, slab, chunk_nx, chunk_ny, pyramid);
}

namespace {

// The checkpoint's header checks and agreement (both writers).
void agree_on_checkpoint(Collective& co, const std::string& path, const Checkpoint& c,
                         const TileSlab& slab, int chunk_nx, int chunk_ny) {
  SameOnAllRanks same;
  same.add_grid(c.nx, c.ny, chunk_nx, chunk_ny);
  same.add("step", c.step);
  same.add("job_spec", c.job_spec_json);
  same.add("ledger size", static_cast<std::int64_t>(c.ledger.size()));
  for (const auto& [name, value] : c.ledger) {
    same.add("ledger name", name);
    same.add("ledger_" + name, value);
  }
  same.check(co, path);
  check_tiling(co, path, slab, c.nx, c.ny);
}

void check_checkpoint_header(const std::string& path, const Checkpoint& c, int chunk_nx,
                             int chunk_ny) {
  if (c.nx <= 0 || c.ny <= 0) {
    fail(path, "invalid grid " + std::to_string(c.nx) + " x " + std::to_string(c.ny) +
                   " (nx and ny must be positive)");
  }
  check_chunk(path, chunk_nx, chunk_ny, c.nx, c.ny);
  detail::check_checkpoint_ledger(c, path);
}

// The present state fields of `c`'s header, each band from rows(id, y0, y1,
// out) in its stored type; the checksums summed band by band. Collective.
void write_checkpoint_bands(Collective& co, const std::string& path, const Checkpoint& c,
                            const std::array<bool, fields::kCount>& present, const TileRows& rows,
                            const TileSlab& slab, int chunk_nx, int chunk_ny) {
  detail::Hdf5Guard guard;
  Hid fcpl;
  co.run([&] { fcpl = detail::checkpoint_fcpl(path); });
  co.agree();
  SizeBound bound;
  for (int i = 0; i < fields::kCount; ++i) {
    const auto id = static_cast<fields::Id>(i);
    if (present[id])
      bound.add_dataset(c.nx, c.ny, 1, fields::info(id).type == fields::Type::kUnits ? 8 : 4,
                        chunk_nx, band_rows(chunk_ny));
  }
  bound.add_text(c.job_spec_json);
  for (const auto& [name, value] : c.ledger) bound.add_text(name + value);
  bound.add_text(std::string(512, ' '));  // the checksums record
  const Bands bands = slab_bands(co.comm(), slab, band_rows(std::min(chunk_ny, c.ny)));

  write_atomically(co, path, fcpl.get(), bound.bytes, [&](hid_t file) {
    Hid dxpl;
    co.run([&] { dxpl = collective_dxpl(path); });
    co.agree();
    TileWriter w{co, file, dxpl.get(), path, slab, c.nx, c.ny, chunk_nx, chunk_ny, bands};
    // Each rank sums its tile band by band; the sums of all ranks are the
    // file's (integrity.h). Every name is entered first, in field order, on
    // every rank (a rank without cells sums nothing).
    detail::Checksums sums;
    for (int i = 0; i < fields::kCount; ++i) {
      const auto id = static_cast<fields::Id>(i);
      const fields::Info& f = fields::info(id);
      if (!present[id]) continue;
      const bool units = f.type == fields::Type::kUnits;
      sums.add_cells(f.checkpoint, static_cast<const std::int64_t*>(nullptr), TileSlab{}, c.nx);
      const auto fill = [&](int y0, int y1, void* out) { rows(id, y0, y1, out); };
      const auto done = [&](int y0, int y1, const void* v) {
        const TileSlab band{slab.x0, slab.y0 + y0, slab.nx, y1 - y0};
        if (units)
          sums.add_cells(f.checkpoint, static_cast<const std::int64_t*>(v), band, c.nx);
        else
          sums.add_cells(f.checkpoint, static_cast<const float*>(v), band, c.nx);
      };
      if (units)
        w.write(f.checkpoint, H5T_STD_I64LE, H5T_NATIVE_INT64, sizeof(std::int64_t), fill, done,
                detail::kCheckpointDeflate, false);
      else
        w.write(f.checkpoint, H5T_IEEE_F32LE, H5T_NATIVE_FLOAT, sizeof(float), fill, done,
                detail::kCheckpointDeflate, false);
    }
    sums.allreduce(co.comm());
    sums = detail::checkpoint_checksums_done(std::move(sums), c);
    co.run([&] {
      detail::write_checkpoint_attrs(file, c, path);
      detail::write_checkpoint_checksums(file, sums, path);  // last
    });
    co.agree();
  });
}

}  // namespace

void write_checkpoint_parallel(MPI_Comm comm, const std::string& path, const Checkpoint& c,
                               const TileSlab& slab, int chunk_nx, int chunk_ny) {
  Collective co(comm, path);
  co.run([&] {
    check_checkpoint_header(path, c, chunk_nx, chunk_ny);
    if (slab.nx >= 0 && slab.ny >= 0)
      detail::check_checkpoint_sizes(c, slab_cells(slab), path, "the tile's nx * ny",
                                     " (tile " + slab_text(slab) + ")");
  });
  co.agree();
  agree_on_checkpoint(co, path, c, slab, chunk_nx, chunk_ny);
  // An optional field is written when every rank that owns cells has it.
  std::array<int, fields::kCount> have{};
  for (int i = 0; i < fields::kCount; ++i) {
    const auto id = static_cast<fields::Id>(i);
    have[id] = fields::is_state(id) && (!fields::info(id).checkpoint_optional || slab_empty(slab) ||
                                        c.size(id) == slab_cells(slab))
                   ? 1
                   : 0;
  }
  MPI_Allreduce(MPI_IN_PLACE, have.data(), fields::kCount, MPI_INT, MPI_LAND, comm);
  std::array<bool, fields::kCount> present{};
  for (int i = 0; i < fields::kCount; ++i) present[static_cast<std::size_t>(i)] = have[i] != 0;
  const TileRows rows = [&](fields::Id id, int y0, int y1, void* out) {
    const std::size_t e = fields::info(id).type == fields::Type::kUnits ? 8 : 4;
    const std::size_t row = e * static_cast<std::size_t>(slab.nx);
    const char* from = fields::info(id).type == fields::Type::kUnits
                           ? reinterpret_cast<const char*>(c.units[id].data())
                           : reinterpret_cast<const char*>(c.reals[id].data());
    std::memcpy(out, from + row * static_cast<std::size_t>(y0),
                row * static_cast<std::size_t>(y1 - y0));
  };
  write_checkpoint_bands(co, path, c, present, rows, slab, chunk_nx, chunk_ny);
}

void write_checkpoint_parallel(MPI_Comm comm, const std::string& path, const Checkpoint& header,
                               const TileRows& rows, const TileSlab& slab, int chunk_nx,
                               int chunk_ny) {
  Collective co(comm, path);
  co.run([&] { check_checkpoint_header(path, header, chunk_nx, chunk_ny); });
  co.agree();
  agree_on_checkpoint(co, path, header, slab, chunk_nx, chunk_ny);
  std::array<bool, fields::kCount> present{};
  for (int i = 0; i < fields::kCount; ++i)
    present[static_cast<std::size_t>(i)] = fields::is_state(static_cast<fields::Id>(i));
  write_checkpoint_bands(co, path, header, present, rows, slab, chunk_nx, chunk_ny);
}

Checkpoint read_checkpoint_parallel(MPI_Comm comm, const std::string& path, const TileSlab& slab,
                                    const std::function<TileRowsIn(const Checkpoint&)>& start) {
  Collective co(comm, path);
  detail::Hdf5Guard guard;
  // The plain checks (exists, regular file, HDF5 signature) on one rank.
  co.run([&] {
    if (co.rank() == 0) detail::check_hdf5_file(path, "checkpoint");
  });
  co.agree();

  Hid file;
  co.run([&] {
    Hid fapl = mpio_fapl(comm, path);
    file = detail::checked(H5Fopen(path.c_str(), H5F_ACC_RDONLY, fapl.get()), H5Fclose, path,
                           "cannot open checkpoint (corrupt or truncated?)");
  });
  co.agree();
  const hid_t fid = file.get();

  Checkpoint c;
  co.run([&] {
    c = detail::read_checkpoint_header(fid, path);
    check_slab(path, slab, c.nx, c.ny);
    detail::read_checkpoint_ledger(fid, path, c);
  });
  co.agree();
  // Not a recorded failure: what start throws (a grid the tiling cannot
  // take: every rank alike) is the caller's to handle.
  const TileRowsIn sink = start(c);

  Hid dxpl;
  co.run([&] { dxpl = collective_dxpl(path); });
  co.agree();
  // Every dataset must be exactly [ny][nx], as in read_checkpoint.
  const std::vector<hsize_t> grid = {static_cast<hsize_t>(c.ny), static_cast<hsize_t>(c.nx)};
  detail::Checksums sums;
  std::vector<char> buf;
  // (The same file on every rank: every rank gets the same answer.)
  std::array<bool, fields::kCount> present{};
  for (int i = 0; i < fields::kCount; ++i) {
    const auto id = static_cast<fields::Id>(i);
    const fields::Info& f = fields::info(id);
    if (!f.state || (f.checkpoint_optional && !detail::link_exists(fid, f.checkpoint))) continue;
    present[id] = true;
    const bool units = f.type == fields::Type::kUnits;
    const std::size_t e = units ? sizeof(std::int64_t) : sizeof(float);
    const std::string what = std::string("dataset '") + f.checkpoint + "'";
    Hid dset;
    int band = kBandRows;
    co.run([&] {
      std::vector<hsize_t> dims;
      dset = detail::open_dataset(fid, f.checkpoint, dims, path);
      if (dims != grid) {
        fail(path, what + " has shape " + detail::shape_text(dims) + ", expected " +
                       detail::shape_text(grid));
      }
      // Bands of the file's chunk rows: each chunk is inflated once.
      Hid dcpl = detail::checked(H5Dget_create_plist(dset.get()), H5Pclose, path,
                                 "creation properties of " + what);
      hsize_t chunk[2] = {0, 0};
      if (H5Pget_layout(dcpl.get()) == H5D_CHUNKED && H5Pget_chunk(dcpl.get(), 2, chunk) == 2)
        band = static_cast<int>(std::max<hsize_t>(1, chunk[0]));
    });
    co.agree();
    sums.add_cells(f.checkpoint, static_cast<const std::int64_t*>(nullptr), TileSlab{}, c.nx);
    const Bands bands = slab_bands(comm, slab, band);
    for (int k = 0; k < bands.count; ++k) {
      const int y0 = std::min(k * bands.band, std::max(slab.ny, 0));
      const int y1 = slab_empty(slab) ? y0 : std::min(y0 + bands.band, slab.ny);
      co.run([&] {
        buf.resize(std::max<std::size_t>(e, e * static_cast<std::size_t>(y1 - y0) *
                                                static_cast<std::size_t>(std::max(slab.nx, 0))));
        SlabSelection sel = select_band(dset.get(), slab, y0, y1, false, path, what);
        detail::check(H5Dread(dset.get(), units ? H5T_NATIVE_INT64 : H5T_NATIVE_FLOAT,
                              sel.mem_space.get(), sel.file_space.get(), dxpl.get(), buf.data()),
                      path, "cannot read " + what + " (corrupt?)");
        if (y1 <= y0) return;
        const TileSlab b{slab.x0, slab.y0 + y0, slab.nx, y1 - y0};
        if (units)
          sums.add_cells(f.checkpoint, reinterpret_cast<const std::int64_t*>(buf.data()), b, c.nx);
        else
          sums.add_cells(f.checkpoint, reinterpret_cast<const float*>(buf.data()), b, c.nx);
        if (sink) sink(id, y0, y1, buf.data());
      });
      co.agree();
    }
  }
  // Each rank summed the cells it read. When the ranks' slabs cover the grid
  // (a resume's tiling does), the sums are the whole datasets' and are
  // verified; a partial read verifies the spec and attributes only.
  {
    sums.allreduce(co.comm());
    unsigned long long cells = slab_empty(slab) ? 0 : slab_cells(slab);
    MPI_Allreduce(MPI_IN_PLACE, &cells, 1, MPI_UNSIGNED_LONG_LONG, MPI_SUM, co.comm());
    const bool whole =
        cells == static_cast<unsigned long long>(c.nx) * static_cast<unsigned long long>(c.ny);
    if (!whole) sums = detail::Checksums{};
    sums = detail::checkpoint_checksums_done(std::move(sums), c);
    co.run([&] { detail::verify_checkpoint(fid, sums, path, whole); });
    co.agree();
  }
  co.run([&] { detail::close_checked(file, path, "cannot close checkpoint"); });
  co.agree();
  return c;
}

Checkpoint read_checkpoint_parallel(MPI_Comm comm, const std::string& path, const TileSlab& slab) {
  Checkpoint values;
  const std::size_t n = slab_empty(slab) ? 0 : slab_cells(slab);
  Checkpoint c = read_checkpoint_parallel(comm, path, slab, [&](const Checkpoint&) -> TileRowsIn {
    return [&](fields::Id id, int y0, int y1, const void* in) {
      const bool units = fields::info(id).type == fields::Type::kUnits;
      const std::size_t row = (units ? 8 : 4) * static_cast<std::size_t>(slab.nx);
      char* to;
      if (units) {
        values.units[id].resize(n);
        to = reinterpret_cast<char*>(values.units[id].data());
      } else {
        values.reals[id].resize(n);
        to = reinterpret_cast<char*>(values.reals[id].data());
      }
      std::memcpy(to + row * static_cast<std::size_t>(y0), in,
                  row * static_cast<std::size_t>(y1 - y0));
    };
  });
  for (int i = 0; i < fields::kCount; ++i) {
    c.units[static_cast<std::size_t>(i)] = std::move(values.units[static_cast<std::size_t>(i)]);
    c.reals[static_cast<std::size_t>(i)] = std::move(values.reals[static_cast<std::size_t>(i)]);
  }
  return c;
}

}  // namespace erg::io

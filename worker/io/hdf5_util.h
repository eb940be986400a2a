// SPDX-License-Identifier: Apache-2.0
// Internal to erg_io: small RAII and error helpers over the HDF5 C API, shared
// by snapshots, checkpoints and HDF5 input maps.
//
// Every public function that touches HDF5 holds an Hdf5Guard for its whole
// duration, and every HDF5 failure becomes an IoError "<path>: <operation>:
// HDF5: <api call>: <description> (cause: <innermost description>)".
#pragma once

#include <hdf5.h>
#include <sys/stat.h>

#include <algorithm>
#include <cerrno>
#include <cstdint>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include "io/atomic_file.h"

namespace erg::io::detail {

inline std::mutex& hdf5_mutex() {
  static std::mutex m;
  return m;
}

// The HDF5 build used here is not thread-safe, so calls from different threads
// (a snapshot writer thread and a checkpoint on the main thread, say) must not
// overlap. The guard also turns off HDF5's automatic printing of its error
// stack to stderr (failures are reported through IoError instead) and starts
// from an empty error stack so that messages describe only this call.
class Hdf5Guard {
 public:
  Hdf5Guard() : lock_(hdf5_mutex()) {
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
    H5Eclear2(H5E_DEFAULT);
  }

 private:
  std::lock_guard<std::mutex> lock_;
};

inline herr_t collect_hdf5_error(unsigned /*n*/, const H5E_error2_t* e, void* data) {
  try {
    auto* out = static_cast<std::vector<std::string>*>(data);
    std::string entry = e->func_name ? e->func_name : "?";
    entry += ": ";
    entry += e->desc ? e->desc : "(no description)";
    // Some descriptions span lines (e.g. the sec2 driver's write failure).
    for (char& c : entry) {
      if (c == '\n') c = ' ';
    }
    out->push_back(std::move(entry));
  } catch (...) {
    return -1;  // no exception may cross the C library
  }
  return 0;
}

// The current HDF5 error stack in one line: the API call that failed and the
// innermost cause (which is where e.g. "No such file or directory" appears).
inline std::string hdf5_error_text() {
  std::vector<std::string> entries;
  H5Ewalk2(H5E_DEFAULT, H5E_WALK_DOWNWARD, collect_hdf5_error, &entries);
  H5Eclear2(H5E_DEFAULT);
  if (entries.empty()) return "HDF5 error (no details on the error stack)";
  std::string text = "HDF5: " + entries.front();
  if (entries.size() > 1) text += " (cause: " + entries.back() + ")";
  return text;
}

[[noreturn]] inline void fail_hdf5(const std::string& path, const std::string& what) {
  fail(path, what + ": " + hdf5_error_text());
}

inline void check(herr_t status, const std::string& path, const std::string& what) {
  if (status < 0) fail_hdf5(path, what);
}

// Owns one HDF5 identifier and releases it with the matching H5*close.
class Hid {
 public:
  using Closer = herr_t (*)(hid_t);

  Hid() = default;
  Hid(hid_t id, Closer closer) : id_(id), closer_(closer) {}
  Hid(Hid&& o) noexcept : id_(std::exchange(o.id_, H5I_INVALID_HID)), closer_(o.closer_) {}
  Hid& operator=(Hid&& o) noexcept {
    if (this != &o) {
      release();
      id_ = std::exchange(o.id_, H5I_INVALID_HID);
      closer_ = o.closer_;
    }
    return *this;
  }
  Hid(const Hid&) = delete;
  Hid& operator=(const Hid&) = delete;
  ~Hid() { release(); }

  hid_t get() const { return id_; }

  // Closes now and reports the status. Matters for files and datasets, whose
  // close flushes buffered data and can therefore fail (e.g. disk full).
  herr_t close() {
    herr_t status = id_ >= 0 ? closer_(id_) : 0;
    id_ = H5I_INVALID_HID;
    return status;
  }

 private:
  void release() {
    if (id_ >= 0) closer_(id_);
    id_ = H5I_INVALID_HID;
  }

  hid_t id_ = H5I_INVALID_HID;
  Closer closer_ = nullptr;
};

// Wraps a freshly returned identifier, failing with the HDF5 cause if invalid.
inline Hid checked(hid_t id, Hid::Closer closer, const std::string& path, const std::string& what) {
  if (id < 0) fail_hdf5(path, what);
  return Hid(id, closer);
}

inline void close_checked(Hid& h, const std::string& path, const std::string& what) {
  check(h.close(), path, what);
}

// ---- files ------------------------------------------------------------------

// Writers build the HDF5 file in memory (core driver, no backing store) and
// write the finished image to the temporary themselves (outside the HDF5
// lock, so other threads can use HDF5 during the disk write). HDF5 thus never
// does disk I/O while writing, which matters because when a write fails inside
// HDF5 1.10 (disk full, file too large) the library keeps the dataset and file
// it could not flush open, retries at process exit and segfaults there. A
// failed fwrite is an ordinary, recoverable error.
// The cost is memory: the compressed file is held twice (the image HDF5
// builds and the copy H5Fget_file_image hands out) while it is saved.
inline Hid create_hdf5_in_memory(const AtomicFile& out, hid_t fcpl = H5P_DEFAULT) {
  constexpr std::size_t kGrowBy = std::size_t{8} << 20;  // image grows 8 MiB at a time
  Hid fapl = checked(H5Pcreate(H5P_FILE_ACCESS), H5Pclose, out.path(), "H5Pcreate(fapl)");
  check(H5Pset_fapl_core(fapl.get(), kGrowBy, /*backing_store=*/0), out.path(), "H5Pset_fapl_core");
  return checked(H5Fcreate(out.tmp().c_str(), H5F_ACC_TRUNC, fcpl, fapl.get()), H5Fclose,
                 out.path(), "cannot create HDF5 file in memory");
}

// Takes the finished image of an in-memory file and closes the file. The
// explicit flush matters: H5Fget_file_image in HDF5 1.10.8 does not flush the
// metadata cache itself and would return an image without the root group's
// object header. Flushed, the image is byte-identical to the file H5Fclose
// writes with the default (sec2) driver.
inline std::vector<char> take_hdf5_image(Hid& file, const std::string& path) {
  check(H5Fflush(file.get(), H5F_SCOPE_GLOBAL), path, "cannot flush the HDF5 file image");
  const ssize_t size = H5Fget_file_image(file.get(), nullptr, 0);
  if (size <= 0) fail_hdf5(path, "cannot size the HDF5 file image");
  std::vector<char> image(static_cast<std::size_t>(size));
  if (H5Fget_file_image(file.get(), image.data(), image.size()) != size) {
    fail_hdf5(path, "cannot copy the HDF5 file image");
  }
  close_checked(file, path, "cannot close HDF5 file");
  return image;
}

// Checks that `path` exists, is a regular file and has the HDF5 signature, so
// the common mistakes get a plain message rather than an HDF5 stack; `kind`
// ("snapshot", ...) only words the messages. (The parallel reader runs these
// checks on one rank before every rank opens the file.)
inline void check_hdf5_file(const std::string& path, const std::string& kind) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) fail_errno(path, "cannot open " + kind, errno);
  if (!S_ISREG(st.st_mode)) fail(path, "cannot open " + kind + ": not a regular file");
  htri_t is_hdf5 = H5Fis_hdf5(path.c_str());
  if (is_hdf5 == 0) fail(path, kind + " is not an HDF5 file (wrong file, or corrupt)");
  if (is_hdf5 < 0) fail_hdf5(path, "cannot read " + kind);
}

// Opens an existing HDF5 file read-only, after check_hdf5_file. `fapl` picks
// the driver (the default sec2, or mpio for a collective open).
inline Hid open_hdf5_readonly(const std::string& path, const std::string& kind,
                              hid_t fapl = H5P_DEFAULT) {
  check_hdf5_file(path, kind);
  return checked(H5Fopen(path.c_str(), H5F_ACC_RDONLY, fapl), H5Fclose, path,
                 "cannot open " + kind + " (corrupt or truncated?)");
}

// True when every component of an absolute or relative link path exists.
// H5Lexists on "a/b" fails, rather than answering false, when "a" is absent.
inline bool link_exists(hid_t loc, const std::string& name) {
  const bool absolute = !name.empty() && name[0] == '/';
  std::string prefix;
  bool any = false;
  std::size_t start = 0;
  while (start <= name.size()) {
    std::size_t end = std::min(name.find('/', start), name.size());
    if (end > start) {
      if (absolute || any) prefix += '/';
      prefix += name.substr(start, end - start);
      any = true;
      if (H5Lexists(loc, prefix.c_str(), H5P_DEFAULT) <= 0) {
        H5Eclear2(H5E_DEFAULT);
        return false;
      }
    }
    start = end + 1;
  }
  return any;
}

// ---- datasets ---------------------------------------------------------------

inline std::string shape_text(const std::vector<hsize_t>& dims) {
  std::string s;
  for (hsize_t d : dims) {
    // Appended piecewise: GCC 12 -O2 falsely flags "[" + std::string with -Wrestrict.
    s += '[';
    s += std::to_string(d);
    s += ']';
  }
  return s.empty() ? "scalar" : s;
}

// Chunked, shuffled and deflated, with the chunk shape as given (the parallel
// writers chunk by tile). Shuffle before deflate groups the bytes of each
// significance, which compresses floats and small integers much better than
// deflate alone.
inline Hid deflate_dcpl(const std::vector<hsize_t>& chunk, int level, const std::string& path) {
  Hid dcpl = checked(H5Pcreate(H5P_DATASET_CREATE), H5Pclose, path, "H5Pcreate(dcpl)");
  check(H5Pset_chunk(dcpl.get(), static_cast<int>(chunk.size()), chunk.data()), path,
        "H5Pset_chunk");
  check(H5Pset_shuffle(dcpl.get()), path, "H5Pset_shuffle");
  check(H5Pset_deflate(dcpl.get(), static_cast<unsigned>(level)), path, "H5Pset_deflate");
  return dcpl;
}

// Chunks of at most 256 x 256 cells over the first two dimensions (whole
// extent over the rest): small enough that reading a sub-region or one tile
// touches little, large enough to compress well.
inline Hid chunked_deflate_dcpl(const std::vector<hsize_t>& dims, int level,
                                const std::string& path) {
  std::vector<hsize_t> chunk = dims;
  for (std::size_t i = 0; i < chunk.size() && i < 2; ++i)
    chunk[i] = std::min<hsize_t>(dims[i], 256);
  return deflate_dcpl(chunk, level, path);
}

// Creates dataset `name` of `file_type` and writes `data` (in `mem_type`).
inline void write_dataset(hid_t file, const std::string& name, hid_t file_type, hid_t mem_type,
                          const std::vector<hsize_t>& dims, const void* data, int deflate_level,
                          const std::string& path) {
  const std::string what = "dataset '" + name + "'";
  Hid space = checked(H5Screate_simple(static_cast<int>(dims.size()), dims.data(), nullptr),
                      H5Sclose, path, "dataspace for " + what);
  Hid dcpl = chunked_deflate_dcpl(dims, deflate_level, path);
  Hid dset = checked(
      H5Dcreate2(file, name.c_str(), file_type, space.get(), H5P_DEFAULT, dcpl.get(), H5P_DEFAULT),
      H5Dclose, path, "cannot create " + what);
  check(H5Dwrite(dset.get(), mem_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data), path,
        "cannot write " + what);
  close_checked(dset, path, "cannot close " + what);
}

// Opens dataset `name` and returns it with its shape; fails naming the path
// and the dataset when it is absent or not a dataset.
inline Hid open_dataset(hid_t file, const std::string& name, std::vector<hsize_t>& dims,
                        const std::string& path) {
  if (!link_exists(file, name)) fail(path, "dataset '" + name + "' not found");
  Hid dset = checked(H5Dopen2(file, name.c_str(), H5P_DEFAULT), H5Dclose, path,
                     "cannot open dataset '" + name + "' (is it a group?)");
  Hid space = checked(H5Dget_space(dset.get()), H5Sclose, path, "dataspace of '" + name + "'");
  int rank = H5Sget_simple_extent_ndims(space.get());
  if (rank < 0) fail_hdf5(path, "rank of dataset '" + name + "'");
  dims.assign(static_cast<std::size_t>(rank), 0);
  if (rank > 0 && H5Sget_simple_extent_dims(space.get(), dims.data(), nullptr) < 0) {
    fail_hdf5(path, "shape of dataset '" + name + "'");
  }
  return dset;
}

// Reads a whole dataset of the expected shape, converting to `mem_type`.
template <class T>
std::vector<T> read_dataset(hid_t file, const std::string& name, hid_t mem_type,
                            const std::vector<hsize_t>& expected, const std::string& path) {
  std::vector<hsize_t> dims;
  Hid dset = open_dataset(file, name, dims, path);
  if (dims != expected) {
    fail(path, "dataset '" + name + "' has shape " + shape_text(dims) + ", expected " +
                   shape_text(expected));
  }
  std::size_t n = 1;
  for (hsize_t d : dims) n *= static_cast<std::size_t>(d);
  std::vector<T> values(n);
  check(H5Dread(dset.get(), mem_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data()), path,
        "cannot read dataset '" + name + "' (corrupt?)");
  return values;
}

// ---- attributes -------------------------------------------------------------

inline void write_attr(hid_t obj, const std::string& name, hid_t file_type, hid_t mem_type,
                       const void* value, const std::string& path) {
  const std::string what = "attribute '" + name + "'";
  Hid space = checked(H5Screate(H5S_SCALAR), H5Sclose, path, "dataspace for " + what);
  Hid attr =
      checked(H5Acreate2(obj, name.c_str(), file_type, space.get(), H5P_DEFAULT, H5P_DEFAULT),
              H5Aclose, path, "cannot create " + what);
  check(H5Awrite(attr.get(), mem_type, value), path, "cannot write " + what);
  close_checked(attr, path, "cannot close " + what);
}

inline void write_attr_i64(hid_t obj, const std::string& name, std::int64_t v,
                           const std::string& path) {
  write_attr(obj, name, H5T_STD_I64LE, H5T_NATIVE_INT64, &v, path);
}

inline void write_attr_u64(hid_t obj, const std::string& name, std::uint64_t v,
                           const std::string& path) {
  write_attr(obj, name, H5T_STD_U64LE, H5T_NATIVE_UINT64, &v, path);
}

inline void write_attr_f64(hid_t obj, const std::string& name, double v, const std::string& path) {
  write_attr(obj, name, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, &v, path);
}

// A variable-length UTF-8 string type: h5py reads these as Python str
// (fixed-length ones come back as bytes).
inline Hid vlen_utf8_type(const std::string& path) {
  Hid type = checked(H5Tcopy(H5T_C_S1), H5Tclose, path, "H5Tcopy(C_S1)");
  check(H5Tset_size(type.get(), H5T_VARIABLE), path, "H5Tset_size(VARIABLE)");
  check(H5Tset_cset(type.get(), H5T_CSET_UTF8), path, "H5Tset_cset(UTF8)");
  return type;
}

inline void write_attr_str(hid_t obj, const std::string& name, const std::string& v,
                           const std::string& path) {
  Hid type = vlen_utf8_type(path);
  const char* p = v.c_str();
  write_attr(obj, name, type.get(), type.get(), &p, path);
}

// Opens a single-valued attribute of the given type class.
inline Hid open_attr(hid_t obj, const std::string& name, H5T_class_t want,
                     const std::string& path) {
  htri_t exists = H5Aexists(obj, name.c_str());
  if (exists < 0) fail_hdf5(path, "cannot look up attribute '" + name + "'");
  if (exists == 0) fail(path, "attribute '" + name + "' is missing");
  Hid attr = checked(H5Aopen(obj, name.c_str(), H5P_DEFAULT), H5Aclose, path,
                     "cannot open attribute '" + name + "'");
  Hid space = checked(H5Aget_space(attr.get()), H5Sclose, path, "dataspace of '" + name + "'");
  if (H5Sget_simple_extent_npoints(space.get()) != 1) {
    fail(path, "attribute '" + name + "' is not a single value");
  }
  Hid type = checked(H5Aget_type(attr.get()), H5Tclose, path, "type of '" + name + "'");
  H5T_class_t cls = H5Tget_class(type.get());
  // Integers are accepted where floats are wanted (a hand-made file may
  // store cell_size_m = 1 as an integer); nothing else converts silently.
  bool ok = cls == want || (want == H5T_FLOAT && cls == H5T_INTEGER);
  if (!ok) fail(path, "attribute '" + name + "' has the wrong type");
  return attr;
}

inline std::int64_t read_attr_i64(hid_t obj, const std::string& name, const std::string& path) {
  Hid attr = open_attr(obj, name, H5T_INTEGER, path);
  std::int64_t v = 0;
  check(H5Aread(attr.get(), H5T_NATIVE_INT64, &v), path, "cannot read attribute '" + name + "'");
  return v;
}

inline std::uint64_t read_attr_u64(hid_t obj, const std::string& name, const std::string& path) {
  Hid attr = open_attr(obj, name, H5T_INTEGER, path);
  std::uint64_t v = 0;
  check(H5Aread(attr.get(), H5T_NATIVE_UINT64, &v), path, "cannot read attribute '" + name + "'");
  return v;
}

inline double read_attr_f64(hid_t obj, const std::string& name, const std::string& path) {
  Hid attr = open_attr(obj, name, H5T_FLOAT, path);
  double v = 0;
  check(H5Aread(attr.get(), H5T_NATIVE_DOUBLE, &v), path, "cannot read attribute '" + name + "'");
  return v;
}

// Reads a string attribute stored either variable-length (what erg writes)
// or fixed-length (what other tools may write).
inline std::string read_attr_str(hid_t obj, const std::string& name, const std::string& path) {
  Hid attr = open_attr(obj, name, H5T_STRING, path);
  const std::string what = "cannot read attribute '" + name + "'";
  Hid ftype = checked(H5Aget_type(attr.get()), H5Tclose, path, what);
  htri_t is_vlen = H5Tis_variable_str(ftype.get());
  if (is_vlen < 0) fail_hdf5(path, what);
  Hid mtype = checked(H5Tcopy(H5T_C_S1), H5Tclose, path, what);
  check(H5Tset_cset(mtype.get(), H5Tget_cset(ftype.get())), path, what);
  if (is_vlen > 0) {
    check(H5Tset_size(mtype.get(), H5T_VARIABLE), path, what);
    char* p = nullptr;
    check(H5Aread(attr.get(), mtype.get(), &p), path, what);
    std::string v = p ? p : "";
    H5free_memory(p);
    return v;
  }
  // Fixed length: read null-padded into a buffer one longer, so the text is
  // always terminated whatever padding the file uses.
  std::size_t size = H5Tget_size(ftype.get());
  if (size == 0) fail_hdf5(path, what);
  check(H5Tset_size(mtype.get(), size), path, what);
  check(H5Tset_strpad(mtype.get(), H5T_STR_NULLPAD), path, what);
  std::vector<char> buf(size + 1, '\0');
  check(H5Aread(attr.get(), mtype.get(), buf.data()), path, what);
  return std::string(buf.data());
}

}  // namespace erg::io::detail

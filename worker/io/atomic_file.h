// SPDX-License-Identifier: Apache-2.0
// The one way erg writes a file that must survive a crash: snapshots, XDMF,
// checkpoints, previews, exports, DIR/job.json, ergd's steering files and
// batch scripts, erg's downloads. Header-only, with no dependency beyond
// POSIX, so every program uses it (target erg_atomic_file).
//
// A writer creates "<path>.tmp-<pid>" (same directory, hence same file
// system, so rename(2) replaces <path> atomically), writes and closes it, then
// publishes it (replace_durably): fsync the data, rename over <path>, fsync
// the directory. If anything throws first, AtomicFile's destructor unlinks the
// temporary, so <path> only ever holds the previous complete file or the new
// complete file.
#pragma once

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstddef>
#include <cstdio>
#include <memory>
#include <string>
#include <string_view>
#include <system_error>
#include <utility>
#include <vector>

#include "io/io_error.h"

namespace erg::io::detail {

// Thread-safe text for an errno value (strerror is not thread-safe).
inline std::string errno_text(int err) {
  return std::generic_category().message(err);
}

// "<path>: <what>" is the shape of every IoError message in erg_io.
[[noreturn]] inline void fail(const std::string& path, const std::string& what) {
  throw IoError(path + ": " + what);
}

// Same, with the text of errno appended (for POSIX and stdio failures).
[[noreturn]] inline void fail_errno(const std::string& path, const std::string& what, int err) {
  fail(path, what + ": " + errno_text(err));
}

class AtomicFile {
 public:
  explicit AtomicFile(std::string path)
      : path_(std::move(path)), tmp_(path_ + ".tmp-" + std::to_string(::getpid())) {}
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;

  // unlink, not remove: if something other than our temporary file sits at
  // the temporary name (say a directory), it is not ours to delete.
  ~AtomicFile() {
    if (!committed_) ::unlink(tmp_.c_str());
  }

  const std::string& path() const { return path_; }
  const std::string& tmp() const { return tmp_; }

  // Opens the temporary for stdio writing; close it with close_stdio().
  FILE* open_stdio() const {
    FILE* fp = std::fopen(tmp_.c_str(), "wb");
    if (!fp) fail_errno(path_, "cannot create temporary file '" + tmp_ + "'", errno);
    return fp;
  }

  // Closes a stdio temporary, reporting delayed write errors (a full disk
  // often only shows at fflush or fclose).
  void close_stdio(FILE* fp) const {
    int err = 0;
    if (std::fflush(fp) != 0 || std::ferror(fp)) err = errno ? errno : EIO;
    if (std::fclose(fp) != 0 && err == 0) err = errno ? errno : EIO;
    if (err != 0) fail_errno(path_, "writing temporary file '" + tmp_ + "' failed", err);
  }

  // Writes `size` bytes as the whole temporary file.
  void write_whole(const void* data, std::size_t size) const {
    FILE* fp = open_stdio();
    const std::size_t written = std::fwrite(data, 1, size, fp);
    const int err = errno;
    if (written != size) {
      std::fclose(fp);
      fail_errno(path_, "writing temporary file '" + tmp_ + "' failed", err ? err : EIO);
    }
    close_stdio(fp);
  }

  // The temporary is complete and closed: publish it (replace_durably).
  void commit();
  // Only the rename of a synced temporary (write_files_atomic).
  void publish();

 private:
  std::string path_;
  std::string tmp_;
  bool committed_ = false;
};

}  // namespace erg::io::detail

namespace erg::io {

namespace detail {

// fsync of the complete, closed temporary `tmp` of `path`.
inline void sync_file(const std::string& tmp, const std::string& path) {
  const int fd = ::open(tmp.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) fail_errno(path, "cannot reopen temporary file '" + tmp + "' to sync it", errno);
  if (::fsync(fd) != 0) {
    const int err = errno;
    ::close(fd);
    fail_errno(path, "fsync of temporary file '" + tmp + "' failed", err);
  }
  ::close(fd);
}

inline void rename_file(const std::string& tmp, const std::string& path) {
  if (std::rename(tmp.c_str(), path.c_str()) != 0)
    fail_errno(path, "rename from temporary file '" + tmp + "' failed", errno);
}

// Best effort: some file systems refuse fsync on a directory, and the file
// is complete either way.
inline void sync_dir_of(const std::string& path) {
  std::string dir = ".";
  if (auto slash = path.find_last_of('/'); slash != std::string::npos)
    dir = slash == 0 ? "/" : path.substr(0, slash);
  const int dfd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dfd >= 0) {
    (void)::fsync(dfd);
    ::close(dfd);
  }
}

}  // namespace detail

// Publishes the complete, closed file `tmp` as `path`: fsync its data,
// rename it over `path`, fsync the directory. Without the first fsync a crash
// right after the rename could leave `path` naming an empty or partial file;
// without the last the rename itself may be lost.
inline void replace_durably(const std::string& tmp, const std::string& path) {
  detail::sync_file(tmp, path);
  detail::rename_file(tmp, path);
  detail::sync_dir_of(path);
}

// Writes `bytes` as the whole of `path`, atomically and durably. Throws
// IoError naming the file and the system's reason.
inline void write_file_atomic(const std::string& path, std::string_view bytes) {
  detail::AtomicFile out(path);
  out.write_whole(bytes.data(), bytes.size());
  out.commit();
}

// Several files (path, bytes) of one directory published together: all are
// written and synced first, then renamed one right after the other, so a
// reader of the directory (the worker's steering) finds them all or none but
// for a window of microseconds, not of the fsyncs.
inline void write_files_atomic(const std::vector<std::pair<std::string, std::string>>& files) {
  std::vector<std::unique_ptr<detail::AtomicFile>> out;
  for (const auto& [path, bytes] : files) {
    out.push_back(std::make_unique<detail::AtomicFile>(path));
    out.back()->write_whole(bytes.data(), bytes.size());
    detail::sync_file(out.back()->tmp(), path);
  }
  for (auto& f : out) f->publish();
  for (const auto& f : out) detail::sync_dir_of(f->path());
}

inline void detail::AtomicFile::commit() {
  sync_file(tmp_, path_);
  publish();
  sync_dir_of(path_);
}

inline void detail::AtomicFile::publish() {
  rename_file(tmp_, path_);
  committed_ = true;
}

}  // namespace erg::io

// Internal to erg_io: the write-to-temporary-then-rename protocol shared by
// every writer (snapshots, XDMF, checkpoints, PNGs).
//
// A writer creates "<path>.tmp-<pid>" (same directory, hence same file
// system, so rename(2) replaces <path> atomically), writes and closes it, then
// calls commit(): fsync the data, rename over <path>, fsync the directory. If
// anything throws first, the destructor unlinks the temporary, so <path> only
// ever holds the previous complete file or the new complete file.
#pragma once

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstddef>
#include <cstdio>
#include <string>
#include <system_error>
#include <utility>

#include "io/io.h"

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

  // The temporary is complete and closed: make its data durable, then
  // publish it under the final name. Without the fsync a crash right after
  // the rename could leave <path> naming an empty or partial file.
  void commit() {
    int fd = ::open(tmp_.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) fail_errno(path_, "cannot reopen temporary file '" + tmp_ + "' to sync it", errno);
    if (::fsync(fd) != 0) {
      int err = errno;
      ::close(fd);
      fail_errno(path_, "fsync of temporary file '" + tmp_ + "' failed", err);
    }
    ::close(fd);
    if (std::rename(tmp_.c_str(), path_.c_str()) != 0) {
      fail_errno(path_, "rename from temporary file '" + tmp_ + "' failed", errno);
    }
    committed_ = true;
    sync_parent_dir();
  }

 private:
  // Makes the rename itself durable. Best effort: some file systems refuse
  // fsync on a directory, and the new file is already complete either way.
  void sync_parent_dir() const {
    std::string dir = ".";
    if (auto slash = path_.find_last_of('/'); slash != std::string::npos) {
      dir = slash == 0 ? "/" : path_.substr(0, slash);
    }
    int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (fd >= 0) {
      (void)::fsync(fd);
      ::close(fd);
    }
  }

  std::string path_;
  std::string tmp_;
  bool committed_ = false;
};

}  // namespace erg::io::detail

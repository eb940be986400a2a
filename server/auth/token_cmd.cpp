// SPDX-License-Identifier: Apache-2.0
#include "auth/token_cmd.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cctype>
#include <cerrno>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <stdexcept>
#include <system_error>

#include "auth/random_hex.h"
#include "io/atomic_file.h"

namespace erg::server {
namespace {

namespace fs = std::filesystem;

[[noreturn]] void fail_errno(const std::string& path, const std::string& what, int err) {
  throw std::runtime_error(path + ": " + what + ": " + std::generic_category().message(err));
}

// A tenant is a name in logs, metrics labels and the dashboard: one word.
bool valid_tenant(const std::string& t) {
  if (t.empty() || t.size() > 64) return false;
  for (char c : t)
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-' || c == '.' ||
          c == '@'))
      return false;
  return true;
}

void usage(std::ostream& os) {
  os << "usage: ergd token new TENANT [--operator] [--tokens FILE (" << kDefaultTokensPath
     << ")]\n"
        "  prints a new random token and appends `TOKEN TENANT` to FILE (created with mode\n"
        "  0600 if missing); a running ergd picks it up within a second\n";
}

// Holds flock(2) on a directory for the lifetime of the object.
class DirLock {
 public:
  DirLock(const std::string& dir, const std::string& file)
      : fd_(::open(dir.c_str(), O_RDONLY | O_DIRECTORY)) {
    if (fd_ < 0) fail_errno(file, "cannot open its directory " + dir, errno);
    while (::flock(fd_, LOCK_EX) != 0)
      if (errno != EINTR) fail_errno(file, "cannot lock its directory " + dir, errno);
  }
  DirLock(const DirLock&) = delete;
  DirLock& operator=(const DirLock&) = delete;
  ~DirLock() { ::close(fd_); }

 private:
  int fd_;
};

}  // namespace

std::string new_token() {
  return random_hex(24);
}

void append_token(const std::string& path, const std::string& token, const std::string& tenant,
                  bool is_operator) {
  const fs::path p = fs::absolute(path);
  const std::string dir = p.parent_path().string();
  DirLock lock(dir, path);

  std::string text;
  struct stat st {};
  const bool exists = ::stat(p.c_str(), &st) == 0;
  if (exists) {
    if (!S_ISREG(st.st_mode)) throw std::runtime_error(path + ": not a regular file");
    std::ifstream in(p, std::ios::binary);
    if (!in) fail_errno(path, "cannot read the tokens file", errno);
    std::ostringstream ss;
    ss << in.rdbuf();
    text = ss.str();
    if (!text.empty() && text.back() != '\n') text += '\n';
  } else if (errno != ENOENT) {
    fail_errno(path, "cannot stat the tokens file", errno);
  } else {
    text = "# TOKEN TENANT [operator]: ergd's tokens (README, \"Tokens and tenants\")\n";
  }
  text += token + " " + tenant + (is_operator ? " operator" : "") + "\n";

  // The temporary is created 0600 before a byte is written, so the token is
  // never readable by others, not even for a moment.
  io::detail::AtomicFile out(p.string());
  const int fd = ::open(out.tmp().c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
  if (fd < 0) fail_errno(out.tmp(), "cannot create the temporary file", errno);
  auto fail_fd = [&](const std::string& what) {
    const int err = errno;
    ::close(fd);
    fail_errno(out.tmp(), what, err);
  };
  if (exists) {
    // Owner first: fchown clears nothing we set after it.
    if (::fchown(fd, st.st_uid, st.st_gid) != 0 && errno != EPERM)
      fail_fd("cannot keep the owner of the tokens file");
    if (::fchmod(fd, st.st_mode & 07777) != 0) fail_fd("cannot keep the mode of the tokens file");
  }
  std::size_t done = 0;
  while (done < text.size()) {
    const ssize_t n = ::write(fd, text.data() + done, text.size() - done);
    if (n < 0) {
      if (errno == EINTR) continue;
      fail_fd("writing failed");
    }
    done += static_cast<std::size_t>(n);
  }
  if (::close(fd) != 0) fail_errno(out.tmp(), "writing failed", errno);
  out.commit();  // fsync, rename over the tokens file, fsync the directory
}

int token_command(const std::vector<std::string>& args) {
  std::string tenant, path = kDefaultTokensPath;
  bool is_operator = false;
  if (args.empty() || args[0] == "--help" || args[0] == "-h") {
    usage(args.empty() ? std::cerr : std::cout);
    return args.empty() ? 2 : 0;
  }
  if (args[0] != "new") {
    std::cerr << "ergd token: unknown subcommand '" << args[0] << "' (the only one is `new`)\n";
    usage(std::cerr);
    return 2;
  }
  for (std::size_t i = 1; i < args.size(); ++i) {
    const std::string& a = args[i];
    if (a == "--tokens") {
      if (i + 1 >= args.size()) {
        std::cerr << "ergd token new: --tokens needs a file\n";
        return 2;
      }
      path = args[++i];
    } else if (a == "--operator") {
      is_operator = true;
    } else if (!a.empty() && a[0] == '-') {
      std::cerr << "ergd token new: unknown option '" << a << "'\n";
      usage(std::cerr);
      return 2;
    } else if (tenant.empty()) {
      tenant = a;
    } else {
      std::cerr << "ergd token new: one TENANT only (got '" << tenant << "' and '" << a << "')\n";
      return 2;
    }
  }
  if (!valid_tenant(tenant)) {
    std::cerr << "ergd token new: TENANT "
              << (tenant.empty() ? std::string("is missing") : "'" + tenant + "' is not valid")
              << "; allowed: 1 to 64 of A-Z a-z 0-9 _ - . @\n";
    return 2;
  }
  try {
    const std::string token = new_token();
    append_token(path, token, tenant, is_operator);
    std::cout << token << "\n" << std::flush;
    std::cerr << "ergd: added a token for tenant " << tenant << (is_operator ? " (operator)" : "")
              << " to " << path << "\n";
  } catch (const std::exception& e) {
    std::cerr << "ergd token new: " << e.what() << "\n";
    return 1;
  }
  return 0;
}

}  // namespace erg::server

#include "auth/tokens.h"

#include <sys/stat.h>

#include <fstream>
#include <sstream>
#include <stdexcept>

namespace erg::server {

namespace {

// Compares without an early exit, so the time taken does not tell an
// attacker how many leading characters of a token were right.
bool equal_constant_time(const std::string& a, const std::string& b) {
  unsigned diff = a.size() == b.size() ? 0u : 1u;
  for (size_t i = 0; i < a.size(); ++i)
    diff |= static_cast<unsigned>(a[i] ^ (i < b.size() ? b[i] : 0));
  return diff == 0;
}

}  // namespace

std::map<std::string, std::string> Tokens::parse(const std::string& text,
                                                 const std::string& origin) {
  std::map<std::string, std::string> out;
  std::istringstream in(text);
  std::string line;
  int n = 0;
  while (std::getline(in, line)) {
    ++n;
    if (auto h = line.find('#'); h != std::string::npos) line.resize(h);
    std::istringstream fields(line);
    std::string token, tenant, extra;
    if (!(fields >> token)) continue;
    if (!(fields >> tenant) || (fields >> extra))
      throw std::runtime_error(origin + ":" + std::to_string(n) +
                               ": expected `TOKEN TENANT` (two fields)");
    if (token.size() < 16)
      throw std::runtime_error(origin + ":" + std::to_string(n) +
                               ": token shorter than 16 characters");
    if (out.count(token))
      throw std::runtime_error(origin + ":" + std::to_string(n) + ": duplicate token");
    out[token] = tenant;
  }
  return out;
}

Tokens::Tokens(std::string path) : path_(std::move(path)) {
  reload_if_changed();
  if (tenants_.empty()) throw std::runtime_error(path_ + ": no tokens");
}

void Tokens::reload_if_changed() {
  struct stat st {};
  if (::stat(path_.c_str(), &st) != 0) {
    if (tenants_.empty()) throw std::runtime_error("cannot read tokens file " + path_);
    return;  // keep the tokens we have while the file is being replaced
  }
  if (st.st_mtim.tv_sec == mtime_.tv_sec && st.st_mtim.tv_nsec == mtime_.tv_nsec) return;
  std::ifstream f(path_);
  std::stringstream ss;
  ss << f.rdbuf();
  try {
    tenants_ = parse(ss.str(), path_);
    mtime_ = st.st_mtim;
  } catch (const std::exception&) {
    if (tenants_.empty()) throw;  // at start-up a bad file is fatal; later the old tokens stay
  }
}

std::optional<std::string> Tokens::tenant_of_token(const std::string& token) {
  std::lock_guard lock(mu_);
  reload_if_changed();
  std::optional<std::string> found;
  for (const auto& [t, tenant] : tenants_)
    if (equal_constant_time(t, token)) found = tenant;
  return found;
}

std::optional<std::string> Tokens::tenant_of_header(const std::string& authorization) {
  static const std::string kBearer = "Bearer ";
  if (authorization.size() <= kBearer.size() || authorization.compare(0, kBearer.size(), kBearer))
    return std::nullopt;
  return tenant_of_token(authorization.substr(kBearer.size()));
}

}  // namespace erg::server

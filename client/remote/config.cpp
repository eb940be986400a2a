// SPDX-License-Identifier: Apache-2.0
#include "remote/config.h"

#include <sys/stat.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace erg::client {

namespace fs = std::filesystem;

namespace {

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t\r");
  if (b == std::string::npos) return "";
  const auto e = s.find_last_not_of(" \t\r");
  return s.substr(b, e - b + 1);
}

}  // namespace

ConnectionFlags extract_connection_flags(std::vector<std::string>& args) {
  ConnectionFlags f;
  std::vector<std::string> rest;
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    std::optional<std::string>* slot = nullptr;
    if (a == "--server")
      slot = &f.server;
    else if (a == "--token")
      slot = &f.token;
    else if (a == "--ca")
      slot = &f.ca;
    if (!slot) {
      rest.push_back(a);
      continue;
    }
    if (i + 1 >= args.size() || args[i + 1].empty())
      throw std::invalid_argument(a + ": missing value");
    *slot = args[++i];
  }
  args = std::move(rest);
  return f;
}

std::map<std::string, std::string> parse_config(const std::string& text,
                                                const std::string& origin) {
  std::map<std::string, std::string> out;
  std::istringstream in(text);
  std::string line;
  int number = 0;
  while (std::getline(in, line)) {
    ++number;
    // A comment starts with `#` at the start of a line or after a blank, so
    // a token may hold a `#`.
    for (size_t k = 0; k < line.size(); ++k)
      if (line[k] == '#' && (k == 0 || line[k - 1] == ' ' || line[k - 1] == '\t')) {
        line.erase(k);
        break;
      }
    line = trim(line);
    if (line.empty()) continue;
    const std::string where = origin + ":" + std::to_string(number) + ": ";
    const auto eq = line.find('=');
    if (eq == std::string::npos)
      throw std::invalid_argument(where + "expected `key = value`, got '" + line + "'");
    const std::string key = trim(line.substr(0, eq));
    const std::string value = trim(line.substr(eq + 1));
    if (key != "server" && key != "token" && key != "ca")
      throw std::invalid_argument(where + "unknown key '" + key +
                                  "' (expected server, token or ca)");
    if (value.empty()) throw std::invalid_argument(where + key + ": missing value");
    out[key] = value;
  }
  return out;
}

std::string normalize_server(const std::string& address) {
  const std::string a = trim(address);
  if (a.empty()) throw std::invalid_argument("empty server address (expected HOST:PORT)");
  if (a.find(":/") != std::string::npos || a.rfind("unix:", 0) == 0) return a;  // a URI
  if (a[0] == '[') {                                                            // [v6]:port
    return a.find("]:") != std::string::npos ? a : a + ":" + std::to_string(kDefaultPort);
  }
  const auto colon = a.find(':');
  if (colon == std::string::npos) return a + ":" + std::to_string(kDefaultPort);
  if (a.find(':', colon + 1) != std::string::npos)  // bare v6 address
    return "[" + a + "]:" + std::to_string(kDefaultPort);
  return a;
}

std::pair<std::string, bool> config_path(const EnvLookup& env) {
  if (const char* p = env("ERG_CONFIG"); p && *p) return {p, true};
  if (const char* home = env("HOME"); home && *home)
    return {(fs::path(home) / ".config" / "erg" / "config").string(), false};
  return {"", false};
}

ConnectionSettings resolve_connection(const ConnectionFlags& flags, const EnvLookup& env) {
  ConnectionSettings s;
  auto from = [&](const std::optional<std::string>& flag, const char* flag_name, const char* var,
                  std::string& value, std::string& origin) {
    if (flag) {
      value = *flag;
      origin = flag_name;
    } else if (const char* v = env(var); v && *v) {
      value = v;
      origin = var;
    }
  };
  from(flags.server, "--server", "ERG_SERVER", s.server, s.server_origin);
  from(flags.token, "--token", "ERG_TOKEN", s.token, s.token_origin);
  from(flags.ca, "--ca", "ERG_CA", s.ca, s.ca_origin);

  if (s.server_origin.empty() || s.token_origin.empty() || s.ca_origin.empty()) {
    const auto [path, named] = config_path(env);
    std::error_code ec;
    if (!path.empty() && (named || fs::exists(path, ec))) {
      std::ifstream in(path);
      if (!in)
        throw std::invalid_argument("cannot read the config file " + path +
                                    (named ? " (named by ERG_CONFIG)" : ""));
      std::stringstream text;
      text << in.rdbuf();
      const auto cfg = parse_config(text.str(), path);
      auto take = [&](const char* key, std::string& value, std::string& origin) {
        if (!origin.empty() || !cfg.count(key)) return false;
        value = cfg.at(key);
        origin = path;
        return true;
      };
      take("server", s.server, s.server_origin);
      if (take("token", s.token, s.token_origin)) {
        struct stat st {};
        if (::stat(path.c_str(), &st) == 0 && (st.st_mode & 077) != 0)
          s.warnings.push_back(path + " holds a token and is readable by others (chmod 600 " +
                               path + ")");
      }
      if (take("ca", s.ca, s.ca_origin) && fs::path(s.ca).is_relative())
        s.ca = (fs::path(path).parent_path() / s.ca).lexically_normal().string();
    }
  }
  if (s.server_origin.empty()) {
    s.server = kDefaultServer;
    s.server_origin = "default";
  }
  s.server = normalize_server(s.server);
  return s;
}

EnvLookup process_env() {
  return [](const char* name) -> const char* { return std::getenv(name); };
}

}  // namespace erg::client

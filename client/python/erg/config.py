# SPDX-License-Identifier: Apache-2.0
"""Where the client finds ergd, and with which token: the rules of the erg
CLI (client/remote/config.h), so a Python program and `erg` given the same
environment talk to the same server as the same tenant.

Each setting is resolved on its own, the first found winning:
  1. an argument of erg.Client (the CLI's --server, --token, --ca)
  2. the environment: ERG_SERVER, ERG_TOKEN, ERG_CA
  3. the config file: $ERG_CONFIG (must exist), else ~/.config/erg/config
     (may be absent), lines `server = host:port`, `token = T`,
     `ca = /path/ca.pem` (relative to the file's folder), blank lines and
     `#` comments (at the start of a line or after a blank)
  4. the default: server 127.0.0.1:7117, no token, no TLS.
The config file is read only when an argument or the environment leaves a
setting open."""
import os
import stat
from dataclasses import dataclass, field

DEFAULT_SERVER = "127.0.0.1:7117"
DEFAULT_PORT = 7117
KEYS = ("server", "token", "ca")


def parse_config(text, origin):
    """The settings of a config file; ValueError naming origin:line on a
    line that is not `key = value`, an unknown key or an empty value."""
    out = {}
    for number, line in enumerate(text.split("\n"), 1):
        # A comment starts with `#` at the start of a line or after a blank,
        # so a token may hold a `#`.
        for k, c in enumerate(line):
            if c == "#" and (k == 0 or line[k - 1] in " \t"):
                line = line[:k]
                break
        line = line.strip(" \t\r")
        if not line:
            continue
        where = "%s:%d: " % (origin, number)
        if "=" not in line:
            raise ValueError(where + "expected `key = value`, got '%s'" % line)
        key, value = (s.strip(" \t\r") for s in line.split("=", 1))
        if key not in KEYS:
            raise ValueError(where + "unknown key '%s' (expected server, token or ca)" % key)
        if not value:
            raise ValueError(where + key + ": missing value")
        out[key] = value
    return out


def normalize_server(address):
    """"host" -> "host:7117"; "host:port", "[v6]:port" and gRPC target URIs
    ("dns:///host:port", "unix:/path") unchanged."""
    a = address.strip(" \t\r")
    if not a:
        raise ValueError("empty server address (expected HOST:PORT)")
    if ":/" in a or a.startswith("unix:"):
        return a
    if a[0] == "[":
        return a if "]:" in a else "%s:%d" % (a, DEFAULT_PORT)
    if ":" not in a:
        return "%s:%d" % (a, DEFAULT_PORT)
    if a.count(":") > 1:  # a bare v6 address
        return "[%s]:%d" % (a, DEFAULT_PORT)
    return a


def config_path(env=None):
    """(path, named): $ERG_CONFIG (named: True) or $HOME/.config/erg/config;
    ("", False) when neither is set."""
    env = os.environ if env is None else env
    if env.get("ERG_CONFIG"):
        return env["ERG_CONFIG"], True
    if env.get("HOME"):
        return os.path.join(env["HOME"], ".config", "erg", "config"), False
    return "", False


@dataclass
class Settings:
    server: str = ""
    token: str = ""  # empty: none
    ca: str = ""     # PEM root certificate file; empty: a plaintext channel
    # Where each came from: "argument", "ERG_SERVER", the config file, "default".
    origins: dict = field(default_factory=dict)
    warnings: list = field(default_factory=list)


def resolve(server=None, token=None, ca=None, env=None):
    """The Settings for these arguments (None: not given) in `env`
    (default: the process environment)."""
    env = os.environ if env is None else env
    s = Settings()
    for key, arg, var in (("server", server, "ERG_SERVER"), ("token", token, "ERG_TOKEN"),
                          ("ca", ca, "ERG_CA")):
        if arg is not None:
            setattr(s, key, str(arg))
            s.origins[key] = "argument"
        elif env.get(var):
            setattr(s, key, env[var])
            s.origins[key] = var
    if len(s.origins) < len(KEYS):
        path, named = config_path(env)
        if path and (named or os.path.exists(path)):
            try:
                with open(path, encoding="utf-8") as f:
                    text = f.read()
            except OSError:
                raise ValueError("cannot read the config file " + path
                                 + (" (named by ERG_CONFIG)" if named else "")) from None
            cfg = parse_config(text, path)
            for key in KEYS:
                if key in s.origins or key not in cfg:
                    continue
                value = cfg[key]
                if key == "token" and os.stat(path).st_mode & (stat.S_IRWXG | stat.S_IRWXO):
                    s.warnings.append("%s holds a token and is readable by others (chmod 600 %s)"
                                      % (path, path))
                if key == "ca" and not os.path.isabs(value):
                    value = os.path.normpath(os.path.join(os.path.dirname(path), value))
                setattr(s, key, value)
                s.origins[key] = path
    if "server" not in s.origins:
        s.server = DEFAULT_SERVER
        s.origins["server"] = "default"
    s.server = normalize_server(s.server)
    return s

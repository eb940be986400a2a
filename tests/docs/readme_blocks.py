# SPDX-License-Identifier: Apache-2.0
"""README's runnable code blocks, run as written.

A fenced block directly preceded by a line `<!-- runnable -->` (or
`<!-- runnable NAME -->`) is a block that a reader is told to paste into a
shell at the repository's root. The tests run each one, unchanged, with
bash -e in a scratch copy of that root: every top-level entry of the
source tree linked in, `build` linked to the build tree being tested, HOME
pointing into the scratch directory (so `~` is not the tester's), and
outputs (`runs/`, ...) written there. Unnamed blocks run in README order in
one scratch directory (a later block may use an earlier one's outputs);
the blocks of one NAME are parts of one shell session, run in order in a
single bash, with the test's checks between the parts."""
import os
import re
import shutil
import signal
import sys
import subprocess
import tempfile

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
README = os.path.join(ROOT, "README.md")
MARK = re.compile(r"^<!-- runnable(?: ([\w.-]+))? -->$")
FENCE = re.compile(r"^```(\w*)\s*$")


class Block:
    def __init__(self, name, lang, code, line):
        self.name, self.lang, self.code, self.line = name, lang, code, line

    def __repr__(self):
        return f"README.md:{self.line} ({self.name or 'runnable'})"


def blocks(path=README):
    """Every runnable block of README, in order."""
    with open(path, encoding="utf-8") as f:
        lines = f.read().split("\n")
    out = []
    i = 0
    while i < len(lines):
        m = MARK.match(lines[i].strip())
        if m:
            j = i + 1
            while j < len(lines) and not lines[j].strip():
                j += 1
            f = FENCE.match(lines[j].strip()) if j < len(lines) else None
            if not f:
                raise ValueError(f"README.md:{i + 1}: a runnable mark not followed by a code block")
            k = j + 1
            while k < len(lines) and lines[k].strip() != "```":
                k += 1
            out.append(Block(m.group(1), f.group(1), "\n".join(lines[j + 1:k]) + "\n", j + 2))
            i = k
        i += 1
    return out


class Scratch:
    """A scratch copy of the repository root (links), with `build` the tested build tree."""

    def __init__(self, build_dir):
        self.dir = tempfile.mkdtemp(prefix="erg-readme-")
        for name in os.listdir(ROOT):
            if name in ("build", "runs", ".git"):
                continue
            os.symlink(os.path.join(ROOT, name), os.path.join(self.dir, name))
        os.symlink(os.path.abspath(build_dir), os.path.join(self.dir, "build"))
        self.home = os.path.join(self.dir, "home")
        os.mkdir(self.home)
        self.env = dict(os.environ, HOME=self.home)
        for k in ("ERG_SERVER", "ERG_TOKEN", "ERG_CA", "ERG_CONFIG"):
            self.env.pop(k, None)

    def path(self, *parts):
        return os.path.join(self.dir, *parts)

    def run(self, block, timeout=600):
        """Runs one block in a fresh bash -e; returns the CompletedProcess."""
        return subprocess.run(["bash", "-e", "-c", block.code], cwd=self.dir, env=self.env,
                              capture_output=True, text=True, timeout=timeout)

    def run_python(self, block, timeout=600):
        """Runs a ```python block in the scratch root, with the Python running the tests."""
        return subprocess.run([sys.executable, "-c", block.code], cwd=self.dir, env=self.env,
                              capture_output=True, text=True, timeout=timeout)

    def cleanup(self):
        shutil.rmtree(self.dir, ignore_errors=True)


class Session:
    """One bash -e fed the parts of a named block in turn (their variables,
    background jobs and working directory carry over, as in a terminal)."""
    END = "__erg_readme_part_done__"

    def __init__(self, scratch):
        self.log = open(scratch.path("session.log"), "w+")
        # Its own process group: whatever the parts started in the
        # background is stopped at close, even when a part failed.
        self.p = subprocess.Popen(["bash", "-e"], cwd=scratch.dir, env=scratch.env,
                                  stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=self.log,
                                  text=True, start_new_session=True)

    def part(self, block, timeout=600):
        """Runs a part; returns its stdout. Raises with the log if bash failed."""
        self.p.stdin.write(block.code + f"\necho {self.END}\n")
        self.p.stdin.flush()
        out = []
        for line in self.p.stdout:
            if line.strip() == self.END:
                return "".join(out)
            out.append(line)
        self.p.wait(timeout=timeout)
        raise AssertionError(f"{block!r} failed (exit {self.p.returncode}):\n" + "".join(out)
                             + "\n" + self.stderr())

    def stderr(self):
        self.log.flush()
        self.log.seek(0)
        return self.log.read()

    def close(self):
        if self.p.poll() is None:
            self.p.stdin.close()
            try:
                self.p.wait(timeout=60)
            except subprocess.TimeoutExpired:
                self.p.kill()
                self.p.wait()
        try:
            os.killpg(self.p.pid, signal.SIGTERM)
        except ProcessLookupError:
            pass
        self.log.close()

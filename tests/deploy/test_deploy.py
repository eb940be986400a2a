# SPDX-License-Identifier: Apache-2.0
"""deploy/: the systemd unit passes `systemd-analyze verify` (and a broken
copy does not: the check can fail), its example settings are flags ergd
accepts, and the Slurm script templates are valid bash. `cmake --install
--prefix P` installs the programs, a unit whose ExecStart is P/bin/ergd
(verified), the examples and README, and the installed erg runs a job.
`ergd token new` makes tokens that a running ergd accepts."""
import os
import re
import shlex
import socket
import stat
import shutil
import signal
import subprocess
import tempfile
import time
import unittest
import urllib.error
import urllib.request

ROOT = os.path.join(os.path.dirname(__file__), "..", "..")
DEPLOY = os.path.join(ROOT, "deploy")
ERGD = os.path.join(os.environ["ERG_BIN_DIR"], "ergd")
BUILD = os.path.dirname(os.environ["ERG_BIN_DIR"])
ANALYZE = shutil.which("systemd-analyze")


def unit_text(ergd_path):
    """The unit template with ExecStart at ergd_path, as `cmake --install` writes it."""
    with open(os.path.join(DEPLOY, "systemd", "ergd.service.in")) as f:
        text = f.read()
    bindir, name = os.path.split(ergd_path)
    return text.replace("@ERGD_BINDIR@/ergd", os.path.join(bindir, name))


class Deploy(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.mkdtemp(prefix="erg-deploy-")

    def tearDown(self):
        shutil.rmtree(self.tmp, ignore_errors=True)

    def verify(self, text):
        path = os.path.join(self.tmp, "ergd.service")
        with open(path, "w") as f:
            f.write(text)
        return subprocess.run([ANALYZE, "verify", "--man=no", path], capture_output=True,
                              text=True)

    @unittest.skipUnless(ANALYZE, "systemd-analyze missing")
    def test_systemd_unit_verifies(self):
        r = self.verify(unit_text(os.path.abspath(ERGD)))
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertNotIn("ergd.service", r.stderr)  # no warning about our unit

    @unittest.skipUnless(ANALYZE, "systemd-analyze missing")
    def test_a_broken_unit_fails_verification(self):
        r = self.verify(unit_text("/nonexistent/ergd"))
        self.assertNotEqual(r.returncode, 0)
        r = self.verify(unit_text(os.path.abspath(ERGD)).replace("Type=simple", "Type=bogus"))
        self.assertIn("bogus", r.stderr)

    def test_example_settings_are_flags_ergd_accepts(self):
        env = {}
        with open(os.path.join(DEPLOY, "systemd", "ergd.env")) as f:
            for line in f:
                line = line.strip()
                if line and not line.startswith("#"):
                    k, v = line.split("=", 1)
                    env[k] = v
        self.assertTrue({"ERGD_LISTEN", "ERGD_HTTP", "ERGD_OPTIONS"} <= set(env))
        tokens = os.path.join(self.tmp, "tokens")
        with open(tokens, "w") as f:
            f.write("deploy-test-token-0123 ops\n")
        p = subprocess.Popen([ERGD, "--listen", "127.0.0.1:0", "--http", "127.0.0.1:0",
                              "--data", os.path.join(self.tmp, "data"), "--tokens", tokens]
                             + shlex.split(env["ERGD_OPTIONS"]), stderr=subprocess.PIPE,
                             text=True)
        time.sleep(1.5)
        self.assertIsNone(p.poll(), p.stderr.read() if p.poll() is not None else "")
        p.send_signal(signal.SIGTERM)
        _, err = p.communicate(timeout=60)
        self.assertEqual(p.returncode, 0, err)
        self.assertIn("serving", err)

    def test_slurm_scripts_are_valid_bash(self):
        for name in ("ergd-job.sbatch", "erg-run.sbatch", "sand-sea.sbatch"):
            r = subprocess.run(["bash", "-n", os.path.join(DEPLOY, "slurm", name)],
                               capture_output=True, text=True)
            self.assertEqual(r.returncode, 0, name + ": " + r.stderr)

    def test_install_into_a_prefix(self):
        prefix = os.path.join(self.tmp, "prefix")
        r = subprocess.run(["cmake", "--install", BUILD, "--prefix", prefix], capture_output=True,
                           text=True)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        for name in ("erg", "erg-worker", "ergd", "erg-bench"):
            self.assertTrue(os.access(os.path.join(prefix, "bin", name), os.X_OK), name)
        for rel in ("share/erg/examples/barchans.json", "share/erg/systemd/ergd.env",
                    "share/erg/slurm/ergd-job.sbatch", "share/doc/erg/README.md",
                    "share/doc/erg/LICENSE", "share/doc/erg/NOTICE"):
            self.assertTrue(os.path.isfile(os.path.join(prefix, rel)), rel)
        with open(os.path.join(prefix, "lib/systemd/system/ergd.service")) as f:
            unit = f.read()
        self.assertNotIn("@ERGD_BINDIR@", unit)
        self.assertIn("ExecStart=" + os.path.join(prefix, "bin", "ergd") + " ", unit)
        if ANALYZE:
            r = self.verify(unit)
            self.assertEqual(r.returncode, 0, r.stderr)
        # The installed erg finds the installed erg-worker next to it.
        out = os.path.join(self.tmp, "run")
        r = subprocess.run([os.path.join(prefix, "bin", "erg"), "run",
                            os.path.join(prefix, "share/erg/examples/barchans.json"), "--out", out,
                            "--steps", "3"], capture_output=True, text=True, timeout=300)
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertTrue(os.path.isfile(os.path.join(out, "snapshots", "step_00000003.h5")))
        self.check_installed_programs_read_installed_files(prefix)

    def check_installed_programs_read_installed_files(self, prefix):
        """The installed erg validate runs P/share/erg/validate, and the installed
        ergd's default Slurm template is P/share/erg/slurm's: each is swapped
        for a file that gives itself away (a script that says so, an empty
        template that ergd refuses by its path), which the source tree's
        copies cannot."""
        share = os.path.join(prefix, "share", "erg")
        self.assertTrue(os.path.isfile(os.path.join(share, "validate", "validate.py")))
        self.assertTrue(os.path.isfile(os.path.join(share, "validate", "thresholds.json")))
        with open(os.path.join(share, "validate", "validate.py"), "w") as f:
            f.write("import sys\nprint('installed validate.py', sys.argv[1:])\n")
        r = subprocess.run([os.path.join(prefix, "bin", "erg"), "validate", "--quick", "--out",
                            os.path.join(self.tmp, "report")], capture_output=True, text=True,
                           timeout=60,
                           env={k: v for k, v in os.environ.items() if k != "ERG_VALIDATE_DIR"})
        self.assertIn("installed validate.py", r.stdout, r.stdout + r.stderr)
        template = os.path.join(share, "slurm", "ergd-job.sbatch")
        open(template, "w").close()  # empty: ergd refuses it, naming its path
        tokens = os.path.join(self.tmp, "tokens-installed")
        with open(tokens, "w") as f:
            f.write("a" * 32 + " alice\n")
        os.chmod(tokens, 0o600)
        r = subprocess.run([os.path.join(prefix, "bin", "ergd"), "--listen", "127.0.0.1:0",
                            "--data", os.path.join(self.tmp, "data"), "--tokens", tokens,
                            "--launcher", "slurm"], capture_output=True, text=True, timeout=60)
        self.assertNotEqual(r.returncode, 0)
        self.assertIn("cannot read the Slurm script template " + template, r.stderr)

    def test_token_new_appends_a_random_token(self):
        tokens = os.path.join(self.tmp, "tokens")
        made = []
        for tenant in ("dunelab", "ops"):
            r = subprocess.run([ERGD, "token", "new", tenant, "--tokens", tokens]
                               + (["--operator"] if tenant == "ops" else []),
                               capture_output=True, text=True)
            self.assertEqual(r.returncode, 0, r.stderr)
            self.assertRegex(r.stdout, r"^[0-9a-f]{48}\n$")
            made.append(r.stdout.strip())
        self.assertNotEqual(made[0], made[1])
        self.assertEqual(stat.S_IMODE(os.stat(tokens).st_mode), 0o600)
        with open(tokens) as f:
            lines = [l.split() for l in f if l.strip() and not l.startswith("#")]
        self.assertEqual(lines, [[made[0], "dunelab"], [made[1], "ops", "operator"]])
        # An existing file keeps its mode (root:ergd 0640 stays readable by ergd).
        os.chmod(tokens, 0o640)
        r = subprocess.run([ERGD, "token", "new", "third", "--tokens", tokens],
                           capture_output=True, text=True)
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertEqual(stat.S_IMODE(os.stat(tokens).st_mode), 0o640)
        self.assertEqual([n for n in os.listdir(self.tmp) if n != "tokens"], [])  # no temporary
        # Bad arguments name what is wrong.
        for args, says in ((["new"], "TENANT is missing"),
                           (["new", "two words"], "is not valid"),
                           (["new", "x", "--bogus"], "unknown option '--bogus'"),
                           (["old", "x"], "unknown subcommand 'old'")):
            r = subprocess.run([ERGD, "token"] + args + ["--tokens", tokens],
                               capture_output=True, text=True)
            self.assertEqual(r.returncode, 2, args)
            self.assertIn(says, r.stderr)
        r = subprocess.run([ERGD, "token", "new", "x", "--tokens",
                            os.path.join(self.tmp, "missing", "tokens")], capture_output=True,
                           text=True)
        self.assertEqual(r.returncode, 1)
        self.assertIn("No such file or directory", r.stderr)

    def test_a_running_ergd_accepts_a_new_token(self):
        tokens = os.path.join(self.tmp, "tokens")
        first = subprocess.run([ERGD, "token", "new", "a", "--tokens", tokens],
                               capture_output=True, text=True, check=True).stdout.strip()
        with socket.socket() as sock:
            sock.bind(("127.0.0.1", 0))
            port = sock.getsockname()[1]
        p = subprocess.Popen([ERGD, "--listen", "127.0.0.1:0", "--http", f"127.0.0.1:{port}",
                              "--data", os.path.join(self.tmp, "data"), "--tokens", tokens],
                             stderr=subprocess.PIPE, text=True)
        try:
            for line in p.stderr:
                if "serving" in line:
                    break
            second = subprocess.run([ERGD, "token", "new", "b", "--tokens", tokens],
                                    capture_output=True, text=True, check=True).stdout.strip()
            def status(token):
                req = urllib.request.Request(f"http://127.0.0.1:{port}/api/jobs",
                                             headers={"Authorization": "Bearer " + token})
                try:
                    with urllib.request.urlopen(req, timeout=5) as resp:
                        return resp.status
                except urllib.error.HTTPError as e:
                    return e.code

            # ergd re-reads the file within a second of the change.
            deadline = time.monotonic() + 5
            while status(second) != 200 and time.monotonic() < deadline:
                time.sleep(0.1)
            self.assertEqual(status(second), 200)
            self.assertEqual(status(first), 200)
            self.assertEqual(status("0" * 48), 401)
        finally:
            p.send_signal(signal.SIGTERM)
            p.communicate(timeout=60)


if __name__ == "__main__":
    unittest.main()

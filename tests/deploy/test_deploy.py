"""deploy/: the systemd unit passes `systemd-analyze verify` (and a broken
copy does not: the check can fail), its example settings are flags ergd
accepts, and the Slurm script templates are valid bash."""
import os
import shlex
import shutil
import signal
import subprocess
import tempfile
import time
import unittest

ROOT = os.path.join(os.path.dirname(__file__), "..", "..")
DEPLOY = os.path.join(ROOT, "deploy")
ERGD = os.path.join(os.environ["ERG_BIN_DIR"], "ergd")
ANALYZE = shutil.which("systemd-analyze")


def unit_text(ergd_path):
    with open(os.path.join(DEPLOY, "systemd", "ergd.service")) as f:
        return f.read().replace("/usr/local/bin/ergd", ergd_path)


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
        for name in ("ergd-job.sbatch", "erg-run.sbatch"):
            r = subprocess.run(["bash", "-n", os.path.join(DEPLOY, "slurm", name)],
                               capture_output=True, text=True)
            self.assertEqual(r.returncode, 0, name + ": " + r.stderr)


if __name__ == "__main__":
    unittest.main()

"""The erg client's remote commands against a scripted fake ergd.

The real erg binary (ERG_BIN_DIR) talks gRPC to fake_ergd.Server in this
process; the fake breaks streams and lies about checksums on cue, which the
real ergd cannot be made to do on demand. ergd itself is tested in
tests/server.
"""
import hashlib
import json
import os
import shutil
import subprocess
import tempfile
import unittest

import fake_ergd
from fake_ergd import S, TOKEN

ERG = os.path.join(os.environ["ERG_BIN_DIR"], "erg")
EXAMPLES = os.environ["ERG_EXAMPLES_DIR"]


class RemoteCli(unittest.TestCase):
    def setUp(self):
        self.server = fake_ergd.Server()
        self.fake = self.server.fake
        self.tmp = tempfile.mkdtemp(prefix="erg_client_")
        self.env = {k: v for k, v in os.environ.items() if not k.startswith("ERG_")}
        self.env.update(HOME=self.tmp, ERG_SERVER=self.server.address, ERG_TOKEN=TOKEN)

    def tearDown(self):
        self.server.stop()
        shutil.rmtree(self.tmp, ignore_errors=True)

    def erg(self, *args, env=None, timeout=60):
        p = subprocess.run([ERG, *args], env=env or self.env, capture_output=True, text=True,
                           timeout=timeout)
        return p.returncode, p.stdout, p.stderr

    def requests(self, method):
        return [r for m, r in self.fake.requests if m == method]

    def job_file(self, **run):
        with open(os.path.join(EXAMPLES, "barchans.json")) as f:
            d = json.load(f)
        d["run"].update(run)
        path = os.path.join(self.tmp, "job.json")
        with open(path, "w") as f:
            json.dump(d, f)
        return path

    # -- submit ------------------------------------------------------------------
    def test_submit_prints_only_the_id_and_sends_overrides_and_resources(self):
        code, out, err = self.erg("submit", self.job_file(), "--steps", "30", "--ranks", "2",
                                  "--threads", "3", "--key", "k-1")
        self.assertEqual(code, 0, err)
        job_id = out.strip()
        self.assertEqual(out, job_id + "\n")
        self.assertRegex(job_id, r"^j-[0-9a-f]{16}$")
        self.assertIn("as " + job_id + ", QUEUED", err)
        (req,) = self.requests("SubmitJob")
        self.assertEqual(req.spec.run.steps, 30)
        with open(os.path.join(EXAMPLES, "barchans.json")) as f:
            every = json.load(f)["run"]["snapshot_every"]
        self.assertEqual(req.spec.run.snapshot_every, every)  # the file's
        self.assertTrue(req.spec.model.HasField("time_step_days"))  # defaults filled
        self.assertEqual(req.resources.ranks, 2)
        self.assertEqual(req.resources.threads_per_rank, 3)
        self.assertEqual(req.idempotency_key, "k-1")
        # The same key again: the same job.
        code, out2, err = self.erg("submit", self.job_file(), "--key", "k-1")
        self.assertEqual((code, out2), (0, out), err)
        # Without --key each invocation still sends a key of its own.
        self.erg("submit", self.job_file())
        self.assertTrue(self.requests("SubmitJob")[-1].idempotency_key)

    def test_submit_rejects_an_invalid_job_before_calling(self):
        path = self.job_file()
        with open(path) as f:
            d = json.load(f)
        d["domain"]["nx"] = -5
        with open(path, "w") as f:
            json.dump(d, f)
        code, out, err = self.erg("submit", path)
        self.assertEqual(code, 2)
        self.assertEqual(out, "")
        self.assertIn("erg: invalid job:\n", err)
        self.assertIn("domain.nx = -5 is out of range", err)
        self.assertEqual(self.requests("SubmitJob"), [])
        code, _, err = self.erg("submit", self.job_file(), "--out", "x")
        self.assertEqual(code, 2)
        self.assertIn("--out is not available for a remote job", err)

    def test_submit_watch_follows_the_job(self):
        code, out, err = self.erg("submit", self.job_file(steps=20, snapshot_every=10), "--watch")
        self.assertEqual(code, 0, err)
        self.assertRegex(out, r"^j-[0-9a-f]{16}\n$")
        self.assertIn("SUCCEEDED", err)

    # -- errors ------------------------------------------------------------------
    def test_status_codes_become_one_line_and_an_exit_code(self):
        code, out, err = self.erg("status", "j-0000000000000000")
        self.assertEqual(code, 5)
        self.assertEqual(err, "erg: status: NOT_FOUND: no job j-0000000000000000\n")
        env = dict(self.env, ERG_TOKEN="wrong")
        code, _, err = self.erg("jobs", env=env)
        self.assertEqual(code, 4)
        self.assertEqual(err, "erg: jobs: UNAUTHENTICATED: no or unknown bearer token\n")
        job = self.fake.add_job(state=S.SUCCEEDED)
        code, _, err = self.erg("steer", job.id, self.events_file())
        self.assertEqual(code, 1)
        self.assertEqual(err, f"erg: steer: FAILED_PRECONDITION: job {job.id} is SUCCEEDED, "
                              "not RUNNING\n")

    def test_unreachable_server(self):
        port = self.server.port
        self.server.stop()
        code, _, err = self.erg("jobs", "--server", f"127.0.0.1:{port}")
        self.assertEqual(code, 1)
        self.assertTrue(err.startswith(f"erg: cannot reach ergd at 127.0.0.1:{port} ("), err)
        self.assertEqual(len(err.splitlines()), 1)
        code, _, err = self.erg("watch", "j-1", "--server", f"127.0.0.1:{port}", timeout=10)
        self.assertEqual(code, 1)
        self.assertIn("cannot reach ergd", err)

    # -- where the server and token come from ------------------------------------
    def test_config_file_and_flags_anywhere(self):
        job = self.fake.add_job()
        cfg = os.path.join(self.tmp, "cfg")
        with open(cfg, "w") as f:
            f.write(f"# test\nserver = {self.server.address}\ntoken = {TOKEN}\n")
        os.chmod(cfg, 0o600)
        env = {k: v for k, v in self.env.items() if k not in ("ERG_SERVER", "ERG_TOKEN")}
        code, out, err = self.erg("status", job.id, env=dict(env, ERG_CONFIG=cfg))
        self.assertEqual(code, 0, err)
        self.assertIn(job.id, out)
        # ~/.config/erg/config
        os.makedirs(os.path.join(self.tmp, ".config", "erg"))
        shutil.copy(cfg, os.path.join(self.tmp, ".config", "erg", "config"))
        code, _, err = self.erg("status", job.id, env=env)
        self.assertEqual(code, 0, err)
        # Flags before the command, and over the environment.
        bad = dict(self.env, ERG_SERVER="127.0.0.1:1", ERG_TOKEN="wrong")
        code, _, err = self.erg("--server", self.server.address, "status", "--token", TOKEN,
                                job.id, env=bad)
        self.assertEqual(code, 0, err)
        code, _, err = self.erg("jobs", env=dict(env, ERG_CONFIG=os.path.join(self.tmp, "no")))
        self.assertEqual(code, 2)
        self.assertIn("cannot read the config file", err)

    # -- jobs, status, cancel, steer ---------------------------------------------
    def test_jobs_pages_and_filters(self):
        for _ in range(55):
            self.fake.add_job(state=S.SUCCEEDED)
        failed = self.fake.add_job(state=S.FAILED)
        code, out, err = self.erg("jobs")
        self.assertEqual(code, 0, err)
        self.assertEqual(len(out.splitlines()), 1 + 50)
        self.assertIn("--all-pages", err)
        code, out, err = self.erg("jobs", "--all-pages")
        self.assertEqual(len(out.splitlines()), 1 + 56)
        self.assertEqual(err, "")
        code, out, err = self.erg("jobs", "--state", "failed")
        lines = out.splitlines()
        self.assertEqual(len(lines), 2, out)
        self.assertEqual(lines[1].split()[:3], [failed.id, "FAILED", "0/40"])
        code, _, err = self.erg("jobs", "--state", "sleeping")
        self.assertEqual(code, 2)

    def test_status_human_and_json(self):
        job = self.fake.add_job(state=S.FAILED, failure_reason="worker crashed",
                                log_tail="line one\nline two", attempts=2, disk_bytes=3 << 20)
        code, out, err = self.erg("status", job.id)
        self.assertEqual(code, 0, err)
        self.assertIn("state      FAILED", out)
        self.assertIn("reason     worker crashed", out)
        self.assertIn("  | line two", out)
        self.assertIn("attempts   2", out)
        self.assertIn("3.00 MiB", out)
        code, out, err = self.erg("status", job.id, "--json")
        self.assertEqual(code, 0, err)
        d = json.loads(out)
        self.assertEqual(d["id"], job.id)
        self.assertEqual(d["state"], "FAILED")
        self.assertEqual(d["spec"]["domain"]["nx"], "64")  # int64 as a string (proto JSON)

    def test_cancel(self):
        job = self.fake.add_job(state=S.QUEUED)
        code, out, err = self.erg("cancel", job.id)
        self.assertEqual((code, out), (0, "CANCELLED\n"), err)

    def events_file(self, text=None):
        path = os.path.join(self.tmp, "events.json")
        with open(path, "w") as f:
            f.write(text or '[{"sand": {"x_m": 1, "y_m": 2, "radius_m": 3, "height": 1}},'
                            ' {"bedrock": {"x_m": 5, "y_m": 5, "radius_m": 2, "height": -1}}]')
        return path

    def test_steer_array_or_one_event(self):
        job = self.fake.add_job(state=S.RUNNING)
        job.progress.step = 7
        code, out, err = self.erg("steer", job.id, self.events_file())
        self.assertEqual(code, 0, err)
        lines = out.splitlines()
        self.assertEqual(len(lines), 2)
        self.assertTrue(lines[0].startswith('step 8: {"sand":'), lines[0])
        self.assertEqual(len(self.requests("SteerJob")[0].events), 2)
        code, out, err = self.erg("steer", job.id, self.events_file(
            '{"vegetation": {"x_m": 1, "y_m": 1, "radius_m": 4, "density": 0.5}}'))
        self.assertEqual(code, 0, err)
        self.assertTrue(out.startswith('step 8: {"vegetation":'), out)
        code, _, err = self.erg("steer", job.id, self.events_file('{"sandd": {}}'))
        self.assertEqual(code, 2)
        self.assertIn("not an erg.v1.Event", err)

    # -- watch -------------------------------------------------------------------
    def test_watch_resumes_after_a_broken_stream(self):
        job = self.fake.add_job(state=S.RUNNING, steps=40, snapshot_every=10)
        self.fake.behaviour.watch_break_after = [3, 4]
        code, out, err = self.erg("watch", job.id)
        self.assertEqual(code, 0, err)
        self.assertEqual(out, "")
        after = [r.after_event_id for r in self.requests("WatchJob")]
        self.assertEqual(after, [0, 3, 7])  # no event missed or seen twice
        self.assertIn("lost ergd", err)
        self.assertIn("reconnected", err)
        self.assertIn("snapshot at step 40", err)
        self.assertIn('steered at step 10: {"sand":', err)
        self.assertIn("worker started on 1 rank(s)", err)
        self.assertEqual(err.count("snapshot at step 20"), 1)
        self.assertIn(f"{job.id} SUCCEEDED", err)

    def test_watch_exit_codes_follow_the_final_state(self):
        job = self.fake.add_job(state=S.RUNNING)
        self.fake.behaviour.watch_final = S.FAILED
        code, _, err = self.erg("watch", job.id)
        self.assertEqual(code, 1, err)
        self.assertIn("FAILED at step", err)
        self.assertIn("erg-worker exited with status 1", err)
        self.assertIn("  | erg: step 20: out of memory", err)
        job = self.fake.add_job(state=S.RUNNING)
        self.fake.behaviour.watch_final = S.CANCELLED
        code, _, err = self.erg("watch", job.id)
        self.assertEqual(code, 3, err)
        self.assertIn("CANCELLED", err)

    # -- fetch and preview ---------------------------------------------------------
    def out_dir(self):
        return os.path.join(self.tmp, "out")

    def test_fetch_latest(self):
        job = self.fake.add_job(steps=40, snapshot_every=10)
        code, out, err = self.erg("fetch", job.id, "--out", self.out_dir())
        self.assertEqual(code, 0, err)
        path = os.path.join(self.out_dir(), "step_00000040.h5")
        self.assertEqual(out, path + "\n")
        with open(path, "rb") as f:
            self.assertEqual(f.read(), fake_ergd.snapshot_bytes(job.id, 40))
        self.assertEqual(os.listdir(self.out_dir()), ["step_00000040.h5"])

    def test_fetch_resumes_a_cut_download(self):
        job = self.fake.add_job()
        self.fake.behaviour.snapshot_break_at = [150000]
        code, out, err = self.erg("fetch", job.id, "--step", "20", "--out", self.out_dir())
        self.assertEqual(code, 0, err)
        offsets = [r.offset for r in self.requests("StreamSnapshot")]
        self.assertEqual(offsets, [0, 2 * fake_ergd.CHUNK])
        self.assertIn(f"erg: resuming step_00000020.h5 at byte {2 * fake_ergd.CHUNK}", err)
        with open(os.path.join(self.out_dir(), "step_00000020.h5"), "rb") as f:
            self.assertEqual(f.read(), fake_ergd.snapshot_bytes(job.id, 20))

    def test_fetch_resumes_a_part_left_by_an_earlier_run(self):
        job = self.fake.add_job()
        data = fake_ergd.snapshot_bytes(job.id, 10)
        os.makedirs(self.out_dir())
        with open(os.path.join(self.out_dir(), "step_00000010.h5.part"), "wb") as f:
            f.write(data[:1000])
        code, out, err = self.erg("fetch", job.id, "--step", "10", "--out", self.out_dir())
        self.assertEqual(code, 0, err)
        self.assertIn("erg: resuming step_00000010.h5 at byte 1000", err)
        self.assertEqual([r.offset for r in self.requests("StreamSnapshot")], [1000])
        with open(os.path.join(self.out_dir(), "step_00000010.h5"), "rb") as f:
            self.assertEqual(f.read(), data)
        self.assertEqual(os.listdir(self.out_dir()), ["step_00000010.h5"])

    def test_fetch_checksum_mismatch_deletes_the_part(self):
        job = self.fake.add_job()
        self.fake.behaviour.wrong_sha = True
        code, out, err = self.erg("fetch", job.id, "--step", "10", "--out", self.out_dir())
        self.assertEqual(code, 1)
        self.assertEqual(out, "")
        self.assertIn("sha256 mismatch for step_00000010.h5", err)
        self.assertEqual(os.listdir(self.out_dir()), [])

    def test_fetch_all_skips_verified_files(self):
        job = self.fake.add_job(steps=40, snapshot_every=10)
        code, out, err = self.erg("fetch", job.id, "--all", "--out", self.out_dir())
        self.assertEqual(code, 0, err)
        self.assertEqual(len(out.splitlines()), 5)
        self.assertEqual(sorted(os.listdir(self.out_dir())),
                         ["step_%08d.h5" % s for s in range(0, 41, 10)])
        # Again: nothing downloaded but a changed file.
        with open(os.path.join(self.out_dir(), "step_00000030.h5"), "r+b") as f:
            f.write(b"XX")
        code, out, err = self.erg("fetch", job.id, "--all", "--out", self.out_dir())
        self.assertEqual(code, 0, err)
        self.assertEqual(err.count("already present and verified"), 4, err)
        self.assertIn("step_00000030.h5 differs", err)
        with open(os.path.join(self.out_dir(), "step_00000030.h5"), "rb") as f:
            self.assertEqual(hashlib.sha256(f.read()).hexdigest(),
                             hashlib.sha256(fake_ergd.snapshot_bytes(job.id, 30)).hexdigest())

    def test_fetch_errors(self):
        job = self.fake.add_job(state=S.QUEUED)
        code, _, err = self.erg("fetch", job.id, "--out", self.out_dir())
        self.assertEqual(code, 5)
        self.assertIn("has no snapshot yet", err)
        job = self.fake.add_job()
        code, _, err = self.erg("fetch", job.id, "--step", "7", "--out", self.out_dir())
        self.assertEqual(code, 5)
        self.assertEqual(err, "erg: fetch: NOT_FOUND: no snapshot at step 7\n")
        code, _, err = self.erg("fetch", job.id, "--step", "7", "--all", "--out", "x")
        self.assertEqual(code, 2)
        code, _, err = self.erg("fetch", job.id)
        self.assertEqual(code, 2)
        self.assertIn("missing --out DIR", err)

    def test_preview(self):
        job = self.fake.add_job()
        path = os.path.join(self.tmp, "p.png")
        code, out, err = self.erg("preview", job.id, "--out", path)
        self.assertEqual(code, 0, err)
        self.assertEqual(out, path + "\n")
        with open(path, "rb") as f:
            self.assertTrue(f.read().startswith(b"\x89PNG"))
        self.assertTrue(self.requests("GetPreview")[0].latest)


if __name__ == "__main__":
    unittest.main()

# SPDX-License-Identifier: Apache-2.0
"""ergd on a real one-node Slurm (munge, slurmctld, slurmd started in the
test's temp directory): a 2-rank job submitted and watched with the erg
CLI, a cancelled job, and a job whose walltime warning stops it (SIGTERM,
checkpoint) so that ergd submits it again and it resumes, ending bitwise
identical to an uninterrupted run. All daemons are stopped at the end."""
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
import unittest

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "server"))

from ergd_fixture import (ALICE, ERG, Ergd, ErgdTest, S, datasets, erg_run, md,  # noqa: E402
                          spec_json)
from slurm_cluster import SlurmCluster  # noqa: E402
from google.protobuf import json_format  # noqa: E402
from erg.v1 import worker_pb2 as W  # noqa: E402


def have_slurm():
    return os.geteuid() == 0 and all(shutil.which(c) for c in
                                     ("slurmctld", "slurmd", "munged", "sbatch"))


@unittest.skipUnless(have_slurm(), "needs root and Slurm (deploy/bootstrap.sh installs it)")
class Slurm(ErgdTest):
    @classmethod
    def setUpClass(cls):
        cls.tmpdir = tempfile.mkdtemp(prefix="ergd-slurm-", dir=os.environ.get("ERG_TEST_TMP"))
        cls.cluster = SlurmCluster(os.path.join(cls.tmpdir, "slurm")).start()
        os.environ["SLURM_CONF"] = cls.cluster.conf  # ergd's sbatch/squeue/scancel
        cls.ergd = Ergd(cls.tmpdir, ("--launcher", "slurm", "--slurm-time-limit", "10",
                                     "--slurm-signal", "50", "--cancel-grace", "20"))

    @classmethod
    def tearDownClass(cls):
        try:
            cls.ergd.stop()
        finally:
            cls.cluster.stop()
            if os.environ.get("ERG_KEEP_TEST_DIRS") != "1":
                shutil.rmtree(cls.tmpdir, ignore_errors=True)

    def erg(self, *args, check=True):
        r = subprocess.run([ERG] + list(args) + ["--server", self.ergd.addr, "--token", ALICE],
                           capture_output=True, text=True, timeout=600)
        if check:
            self.assertEqual(r.returncode, 0, r.stderr[-3000:] + self.cluster.logs())
        return r

    def job_file(self, d, name):
        path = os.path.join(self.tmpdir, name + ".json")
        with open(path, "w") as f:
            json.dump(d, f)
        return path

    def test_1_two_rank_job_submitted_and_watched_with_the_cli(self):
        d = spec_json(name="slurm-2", nx=96, ny=96, steps=60, snapshot_every=30)
        r = self.erg("submit", self.job_file(d, "two"), "--ranks", "2", "--threads", "1",
                     "--watch")
        job_id = r.stdout.strip().splitlines()[0]
        j = self.ergd.get(job_id)
        self.assertEqual(j.state, S.SUCCEEDED, j.failure_reason + j.log_tail)
        self.assertEqual(j.launcher, "slurm")
        self.assertTrue(re.fullmatch(r"\d+", j.launcher_id), j.launcher_id)
        self.assertEqual(self.cluster.squeue_state(j.launcher_id), "COMPLETED")
        with open(os.path.join(self.ergd.data, "jobs", job_id, "job.sbatch")) as f:
            script = f.read()
        self.assertIn("#SBATCH --ntasks=2", script)
        self.assertIn("#SBATCH --time=10", script)
        self.assertNotIn("--account", script)  # no value: the line is dropped
        out = os.path.join(self.tmpdir, "fetched")
        self.erg("fetch", job_id, "--out", out)
        ref = erg_run(d, os.path.join(self.tmpdir, "ref-two"), self.tmpdir)
        self.assertSameSnapshot(os.path.join(out, "snapshots", "step_00000060.h5"),
                                os.path.join(ref, "snapshots", "step_00000060.h5"))

    def test_2_cancel(self):
        d = spec_json(name="slurm-cancel", nx=128, ny=128, steps=100000, snapshot_every=1000,
                      checkpoint_every=100)
        job_id = self.erg("submit", self.job_file(d, "cancel"), "--threads", "1").stdout.strip()
        self.ergd.wait(job_id, until=lambda j: j.state == S.RUNNING and j.progress.step > 0,
                       timeout=120)
        self.erg("cancel", job_id)
        w = self.erg("watch", job_id, check=False)
        self.assertEqual(w.returncode, 3, w.stderr[-2000:])  # CANCELLED
        j = self.ergd.get(job_id)
        self.assertEqual(j.state, S.CANCELLED)
        self.assertIn(self.cluster.squeue_state(j.launcher_id), ("FAILED", "CANCELLED",
                                                                 "COMPLETED"))
        ckpts = os.listdir(os.path.join(self.ergd.data, "jobs", job_id, "run", "checkpoints"))
        self.assertTrue([c for c in ckpts if c.endswith(".h5")])

    def test_3_walltime_warning_checkpoints_and_the_job_resumes_bitwise(self):
        # A 1-minute walltime with the warning 50 s before its end: each
        # attempt is stopped after about 10 s and the job needs about 30 s.
        d = spec_json(name="slurm-walltime", nx=256, ny=256, steps=3000, snapshot_every=1000,
                      checkpoint_every=250)
        job_id = self.erg("submit", self.job_file(d, "walltime"), "--threads", "1",
                          "--time-limit", "1").stdout.strip()
        j = self.ergd.wait(job_id, timeout=900)
        self.assertEqual(j.state, S.SUCCEEDED, j.failure_reason + j.log_tail)
        self.assertGreaterEqual(j.attempts, 2)
        notes = [ev.message for ev in self.ergd.stub.WatchJob(
            S.WatchJobRequest(id=job_id), metadata=md(ALICE), timeout=60)
            if ev.HasField("message")]
        self.assertTrue(any("stopped by a signal" in n for n in notes), notes)
        self.assertTrue(any("resumed from the last checkpoint" in n for n in notes), notes)
        ref = erg_run(d, os.path.join(self.tmpdir, "ref-walltime"), self.tmpdir)
        for step in (1000, 2000, 3000):
            name = "step_%08d.h5" % step
            self.assertSameSnapshot(
                os.path.join(self.ergd.data, "jobs", job_id, "run", "snapshots", name),
                os.path.join(ref, "snapshots", name))

    def test_5_a_job_requeued_by_slurm_resumes_from_its_checkpoint(self):
        # Preemption or an admin's `scontrol requeue`: Slurm stops the batch
        # script (SIGTERM: the worker checkpoints) and runs it again, with
        # the same Slurm job id; the script resumes from the checkpoint.
        d = spec_json(name="slurm-requeue", nx=96, ny=96, steps=800, snapshot_every=400,
                      checkpoint_every=100)
        job_id = self.erg("submit", self.job_file(d, "requeue"), "--threads", "1").stdout.strip()
        j = self.ergd.wait(job_id, until=lambda j: j.state == S.RUNNING and j.progress.step >= 200,
                           timeout=120)
        subprocess.run(["scontrol", "requeue", j.launcher_id], check=True, env=self.cluster.env)
        # Slurm holds a requeued job back for a while (its begin time moves
        # about two minutes ahead); let it start again at once.
        t0 = time.time()
        while self.cluster.squeue_state(j.launcher_id) != "PENDING" and time.time() - t0 < 60:
            time.sleep(0.2)
        subprocess.run(["scontrol", "update", "JobId=" + j.launcher_id, "StartTime=now"],
                       check=True, env=self.cluster.env)
        done = self.ergd.wait(job_id, timeout=600)
        self.assertEqual(done.state, S.SUCCEEDED, done.failure_reason + done.log_tail)
        # The job's notes hold every Slurm state ergd saw ("slurm job N:
        # STATE"), which tells why it would have submitted a new job; read
        # only when it did.
        notes = [] if done.launcher_id == j.launcher_id else [
            ev.message for ev in self.ergd.stub.WatchJob(
                S.WatchJobRequest(id=job_id), metadata=md(ALICE), timeout=60)
            if ev.HasField("message")]
        self.assertEqual(done.launcher_id, j.launcher_id, notes)  # the same Slurm job, run twice
        # Two starts in the progress file: the second at the checkpoint's step.
        with open(os.path.join(self.ergd.data, "jobs", job_id, "progress-1.jsonl")) as f:
            events = [json_format.Parse(line, W.WorkerEvent()) for line in f]
            starts = [e.step for e in events if e.HasField("start")]
        self.assertEqual(len(starts), 2, starts)
        self.assertEqual(starts[0], 0)
        self.assertGreaterEqual(starts[1], 200)
        ref = erg_run(d, os.path.join(self.tmpdir, "ref-requeue"), self.tmpdir)
        name = "step_00000800.h5"
        self.assertSameSnapshot(os.path.join(self.ergd.data, "jobs", job_id, "run", "snapshots",
                                             name), os.path.join(ref, "snapshots", name))

    def test_4_erg_run_sbatch_without_the_server(self):
        d = spec_json(name="sbatch", nx=96, ny=96, steps=40, snapshot_every=20)
        out = os.path.join(self.tmpdir, "sbatch-out")
        script = os.path.join(os.path.dirname(__file__), "..", "..", "deploy", "slurm",
                              "erg-run.sbatch")
        env = dict(self.cluster.env, ERG_BIN=os.path.dirname(ERG))
        # The script asks for its walltime warning 300 s before the end: with
        # a limit of 5 minutes that is at once (Slurm sends it within a
        # minute), and the worker stops at a checkpoint instead of finishing
        # whenever the machine is slow. The warning is tested in test_3.
        r = subprocess.run(["sbatch", "--parsable", "--ntasks=2", "--cpus-per-task=1",
                            "--time=10", "--signal=B:TERM@60",
                            "--output=" + os.path.join(self.tmpdir, "sbatch-%j.out"),
                            script, self.job_file(d, "sbatch"), out],
                           capture_output=True, text=True, env=env, check=True)
        slurm_id = r.stdout.strip().split(";")[0]
        t0 = time.time()
        while self.cluster.squeue_state(slurm_id) not in ("COMPLETED", "FAILED", "CANCELLED",
                                                          "TIMEOUT"):
            self.assertLess(time.time() - t0, 300, self.cluster.logs())
            time.sleep(0.5)
        with open(os.path.join(self.tmpdir, "sbatch-%s.out" % slurm_id)) as f:
            log = f.read()
        self.assertEqual(self.cluster.squeue_state(slurm_id), "COMPLETED", log)
        self.assertIn("worker exited with 0", log)
        ref = erg_run(d, os.path.join(self.tmpdir, "ref-sbatch"), self.tmpdir)
        self.assertSameSnapshot(os.path.join(out, "snapshots", "step_00000040.h5"),
                                os.path.join(ref, "snapshots", "step_00000040.h5"))


if __name__ == "__main__":
    unittest.main()

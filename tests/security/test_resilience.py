# SPDX-License-Identifier: Apache-2.0
"""ergd against failing workers and unfit jobs, for real on loopback.

- A worker SIGKILLed mid-job is retried from its newest intact checkpoint
  (ergd --worker-retries), each retry and its reason in the job's events,
  and the job ends bitwise equal to an uninterrupted local run.
- With retries off, the job ends FAILED; `erg resume ID` (the ResumeJob RPC)
  continues it from its checkpoint, again bitwise; resuming a job that is
  not FAILED, or another tenant's, is refused.
- A job whose memory estimate exceeds what ergd may use is refused at
  submission, naming the estimate and the limit; threads per rank are capped
  at the cores.
"""
import os
import signal
import subprocess
import sys
import unittest

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "server"))

import grpc  # noqa: E402

from ergd_fixture import (ALICE, BOB, ERG, ErgdTest, S, erg_run, md, spec_json,  # noqa: E402
                          terminal)

# Long enough to be caught running on a 2-core machine with one thread.
LONG = dict(nx=96, ny=96, steps=1200, snapshot_every=600, checkpoint_every=100)


def running_past(step):
    return lambda j: j.state == S.RUNNING and j.progress.step >= step or terminal(j.state)


def notes(e, job_id, token=ALICE):
    return [ev.message for ev in e.stub.WatchJob(S.WatchJobRequest(id=job_id), metadata=md(token),
                                                 timeout=120) if ev.HasField("message")]


def kill_worker(job):
    os.kill(int(job.launcher_id), signal.SIGKILL)


class WorkerRetry(ErgdTest):
    extra_args = ("--worker-retries", "2")

    def test_a_killed_worker_resumes_from_its_checkpoint_bitwise(self):
        e = self.ergd
        d = spec_json(name="retried", **LONG)
        job = e.submit(d)
        j = e.wait(job.id, until=running_past(250))
        self.assertEqual(j.state, S.RUNNING, j.failure_reason)
        kill_worker(j)
        done = e.wait(job.id, timeout=300)
        self.assertEqual(done.state, S.SUCCEEDED, done.failure_reason + done.log_tail)
        self.assertEqual(done.attempts, 2)
        self.assertEqual(done.worker_retries, 1)
        n = notes(e, job.id)
        died = [m for m in n if "the worker died" in m]
        self.assertEqual(len(died), 1, n)
        self.assertIn("killed by signal 9", died[0])
        self.assertIn("retry 1 of 2", died[0])
        resumed = [m for m in n if "resumed from its checkpoint of step" in m]
        self.assertEqual(len(resumed), 1, n)
        self.assertIn("attempt 2", resumed[0])
        ref = erg_run(d, os.path.join(self.tmpdir, "ref-retried"), self.tmpdir)
        for step in (600, 1200):
            self.assertSameSnapshot(
                os.path.join(e.data, "jobs", job.id, "run", "snapshots", "step_%08d.h5" % step),
                os.path.join(ref, "snapshots", "step_%08d.h5" % step))


class ResumeFailed(ErgdTest):
    extra_args = ("--worker-retries", "0")

    def resume(self, job_id, token=ALICE):
        return self.ergd.stub.ResumeJob(S.ResumeJobRequest(id=job_id), metadata=md(token),
                                        timeout=30)

    def test_erg_resume_continues_a_failed_job_from_its_checkpoint(self):
        e = self.ergd
        d = spec_json(name="resumable", **LONG)
        job = e.submit(d)
        j = e.wait(job.id, until=running_past(250))
        self.assertEqual(j.state, S.RUNNING, j.failure_reason)
        kill_worker(j)
        failed = e.wait(job.id, timeout=120)
        self.assertEqual(failed.state, S.FAILED)
        self.assertIn("killed by signal 9", failed.failure_reason)
        self.assertIn("erg resume " + job.id, failed.failure_reason)
        # Another tenant's job does not exist for them.
        with self.assertRaises(grpc.RpcError) as err:
            self.resume(job.id, token=BOB)
        self.assertEqual(err.exception.code(), grpc.StatusCode.NOT_FOUND)
        # The CLI, against the real ergd.
        env = dict(os.environ, ERG_SERVER=e.addr, ERG_TOKEN=ALICE)
        r = subprocess.run([ERG, "resume", job.id], env=env, capture_output=True, text=True,
                           timeout=60)
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertEqual(r.stdout.strip(), "QUEUED")
        self.assertIn("newest intact checkpoint", r.stderr)
        done = e.wait(job.id, timeout=300)
        self.assertEqual(done.state, S.SUCCEEDED, done.failure_reason + done.log_tail)
        self.assertEqual(done.attempts, 2)
        self.assertEqual(done.failure_reason, "")
        n = notes(e, job.id)
        self.assertTrue(any("resumed by its tenant (erg resume)" in m for m in n), n)
        self.assertTrue(any("resumed from its checkpoint of step" in m for m in n), n)
        ref = erg_run(d, os.path.join(self.tmpdir, "ref-resumed"), self.tmpdir)
        for step in (600, 1200):
            self.assertSameSnapshot(
                os.path.join(e.data, "jobs", job.id, "run", "snapshots", "step_%08d.h5" % step),
                os.path.join(ref, "snapshots", "step_%08d.h5" % step))
        # A job that is not FAILED is not resumed.
        with self.assertRaises(grpc.RpcError) as err:
            self.resume(job.id)
        self.assertEqual(err.exception.code(), grpc.StatusCode.FAILED_PRECONDITION)
        self.assertIn("SUCCEEDED", err.exception.details())

    def test_a_failed_job_without_a_checkpoint_is_not_resumed(self):
        e = self.ergd
        job = e.submit(spec_json(name="nocheckpoint", nx=96, ny=96, steps=1200,
                                 snapshot_every=0, checkpoint_every=0))
        j = e.wait(job.id, until=running_past(20))
        kill_worker(j)
        self.assertEqual(e.wait(job.id, timeout=120).state, S.FAILED)
        with self.assertRaises(grpc.RpcError) as err:
            self.resume(job.id)
        self.assertEqual(err.exception.code(), grpc.StatusCode.FAILED_PRECONDITION)
        self.assertIn("no checkpoint", err.exception.details())


class Limits(ErgdTest):
    extra_args = ("--max-job-memory", str(1 << 30))

    def test_a_job_too_large_for_the_memory_is_refused_naming_the_estimate(self):
        d = spec_json(name="huge", nx=1048576, ny=1048576, steps=1000000000)
        with self.assertRaises(grpc.RpcError) as err:
            self.ergd.submit(d)
        self.assertEqual(err.exception.code(), grpc.StatusCode.RESOURCE_EXHAUSTED)
        m = err.exception.details()
        self.assertIn("memory estimate", m)
        self.assertIn("100 bytes per cell x 1099511627776 cells", m)
        self.assertIn("--max-job-memory", m)
        # 3200 x 3200 x 100 B = 0.95 GiB fits in 1 GiB; 3300 x 3300 does not.
        ok = self.ergd.submit(spec_json(name="fits", nx=3200, ny=3200, steps=1))
        self.ergd.stub.CancelJob(S.CancelJobRequest(id=ok.id), metadata=md(ALICE), timeout=30)
        with self.assertRaises(grpc.RpcError) as err:
            self.ergd.submit(spec_json(name="toobig", nx=3300, ny=3300, steps=1))
        self.assertEqual(err.exception.code(), grpc.StatusCode.RESOURCE_EXHAUSTED)

    def test_threads_per_rank_are_capped_at_the_cores(self):
        cores = os.cpu_count()
        with self.assertRaises(grpc.RpcError) as err:
            self.ergd.submit(spec_json(name="threads", steps=1), threads=1024)
        self.assertEqual(err.exception.code(), grpc.StatusCode.INVALID_ARGUMENT)
        m = err.exception.details()
        self.assertIn("resources.threads_per_rank: 1024 is out of range [0, %d]" % cores, m)
        ok = self.ergd.submit(spec_json(name="threads-ok", steps=1), threads=cores)
        self.assertEqual(self.ergd.wait(ok.id).state, S.SUCCEEDED)


if __name__ == "__main__":
    unittest.main()

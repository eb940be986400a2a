# SPDX-License-Identifier: Apache-2.0
"""Jobs through their lives: the queue (bounded, fair across tenants),
cancel (queued and running), steering a running job and re-running its
recorded spec to the same bits, ergd SIGKILLed mid-job and restarted, and
the limits (tenant cells x steps, per-job disk)."""
import json
import os
import time
import unittest

import grpc
from google.protobuf import json_format

from ergd_fixture import (ALICE, BOB, CAROL, Ergd, ErgdTest, J, S, erg_run, md, spec_json,
                          terminal)

# Long enough to be caught running on this 2-core machine (a few seconds).
LONG = dict(nx=128, ny=128, steps=3000, snapshot_every=500, checkpoint_every=100)


def running_past(step):
    return lambda j: j.state == S.RUNNING and j.progress.step >= step or terminal(j.state)


class Queue(ErgdTest):
    extra_args = ("--max-running", "1", "--tenant-cell-steps", str(128 * 128 * 3000 * 3 + 1))

    def test_bounded_fair_queue_cancel_and_tenant_limit(self):
        e = self.ergd
        a1 = e.submit(spec_json(name="a1", **LONG))
        a2 = e.submit(spec_json(name="a2", **LONG))
        a3 = e.submit(spec_json(name="a3", **LONG))
        b1 = e.submit(spec_json(name="b1", steps=20), token=BOB)
        e.wait(a1.id, until=running_past(1))
        time.sleep(0.5)
        # One at a time: the rest wait.
        self.assertEqual([e.get(j.id).state for j in (a2, a3)], [S.QUEUED, S.QUEUED])
        self.assertEqual(e.get(b1.id, BOB).state, S.QUEUED)
        # Alice's queued work is 3 long jobs: a fourth is over her limit, with
        # a message naming it; Bob is not affected.
        with self.assertRaises(grpc.RpcError) as err:
            e.submit(spec_json(name="a4", **LONG))
        self.assertEqual(err.exception.code(), grpc.StatusCode.RESOURCE_EXHAUSTED)
        self.assertIn("--tenant-cell-steps", err.exception.details())
        # Cancel a queued job: at once, never started.
        c = e.stub.CancelJob(S.CancelJobRequest(id=a3.id), metadata=md(ALICE), timeout=10)
        self.assertEqual(c.state, S.CANCELLED)
        self.assertEqual(e.get(a3.id).attempts, 0)
        # Cancel the running one: the worker checkpoints and stops.
        e.stub.CancelJob(S.CancelJobRequest(id=a1.id), metadata=md(ALICE), timeout=10)
        j = e.wait(a1.id, timeout=60)
        self.assertEqual(j.state, S.CANCELLED)
        self.assertLess(j.progress.step, 3000)
        with open(e.log) as f:
            self.assertRegex(f.read(), r"ergd: job %s \(tenant alice\): cancelled at step \d+\n"
                             % a1.id)
        ckpts = os.listdir(os.path.join(e.data, "jobs", a1.id, "run", "checkpoints"))
        self.assertTrue([c for c in ckpts if c.endswith(".h5")])
        # Fair: Bob's job (submitted after a2) starts before Alice's second.
        b = e.wait(b1.id, BOB, timeout=60)
        self.assertEqual(b.state, S.SUCCEEDED)
        a2now = e.get(a2.id)
        self.assertTrue(a2now.started_unix_ms == 0 or a2now.started_unix_ms >= b.started_unix_ms,
                        (a2now.started_unix_ms, b.started_unix_ms))
        e.stub.CancelJob(S.CancelJobRequest(id=a2.id), metadata=md(ALICE), timeout=10)
        self.assertEqual(e.wait(a2.id, timeout=60).state, S.CANCELLED)
        # The watch of a cancelled job ends with CANCELLED.
        last = list(e.stub.WatchJob(S.WatchJobRequest(id=a1.id), metadata=md(ALICE),
                                    timeout=30))[-1]
        self.assertEqual(last.state_changed, S.CANCELLED)


class Steering(ErgdTest):
    def test_steer_a_running_job_and_rerun_its_recorded_spec(self):
        e = self.ergd
        d = spec_json(name="steered", nx=96, ny=96, steps=1500, snapshot_every=500,
                      checkpoint_every=500)
        job = e.submit(d, token=CAROL)
        e.wait(job.id, CAROL, until=running_past(50))
        sand = J.Event(sand=J.Brush(x_m=48, y_m=48, radius_m=12, falloff_m=4, height=2.0))
        wind = J.Event(wind=J.WindRegime(constant=J.ConstantWind(speed_mps=7, direction_deg=110)))
        r = e.stub.SteerJob(S.SteerJobRequest(id=job.id, events=[sand, wind]),
                            metadata=md(CAROL), timeout=60)
        self.assertEqual(len(r.applied), 2)
        step = r.applied[0].step
        self.assertGreaterEqual(step, 50)
        self.assertEqual(r.applied[1].step, step)
        self.assertAlmostEqual(r.applied[0].sand.height, 2.0)
        # A bad event is refused, naming the field; the job runs on.
        bad = J.Event(vegetation=J.VegetationRegion(x_m=1, y_m=1, radius_m=3, density=5))
        with self.assertRaises(grpc.RpcError) as err:
            e.stub.SteerJob(S.SteerJobRequest(id=job.id, events=[bad]), metadata=md(CAROL),
                            timeout=60)
        self.assertEqual(err.exception.code(), grpc.StatusCode.INVALID_ARGUMENT)
        self.assertIn("density", err.exception.details())
        done = e.wait(job.id, CAROL, timeout=300)
        self.assertEqual(done.state, S.SUCCEEDED, done.failure_reason + done.log_tail)
        # The recorded spec holds the events with their step ...
        steered = [ev for ev in done.spec.events]
        self.assertEqual([ev.step for ev in steered], [step, step])
        self.assertTrue(steered[0].HasField("sand") and steered[1].HasField("wind"))
        # ... and re-running it (locally, from its JSON) gives the same bits.
        recorded = json.loads(json_format.MessageToJson(done.spec, preserving_proto_field_name=True))
        ref = erg_run(recorded, os.path.join(self.tmpdir, "rerun"), self.tmpdir)
        got = os.path.join(e.data, "jobs", job.id, "run", "snapshots", "step_00001500.h5")
        self.assertSameSnapshot(got, os.path.join(ref, "snapshots", "step_00001500.h5"))
        # ... and differs from the unsteered run (the steering did something).
        plain = erg_run(d, os.path.join(self.tmpdir, "plain"), self.tmpdir)
        from ergd_fixture import datasets
        import numpy as np
        self.assertFalse(np.array_equal(
            datasets(got)["sand"], datasets(os.path.join(plain, "snapshots",
                                                         "step_00001500.h5"))["sand"]))

    def test_only_running_jobs_are_steered(self):
        job = self.ergd.submit(spec_json(steps=3), token=CAROL)
        self.ergd.wait(job.id, CAROL)
        with self.assertRaises(grpc.RpcError) as err:
            self.ergd.stub.SteerJob(S.SteerJobRequest(id=job.id, events=[J.Event(
                sand=J.Brush(x_m=1, y_m=1, radius_m=2, height=1))]), metadata=md(CAROL),
                timeout=30)
        self.assertEqual(err.exception.code(), grpc.StatusCode.FAILED_PRECONDITION)


class Restart(ErgdTest):
    def test_ergd_killed_mid_job_loses_nothing_and_the_job_resumes_bitwise(self):
        e = self.ergd
        d = spec_json(name="survivor", nx=96, ny=96, steps=2000, snapshot_every=1000,
                      checkpoint_every=100)
        job = e.submit(d, ranks=2)
        queued = e.submit(spec_json(name="waiting", steps=10), token=BOB)
        e.wait(job.id, until=running_past(300))
        seen = [ev.id for ev in e.stub.WatchJob(S.WatchJobRequest(id=queued.id),
                                                metadata=md(BOB), timeout=60)]
        e.kill()  # SIGKILL: no chance to clean up
        time.sleep(1.0)
        e.start()  # same data directory and ports
        j = e.get(job.id)  # still known
        self.assertIn(j.state, (S.QUEUED, S.RUNNING, S.SUCCEEDED))
        done = e.wait(job.id, timeout=300)
        self.assertEqual(done.state, S.SUCCEEDED, done.failure_reason + done.log_tail)
        self.assertEqual(done.attempts, 2)
        notes = [ev.message for ev in e.stub.WatchJob(S.WatchJobRequest(id=job.id),
                                                      metadata=md(ALICE), timeout=60)
                 if ev.HasField("message")]
        self.assertTrue(any("resume" in n for n in notes), notes)
        # The other tenant's finished job and its events are intact.
        self.assertEqual(e.get(queued.id, BOB).state, S.SUCCEEDED)
        again = [ev.id for ev in e.stub.WatchJob(S.WatchJobRequest(id=queued.id),
                                                 metadata=md(BOB), timeout=60)]
        self.assertEqual(again, seen)
        # Bitwise the same as one uninterrupted local run.
        ref = erg_run(d, os.path.join(self.tmpdir, "ref"), self.tmpdir)
        for step in (1000, 2000):
            name = "step_%08d.h5" % step
            self.assertSameSnapshot(os.path.join(e.data, "jobs", job.id, "run", "snapshots", name),
                                    os.path.join(ref, "snapshots", name))


class DiskLimit(ErgdTest):
    extra_args = ("--max-job-disk", "300000")

    def test_a_job_over_its_disk_limit_fails_with_a_clear_reason(self):
        job = self.ergd.submit(spec_json(name="hog", nx=128, ny=128, steps=100000,
                                         snapshot_every=1, checkpoint_every=0))
        j = self.ergd.wait(job.id, timeout=120)
        self.assertEqual(j.state, S.FAILED)
        self.assertIn("--max-job-disk", j.failure_reason)
        self.assertIn("run.snapshot_every", j.failure_reason)
        self.assertTrue(j.log_tail)  # the worker's last words
        # ergd's log says why, on the job's line.
        with open(self.ergd.log) as f:
            self.assertRegex(f.read(), r"ergd: job %s \(tenant alice\): failed at step \d+: "
                             r"[^\n]*--max-job-disk" % job.id)


class ForcedCancel(ErgdTest):
    extra_args = ("--cancel-grace", "0.3")

    def test_a_worker_that_outlives_the_grace_period_is_killed(self):
        import h5py
        e = self.ergd
        # Big, slow steps (768^2 on one thread): the SIGTERM waits for the end
        # of a step, the grace period does not.
        job = e.submit(spec_json(name="slow", nx=768, ny=768, steps=100000, snapshot_every=0,
                                 checkpoint_every=1))
        e.wait(job.id, until=running_past(2), timeout=120)
        t0 = time.time()
        e.stub.CancelJob(S.CancelJobRequest(id=job.id), metadata=md(ALICE), timeout=10)
        j = e.wait(job.id, timeout=60)
        self.assertEqual(j.state, S.CANCELLED)
        self.assertLess(time.time() - t0, 30)
        # Killed mid-write or not, every checkpoint file there is complete.
        d = os.path.join(e.data, "jobs", job.id, "run", "checkpoints")
        names = [n for n in os.listdir(d) if n.endswith(".h5")]
        self.assertTrue(names)
        for n in names:
            with h5py.File(os.path.join(d, n), "r") as f:
                self.assertEqual(f["sand_units"].shape, (768, 768))


if __name__ == "__main__":
    unittest.main()

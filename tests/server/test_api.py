# SPDX-License-Identifier: Apache-2.0
"""ergd's API contract: authentication, tenants, validation, limits,
idempotency, paging, health and reflection, a Python client built from
proto/ submitting, watching and streaming."""
import os
import time
import unittest

import grpc

from ergd_fixture import (ALICE, BOB, ErgdTest, J, S, erg_run, md, sha256, spec_json, spec_of,
                          terminal)


class Api(ErgdTest):
    def test_python_client_submits_watches_and_streams(self):
        d = spec_json(steps=40, snapshot_every=10, name="python-client")
        job = self.ergd.submit(d)
        self.assertTrue(job.id.startswith("j-"))
        self.assertEqual(job.state, S.QUEUED)
        self.assertEqual(job.tenant, "alice")
        kinds, last_step, ids = [], -1, []
        for ev in self.ergd.stub.WatchJob(S.WatchJobRequest(id=job.id), metadata=md(ALICE),
                                          timeout=120):
            ids.append(ev.id)
            kinds.append(ev.WhichOneof("kind"))
            if ev.HasField("progress"):
                self.assertGreaterEqual(ev.progress.step, last_step)
                last_step = ev.progress.step
        self.assertEqual(ids, sorted(ids))
        self.assertIn("snapshot_step", kinds)
        self.assertEqual(kinds[-1], "state_changed")
        j = self.ergd.get(job.id)
        self.assertEqual(j.state, S.SUCCEEDED, j.failure_reason + j.log_tail)
        self.assertEqual(list(j.snapshot_steps), [0, 10, 20, 30, 40])
        self.assertEqual(j.progress.step, 40)
        self.assertEqual(j.attempts, 1)
        self.assertGreater(j.disk_bytes, 0)
        # The stream resumes after any event id and misses nothing.
        tail = [ev.id for ev in self.ergd.stub.WatchJob(
            S.WatchJobRequest(id=job.id, after_event_id=ids[2]), metadata=md(ALICE), timeout=30)]
        self.assertEqual(tail, ids[3:])
        # The snapshot as streamed equals, bit for bit, an `erg run` of the same spec.
        first, data = self.ergd.fetch_bytes(job.id)
        self.assertEqual(first.step, 40)
        self.assertEqual(first.size, len(data))
        self.assertEqual(first.sha256, sha256(data))
        self.assertEqual(first.name, "step_00000040.h5")
        got = os.path.join(self.tmpdir, "streamed.h5")
        with open(got, "wb") as f:
            f.write(data)
        ref = erg_run(d, os.path.join(self.tmpdir, "ref"), self.tmpdir)
        self.assertSameSnapshot(got, os.path.join(ref, "snapshots", "step_00000040.h5"))
        # A byte offset resumes the stream.
        first2, rest = self.ergd.fetch_bytes(job.id, offset=len(data) - 1000)
        self.assertEqual(rest, data[-1000:])
        self.assertEqual(first2.sha256, first.sha256)
        # A given step, and a step that does not exist.
        f10, d10 = self.ergd.fetch_bytes(job.id, step=10)
        self.assertEqual(f10.step, 10)
        with self.assertRaises(grpc.RpcError) as e:
            self.ergd.fetch_bytes(job.id, step=15)
        self.assertEqual(e.exception.code(), grpc.StatusCode.NOT_FOUND)
        self.assertIn("10, 20", e.exception.details())
        with self.assertRaises(grpc.RpcError) as e:
            self.ergd.fetch_bytes(job.id, offset=len(data) + 1)
        self.assertEqual(e.exception.code(), grpc.StatusCode.OUT_OF_RANGE)
        # The preview is a PNG.
        p = self.ergd.stub.GetPreview(S.GetPreviewRequest(id=job.id, latest=True),
                                      metadata=md(ALICE), timeout=30)
        self.assertEqual(p.step, 40)
        self.assertEqual(p.png[:8], b"\x89PNG\r\n\x1a\n")

    def test_every_call_needs_a_known_token(self):
        stub = self.ergd.stub
        for metadata in ([], [("authorization", "Bearer nope-nope-nope-nope")],
                         [("authorization", ALICE)]):  # no "Bearer "
            with self.assertRaises(grpc.RpcError) as e:
                stub.ListJobs(S.ListJobsRequest(), metadata=metadata, timeout=10)
            self.assertEqual(e.exception.code(), grpc.StatusCode.UNAUTHENTICATED)
            with self.assertRaises(grpc.RpcError) as e:
                stub.SubmitJob(S.SubmitJobRequest(spec=spec_of(spec_json())), metadata=metadata,
                               timeout=10)
            self.assertEqual(e.exception.code(), grpc.StatusCode.UNAUTHENTICATED)
            with self.assertRaises(grpc.RpcError) as e:
                list(stub.WatchJob(S.WatchJobRequest(id="j-0"), metadata=metadata, timeout=10))
            self.assertEqual(e.exception.code(), grpc.StatusCode.UNAUTHENTICATED)

    def test_a_tenant_never_sees_another_tenants_job(self):
        job = self.ergd.submit(spec_json(steps=5, name="alice-only"))
        calls = [
            lambda t: self.ergd.get(job.id, t),
            lambda t: self.ergd.stub.CancelJob(S.CancelJobRequest(id=job.id), metadata=md(t),
                                               timeout=10),
            lambda t: list(self.ergd.stub.WatchJob(S.WatchJobRequest(id=job.id), metadata=md(t),
                                                   timeout=10)),
            lambda t: self.ergd.fetch_bytes(job.id, t),
            lambda t: self.ergd.stub.GetPreview(S.GetPreviewRequest(id=job.id, latest=True),
                                                metadata=md(t), timeout=10),
            lambda t: self.ergd.stub.SteerJob(S.SteerJobRequest(id=job.id, events=[J.Event()]),
                                              metadata=md(t), timeout=10),
        ]
        for call in calls:
            with self.assertRaises(grpc.RpcError) as e:
                call(BOB)
            self.assertEqual(e.exception.code(), grpc.StatusCode.NOT_FOUND)
            # ... exactly like an id that does not exist
            self.assertNotIn("alice", e.exception.details())
        ids = [j.id for j in self.ergd.stub.ListJobs(S.ListJobsRequest(page_size=1000),
                                                      metadata=md(BOB), timeout=10).jobs]
        self.assertNotIn(job.id, ids)
        self.ergd.wait(job.id)

    def test_a_spec_with_six_mistakes_gets_six_lines(self):
        # The mistakes of erg check's test (tests/job), as a binary client can
        # make them: fields this ergd does not know, an enum number outside the
        # schema, two values out of range and a cross-field rule.
        d = spec_json()
        d["domain"]["nx"] = -5
        d["wind"]["constant"]["direction_deg"] = 400
        d["model"]["max_hop_m"] = 40
        spec = spec_of(d)
        spec.MergeFromString(b"\xba\x3e\x03red")   # field 999 (a string)
        spec.run.MergeFromString(b"\x98\x06\x01")  # run's field 99 (a varint)
        spec.transport = 7
        with self.assertRaises(grpc.RpcError) as e:
            self.ergd.stub.SubmitJob(S.SubmitJobRequest(spec=spec), metadata=md(ALICE),
                                     timeout=30)
        self.assertEqual(e.exception.code(), grpc.StatusCode.INVALID_ARGUMENT)
        lines = e.exception.details().split("\n")
        self.assertEqual(len(lines), 6, lines)
        want = ["spec: unknown field number 999", "run: unknown field number 99",
                "transport = 7 is not a known value; allowed EXPECTED, STOCHASTIC",
                "domain.nx = -5 is out of range; allowed [8, 1048576] cells",
                "wind.constant.direction_deg = 400 is out of range",
                "model.max_hop_m = 40 m"]
        for w in want:
            self.assertTrue(any(w in line for line in lines), (w, lines))

    def test_bad_specs_are_invalid_argument_naming_the_field(self):
        bad = spec_json()
        bad["domain"]["nx"] = 3
        bad["model"]["repose_deg"] = 95
        with self.assertRaises(grpc.RpcError) as e:
            self.ergd.submit(bad)
        self.assertEqual(e.exception.code(), grpc.StatusCode.INVALID_ARGUMENT)
        self.assertIn("domain.nx", e.exception.details())
        self.assertIn("model.repose_deg", e.exception.details())
        self.assertIn("[1, 89]", e.exception.details())
        # Map files are not read on a tenant's behalf (every map field:
        # tests/security/test_maps.py).
        m = spec_json()
        m["layers"]["bedrock"] = {"map": {"path": "/etc/passwd"}}
        with self.assertRaises(grpc.RpcError) as e:
            self.ergd.submit(m)
        self.assertEqual(e.exception.code(), grpc.StatusCode.PERMISSION_DENIED)
        self.assertIn("layers.bedrock.map", e.exception.details())
        # Resources are validated too.
        with self.assertRaises(grpc.RpcError) as e:
            self.ergd.submit(spec_json(), ranks=100000)
        self.assertIn("resources.ranks", e.exception.details())
        # A rank count the worker could not tile the domain with is refused
        # at submission, with the worker's own reason.
        wide = spec_json(nx=64, ny=64)
        wide["model"]["avalanche_iterations"] = 50
        with self.assertRaises(grpc.RpcError) as e:
            self.ergd.submit(wide, ranks=2)
        self.assertEqual(e.exception.code(), grpc.StatusCode.INVALID_ARGUMENT)
        self.assertIn("resources.ranks: cannot split 64 x 64 cells into 2 tiles",
                      e.exception.details())
        # Slurm requests are checked whatever the launcher.
        req = S.SubmitJobRequest(spec=spec_of(spec_json()), resources=S.Resources(
            partition="debug; rm -rf /", time_limit_minutes=-5))
        with self.assertRaises(grpc.RpcError) as e:
            self.ergd.stub.SubmitJob(req, metadata=md(ALICE), timeout=10)
        self.assertIn("resources.partition", e.exception.details())
        self.assertIn("resources.time_limit_minutes", e.exception.details())
        # Nothing was queued by any of them.
        self.assertFalse([j for j in self.ergd.stub.ListJobs(
            S.ListJobsRequest(page_size=1000), metadata=md(ALICE), timeout=10).jobs
            if j.state == S.FAILED])

    def test_message_and_spec_sizes_are_bounded(self):
        d = spec_json()
        # 300 KiB of name: over ergd's spec limit (256 KiB), under gRPC's 4 MiB.
        d["name"] = "x" * (300 * 1024)
        with self.assertRaises(grpc.RpcError) as e:
            self.ergd.submit(d)
        # Size errors are RESOURCE_EXHAUSTED, whichever limit says no.
        self.assertEqual(e.exception.code(), grpc.StatusCode.RESOURCE_EXHAUSTED)
        self.assertIn("spec:", e.exception.details())
        d["name"] = "x" * (5 * 1024 * 1024)  # over the 4 MiB message limit
        with self.assertRaises(grpc.RpcError) as e:
            self.ergd.submit(d)
        self.assertEqual(e.exception.code(), grpc.StatusCode.RESOURCE_EXHAUSTED)
        # ergd is still serving.
        self.ergd.stub.ListJobs(S.ListJobsRequest(), metadata=md(ALICE), timeout=10)

    def test_the_same_idempotency_key_returns_the_same_job(self):
        a = self.ergd.submit(spec_json(steps=5, name="idem"), key="bake-42")
        b = self.ergd.submit(spec_json(steps=7, name="other"), key="bake-42")
        self.assertEqual(a.id, b.id)
        self.assertEqual(b.spec.name, "idem")
        c = self.ergd.submit(spec_json(steps=5, name="idem"), key="bake-42", token=BOB)
        self.assertNotEqual(c.id, a.id)  # keys are per tenant
        self.ergd.wait(a.id)
        self.ergd.wait(c.id, BOB)

    def test_coarse_cells_are_accepted_with_a_warning_naming_the_length(self):
        # 4 m cells: the 10 m shadow is under 4 cells (sim/resolution.h).
        coarse = self.ergd.submit(spec_json(nx=32, ny=32, steps=2, snapshot_every=0,
                                            checkpoint_every=0, name="coarse",
                                            domain={"nx": 32, "ny": 32, "cell_size_m": 4}))
        self.assertEqual(len(coarse.warnings), 1, list(coarse.warnings))
        self.assertIn("model.shadow_radius_m = 10 m", coarse.warnings[0])
        self.assertIn("4 cells of 4 m (domain.cell_size_m)", coarse.warnings[0])
        self.assertEqual(list(self.ergd.get(coarse.id).warnings), list(coarse.warnings))
        fine = self.ergd.submit(spec_json(steps=2, snapshot_every=0, checkpoint_every=0,
                                          name="fine"))
        self.assertEqual(list(fine.warnings), [])
        self.ergd.wait(coarse.id)
        self.ergd.wait(fine.id)

    def test_list_jobs_pages_and_filters(self):
        ids = [self.ergd.submit(spec_json(steps=2, snapshot_every=0, checkpoint_every=0,
                                          name="page-%d" % i), token=BOB).id for i in range(7)]
        for i in ids:
            self.ergd.wait(i, BOB)
        seen, token = [], ""
        while True:
            r = self.ergd.stub.ListJobs(S.ListJobsRequest(page_size=3, page_token=token),
                                        metadata=md(BOB), timeout=10)
            self.assertLessEqual(len(r.jobs), 3)
            seen += [j.id for j in r.jobs]
            token = r.next_page_token
            if not token:
                break
        self.assertEqual([i for i in seen if i in ids], list(reversed(ids)))  # newest first
        done = self.ergd.stub.ListJobs(S.ListJobsRequest(page_size=1000, state=S.SUCCEEDED),
                                       metadata=md(BOB), timeout=10).jobs
        self.assertTrue(set(ids) <= {j.id for j in done})
        self.assertTrue(all(j.state == S.SUCCEEDED for j in done))
        with self.assertRaises(grpc.RpcError) as e:
            self.ergd.stub.ListJobs(S.ListJobsRequest(page_size=5000), metadata=md(BOB),
                                    timeout=10)
        self.assertEqual(e.exception.code(), grpc.StatusCode.INVALID_ARGUMENT)

    def test_health_and_reflection(self):
        # grpc.health.v1.Health/Check by hand (HealthCheckRequest{service}).
        name = b"erg.v1.JobService"
        check = self.ergd.channel.unary_unary("/grpc.health.v1.Health/Check")
        reply = check(b"\x0a" + bytes([len(name)]) + name, timeout=10)
        self.assertEqual(reply, b"\x08\x01")  # status: SERVING
        # Server reflection lists the service (grpc.reflection.v1alpha).
        info = self.ergd.channel.stream_stream(
            "/grpc.reflection.v1alpha.ServerReflection/ServerReflectionInfo")
        replies = list(info(iter([b"\x3a\x00"]), timeout=10))  # list_services: ""
        self.assertIn(b"erg.v1.JobService", replies[0])


if __name__ == "__main__":
    unittest.main()

# SPDX-License-Identifier: Apache-2.0
"""The probes ergd already withstood, kept standing: every RPC and every
HTTP route refuses a missing or wrong token; another tenant's job is
NOT_FOUND, exactly like one that does not exist; ids that try to walk the
file system find nothing; NaN and infinities in a spec are refused naming
the field; concurrent submits with one idempotency key make one job."""
import math
import threading
import unittest
import urllib.error
import urllib.request

import grpc
from google.protobuf.descriptor import FieldDescriptor as FD

from ergd_fixture import ALICE, BOB, ErgdTest, J, S, md, spec_json, spec_of

SERVICE = S.DESCRIPTOR.services_by_name["JobService"]


def http_status(url, token=None, method="GET"):
    req = urllib.request.Request(url, method=method, data=b"" if method == "POST" else None)
    if token:
        req.add_header("Authorization", "Bearer " + token)
    try:
        with urllib.request.urlopen(req, timeout=10) as r:
            return r.status
    except urllib.error.HTTPError as e:
        return e.code


def rpc(channel, method, request, metadata):
    """Calls a JobService method by its descriptor; returns the RpcError."""
    path = "/%s/%s" % (SERVICE.full_name, method.name)
    reply = getattr(S, method.output_type.name, None) or getattr(J, method.output_type.name)
    if method.server_streaming:
        call = channel.unary_stream(path, request_serializer=lambda m: m.SerializeToString(),
                                    response_deserializer=reply.FromString)
        try:
            for _ in call(request, metadata=metadata, timeout=10):
                pass
        except grpc.RpcError as e:
            return e
        return None
    call = channel.unary_unary(path, request_serializer=lambda m: m.SerializeToString(),
                               response_deserializer=reply.FromString)
    try:
        call(request, metadata=metadata, timeout=10)
    except grpc.RpcError as e:
        return e
    return None


def request_of(method, job_id):
    cls = getattr(S, method.input_type.name)
    req = cls()
    if "id" in cls.DESCRIPTOR.fields_by_name:
        req.id = job_id
    if "latest" in cls.DESCRIPTOR.fields_by_name:
        req.latest = True
    if method.name == "SubmitJob":
        req.spec.CopyFrom(spec_of(spec_json(steps=1)))
    if method.name == "SteerJob":
        req.events.add(step=0).sand.SetInParent()
    return req


def double_fields(msg, prefix=""):
    """(path, field) for every singular double field of the messages present
    in `msg` (the base spec), found through the descriptor."""
    out = []
    for f in msg.DESCRIPTOR.fields:
        name = prefix + f.name
        if f.label == FD.LABEL_REPEATED:
            continue
        if f.type == FD.TYPE_DOUBLE or f.type == FD.TYPE_FLOAT:
            out.append(name)
        elif f.type == FD.TYPE_MESSAGE and msg.HasField(f.name):
            out += double_fields(getattr(msg, f.name), name + ".")
    return out


def set_path(msg, path, value):
    *parents, leaf = path.split(".")
    for p in parents:
        msg = getattr(msg, p)
    setattr(msg, leaf, value)


class Probes(ErgdTest):
    @classmethod
    def setUpClass(cls):
        super().setUpClass()
        cls.job = cls.ergd.submit(spec_json(steps=2, snapshot_every=1, name="probe"))
        cls.ergd.wait(cls.job.id)

    def test_every_rpc_refuses_a_missing_or_wrong_token(self):
        methods = list(SERVICE.methods)
        self.assertGreaterEqual(len(methods), 8)
        for method in methods:
            for metadata in ([], [("authorization", "Bearer nope-nope-nope-nope-nope")],
                             [("authorization", ALICE)], [("authorization", "Bearer ")],
                             [("authorization", "Bearer " + ALICE[:-1])]):
                e = rpc(self.ergd.channel, method, request_of(method, self.job.id), metadata)
                self.assertIsNotNone(e, method.name)
                self.assertEqual(e.code(), grpc.StatusCode.UNAUTHENTICATED,
                                 (method.name, metadata))

    def test_every_http_route_refuses_a_missing_or_wrong_token(self):
        for path in ("/", "/api/jobs", "/api/jobs/%s" % self.job.id,
                     "/api/jobs/%s/preview.png" % self.job.id, "/metrics",
                     "/jobs/%s" % self.job.id, "/api/jobs/%s/events" % self.job.id,
                     "/api/jobs/%s/relief" % self.job.id, "/static/job.js",
                     "/static/dashboard.css", "/?state=running"):
            self.assertEqual(http_status(self.ergd.http + path), 401, path)
            self.assertEqual(http_status(self.ergd.http + path, "wrong-token-0123456789"), 401)
        self.assertEqual(http_status(self.ergd.http + "/login?token=wrong-token-0123456789"), 401)

    def test_another_tenants_job_is_not_found_like_a_missing_one(self):
        missing = "j-" + "0" * 16
        for method in SERVICE.methods:
            if "id" not in getattr(S, method.input_type.name).DESCRIPTOR.fields_by_name:
                continue
            theirs = rpc(self.ergd.channel, method, request_of(method, self.job.id), md(BOB))
            none = rpc(self.ergd.channel, method, request_of(method, missing), md(BOB))
            self.assertEqual(theirs.code(), grpc.StatusCode.NOT_FOUND, method.name)
            self.assertEqual(none.code(), grpc.StatusCode.NOT_FOUND, method.name)
            self.assertEqual(theirs.details().replace(self.job.id, "ID"),
                             none.details().replace(missing, "ID"), method.name)
            self.assertNotIn("alice", theirs.details())
        for path in ("/api/jobs/%s" % self.job.id, "/api/jobs/%s/preview.png" % self.job.id,
                     "/api/jobs/%s/preview.png?step=0" % self.job.id, "/jobs/%s" % self.job.id,
                     "/api/jobs/%s/events" % self.job.id, "/api/jobs/%s/relief" % self.job.id):
            self.assertEqual(http_status(self.ergd.http + path, BOB), 404, path)

    def test_ids_that_walk_the_file_system_find_nothing(self):
        ids = ["../../ergd.sqlite", "../" + self.job.id, self.job.id + "/../" + self.job.id,
               "/etc/passwd", "..", ".", "", "j-%2e%2e%2fergd.sqlite", self.job.id + "\x00",
               "jobs/" + self.job.id, self.job.id + "/run/snapshots/step_00000000.h5"]
        for method in SERVICE.methods:
            if "id" not in getattr(S, method.input_type.name).DESCRIPTOR.fields_by_name:
                continue
            for bad in ids:
                e = rpc(self.ergd.channel, method, request_of(method, bad), md(ALICE))
                self.assertIsNotNone(e, (method.name, bad))
                self.assertEqual(e.code(), grpc.StatusCode.NOT_FOUND, (method.name, bad))
        # Over HTTP, raw (no client-side normalisation of the path).
        for path in ("/api/jobs/../../ergd.sqlite", "/api/jobs/..%2F..%2Fergd.sqlite",
                     "/api/jobs/%s/../../../ergd.sqlite" % self.job.id,
                     "/api/jobs/%s%%2Frun%%2Fsnapshots/preview.png" % self.job.id):
            answer = self.ergd.raw_get(path, ALICE)
            status = int(answer.split(b" ", 2)[1])
            self.assertIn(status, (400, 404), path)
            self.assertNotIn(b"SQLite", answer)

    def test_nan_and_infinities_are_refused_naming_the_field(self):
        base = spec_of(spec_json(steps=1, name="nan"))
        fields = double_fields(base)
        self.assertGreaterEqual(len(fields), 10)
        for path in fields:
            for value in (math.nan, math.inf, -math.inf):
                spec = spec_of(spec_json(steps=1, name="nan"))
                set_path(spec, path, value)
                with self.assertRaises(grpc.RpcError, msg=(path, value)) as e:
                    self.ergd.stub.SubmitJob(S.SubmitJobRequest(spec=spec), metadata=md(ALICE),
                                             timeout=10)
                self.assertEqual(e.exception.code(), grpc.StatusCode.INVALID_ARGUMENT,
                                 (path, value))
                self.assertIn(path, e.exception.details())

    def test_concurrent_submits_with_one_key_make_one_job(self):
        ids, errors = [], []

        def submit():
            try:
                ids.append(self.ergd.submit(spec_json(steps=1, name="idem-race"),
                                            key="race-1").id)
            except grpc.RpcError as e:  # pragma: no cover - reported below
                errors.append(e)

        threads = [threading.Thread(target=submit) for _ in range(16)]
        for t in threads:
            t.start()
        for t in threads:
            t.join(60)
        self.assertEqual(errors, [])
        self.assertEqual(len(ids), 16)
        self.assertEqual(len(set(ids)), 1, ids)
        jobs = [j for j in self.ergd.stub.ListJobs(S.ListJobsRequest(page_size=1000),
                                                   metadata=md(ALICE), timeout=10).jobs
                if j.spec.name == "idem-race"]
        self.assertEqual(len(jobs), 1)
        self.ergd.wait(ids[0])


if __name__ == "__main__":
    unittest.main()

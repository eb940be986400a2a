# SPDX-License-Identifier: Apache-2.0
"""Errors a client can provoke are its own and bounded: size limits are
RESOURCE_EXHAUSTED whichever limit says no; a request that is not a valid
protobuf is INVALID_ARGUMENT with a message (not INTERNAL, not empty); an id
echoed back in an error is cut to 64 characters, whatever its length."""
import unittest

import grpc

from ergd_fixture import ALICE, ErgdTest, J, S, md, spec_json, spec_of
from test_probes import SERVICE, request_of, rpc


def nested_groups(depth):
    """An unknown field 15 as `depth` nested groups: protobuf's parser gives
    up past 100 levels."""
    return b"\x7b" * depth + b"\x7c" * depth


class Errors(ErgdTest):
    @classmethod
    def setUpClass(cls):
        super().setUpClass()
        cls.job = cls.ergd.submit(spec_json(steps=2, snapshot_every=1, name="errors"))
        cls.ergd.wait(cls.job.id)

    def code_of(self, call):
        with self.assertRaises(grpc.RpcError) as e:
            call()
        return e.exception.code(), e.exception.details()

    def test_size_errors_are_resource_exhausted(self):
        for size in (300 * 1024, 5 * 1024 * 1024):  # over ergd's spec limit; over gRPC's 4 MiB
            d = spec_json(name="x" * size)
            code, _ = self.code_of(lambda: self.ergd.submit(d))
            self.assertEqual(code, grpc.StatusCode.RESOURCE_EXHAUSTED, size)
        code, details = self.code_of(lambda: self.ergd.submit(spec_json(), key="k" * 200))
        self.assertEqual(code, grpc.StatusCode.RESOURCE_EXHAUSTED)
        self.assertIn("idempotency_key", details)
        events = [J.Event(step=0, sand=J.Brush(x_m=1, y_m=1, radius_m=1, height=1))] * 1001
        code, details = self.code_of(lambda: self.ergd.stub.SteerJob(
            S.SteerJobRequest(id=self.job.id, events=events), metadata=md(ALICE), timeout=10))
        self.assertEqual(code, grpc.StatusCode.RESOURCE_EXHAUSTED)
        self.assertIn("events", details)

    def test_malformed_protobufs_are_invalid_argument_with_a_message(self):
        bad = {"nested groups": nested_groups(2000), "truncated": b"\x0a\xff\x01abc",
               "wrong wire type": b"\x0d\x01", "bad varint": b"\x08" + b"\xff" * 11}
        for method in SERVICE.methods:
            path = "/%s/%s" % (SERVICE.full_name, method.name)
            for what, payload in bad.items():
                for metadata in (md(ALICE), []):
                    if method.server_streaming:
                        call = self.ergd.channel.unary_stream(path)
                        code, details = self.code_of(
                            lambda: list(call(payload, metadata=metadata, timeout=10)))
                    else:
                        call = self.ergd.channel.unary_unary(path)
                        code, details = self.code_of(
                            lambda: call(payload, metadata=metadata, timeout=10))
                    self.assertEqual(code, grpc.StatusCode.INVALID_ARGUMENT,
                                     (method.name, what, details))
                    self.assertIn("not a valid protobuf message", details)
        # ergd is still serving.
        self.assertEqual(self.ergd.get(self.job.id).id, self.job.id)

    def test_echoed_ids_are_truncated(self):
        long_id = "j-" + "a" * 100000
        for method in SERVICE.methods:
            if "id" not in getattr(S, method.input_type.name).DESCRIPTOR.fields_by_name:
                continue
            e = rpc(self.ergd.channel, method, request_of(method, long_id), md(ALICE))
            self.assertEqual(e.code(), grpc.StatusCode.NOT_FOUND, method.name)
            self.assertLess(len(e.details()), 200, method.name)
            self.assertIn("j-aaaa", e.details())
            self.assertIn("(100002 bytes)", e.details())
        # Not printable: shown as '?', never as raw bytes.
        e = rpc(self.ergd.channel, SERVICE.methods_by_name["GetJob"],
                request_of(SERVICE.methods_by_name["GetJob"], "j-\x1b[31mred"), md(ALICE))
        self.assertEqual(e.code(), grpc.StatusCode.NOT_FOUND)
        self.assertNotIn("\x1b", e.details())
        # Over HTTP too.
        for path in ("/api/jobs/%s" % ("j-" + "b" * 5000),
                     "/api/jobs/%s/preview.png" % ("j-" + "b" * 5000)):
            answer = self.ergd.raw_get(path, ALICE)
            self.assertEqual(int(answer.split(b" ", 2)[1]), 404, answer[:200])
            self.assertLess(len(answer.split(b"\r\n\r\n", 1)[1]), 200)


if __name__ == "__main__":
    unittest.main()

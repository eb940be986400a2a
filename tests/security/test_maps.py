# SPDX-License-Identifier: Apache-2.0
"""No server file is read for a tenant: every erg.v1.MapFile field anywhere
in a submitted JobSpec, or in a steering event, is refused with
PERMISSION_DENIED, with a message that does not depend on whether the path
exists. The map-bearing fields are generated from the protobuf descriptor,
so a layer added to the schema later is attacked here without a change."""
import os
import unittest

import grpc
from google.protobuf.descriptor import FieldDescriptor as FD

from ergd_fixture import ALICE, BOB, ErgdTest, J, S, md, spec_json, spec_of

MAP_FILE = "erg.v1.MapFile"


def map_paths(desc, seen=()):
    """Every chain of fields from `desc` to a MapFile field: singular,
    repeated, oneof and map fields alike; a recursive type is followed once."""
    out = []
    for f in desc.fields:
        if f.type != FD.TYPE_MESSAGE:
            continue
        m = f.message_type
        if m.GetOptions().map_entry:  # map<K, V>: the way to V
            v = m.fields_by_name["value"]
            if v.type != FD.TYPE_MESSAGE:
                continue
            m = v.message_type
        if m.full_name == MAP_FILE:
            out.append([f])
        elif m.full_name not in seen:
            out += [[f] + p for p in map_paths(m, seen + (desc.full_name, m.full_name))]
    return out


def set_map(msg, path, target):
    """Sets the MapFile at the end of `path` in `msg` (adding elements to
    repeated fields); returns the field path ergd names, e.g.
    "layers.obstacles.map" or "events[0]...."."""
    names = []
    for f in path:
        field = getattr(msg, f.name)
        if f.message_type.GetOptions().map_entry:
            key = "k" if f.message_type.fields_by_name["key"].type == FD.TYPE_STRING else 0
            names.append("%s[0].value" % f.name)
            msg = field[key]
        elif f.label == FD.LABEL_REPEATED:
            names.append("%s[%d]" % (f.name, len(field)))
            msg = field.add()
        else:
            names.append(f.name)
            msg = field
    msg.path = target
    msg.dataset = "/sand"
    return ".".join(names)


def label(path):
    return ".".join(f.name for f in path)


class Maps(ErgdTest):
    @classmethod
    def setUpClass(cls):
        super().setUpClass()
        # Another tenant's result: what the obstacle map used to leak.
        cls.bobs = cls.ergd.submit(spec_json(steps=2, snapshot_every=1, name="bobs"), token=BOB)
        cls.ergd.wait(cls.bobs.id, BOB)
        cls.bobs_snapshot = os.path.join(cls.ergd.data, "jobs", cls.bobs.id, "run", "snapshots",
                                         "step_00000000.h5")
        # Targets that exist (an HDF5 file, a text file, a directory) and
        # that do not: each must get the same answer.
        cls.targets = [cls.bobs_snapshot, "/etc/passwd", "/", "/nonexistent/x.h5",
                       "../../jobs/%s/run/snapshots/step_00000000.h5" % cls.bobs.id,
                       "no-such-relative.png"]

    def alice_jobs(self):
        return len(self.ergd.stub.ListJobs(S.ListJobsRequest(page_size=1000), metadata=md(ALICE),
                                           timeout=10).jobs)

    def refused(self, call):
        with self.assertRaises(grpc.RpcError) as e:
            call()
        self.assertEqual(e.exception.code(), grpc.StatusCode.PERMISSION_DENIED,
                         e.exception.details())
        return e.exception.details()

    def test_the_descriptor_walk_finds_every_layer(self):
        found = {label(p) for p in map_paths(J.JobSpec.DESCRIPTOR)}
        # The layers known today, obstacles included; the walk finds any new one.
        for name in ("bedrock", "sand", "vegetation", "resistance", "obstacles"):
            self.assertIn("layers.%s.map" % name, found)
        self.assertTrue(os.path.exists(self.bobs_snapshot))

    def test_every_map_field_of_a_submission_is_refused_the_same_whatever_the_path(self):
        paths = map_paths(J.JobSpec.DESCRIPTOR)
        before = self.alice_jobs()
        for path in paths:
            answers = set()
            for target in self.targets:
                spec = spec_of(spec_json(steps=1, name="maps"))
                where = set_map(spec, path, target)
                details = self.refused(lambda: self.ergd.stub.SubmitJob(
                    S.SubmitJobRequest(spec=spec), metadata=md(ALICE), timeout=10))
                self.assertIn(where + ": map files are not accepted", details)
                self.assertNotIn(target, details)
                answers.add(details)
            # The answer tells nothing about the server's files.
            self.assertEqual(len(answers), 1, (label(path), answers))
        # All of them at once: each is named.
        spec = spec_of(spec_json(steps=1, name="maps"))
        wheres = [set_map(spec, p, self.bobs_snapshot) for p in paths]
        details = self.refused(lambda: self.ergd.stub.SubmitJob(
            S.SubmitJobRequest(spec=spec), metadata=md(ALICE), timeout=10))
        for w in wheres:
            self.assertIn(w, details)
        # An idempotency key does not get around it, nor does JSON's empty map.
        spec = spec_of(spec_json(steps=1, name="maps"))
        spec.layers.obstacles.map.SetInParent()
        self.refused(lambda: self.ergd.stub.SubmitJob(
            S.SubmitJobRequest(spec=spec, idempotency_key="maps-1"), metadata=md(ALICE),
            timeout=10))
        # No job was created by any of them.
        self.assertEqual(self.alice_jobs(), before)

    def test_the_obstacle_map_no_longer_reads_another_tenants_snapshot(self):
        d = spec_json(steps=1, name="leak")
        d["layers"]["obstacles"] = {"map": {"path": self.bobs_snapshot, "dataset": "/sand"}}
        details = self.refused(lambda: self.ergd.submit(d))
        self.assertIn("layers.obstacles.map", details)

    def test_every_map_field_of_a_steering_event_is_refused(self):
        paths = map_paths(J.Event.DESCRIPTOR)
        if not paths:
            # Events carry no MapFile today (the walk above says so); the
            # guard runs on them all the same (server/auth/request_checks.h).
            self.assertEqual(map_paths(S.SteerJobRequest.DESCRIPTOR), [])
            return
        job = self.ergd.submit(spec_json(nx=64, ny=64, steps=100000, snapshot_every=0,
                                         checkpoint_every=0, name="steer-maps"))
        try:
            self.ergd.wait(job.id, until=lambda j: j.state == S.RUNNING, timeout=60)
            for path in paths:
                answers = set()
                for target in self.targets:
                    ev = J.Event(step=0)
                    where = set_map(ev, path, target)
                    details = self.refused(lambda: self.ergd.stub.SteerJob(
                        S.SteerJobRequest(id=job.id, events=[ev]), metadata=md(ALICE),
                        timeout=10))
                    self.assertIn("events[0]." + where, details)
                    answers.add(details)
                self.assertEqual(len(answers), 1)
        finally:
            self.ergd.stub.CancelJob(S.CancelJobRequest(id=job.id), metadata=md(ALICE),
                                     timeout=10)
            self.ergd.wait(job.id)


if __name__ == "__main__":
    unittest.main()

# SPDX-License-Identifier: Apache-2.0
"""The worker protocol end to end: erg-worker writes erg.v1.WorkerEvent lines
(proto/erg/v1/worker.proto) and ergd parses them with protobuf, so text the
worker reports reaches the job record exactly as written.

The failure is real: ergd's data directory is named with a newline, quotes,
a backslash and non-ASCII letters; while the job runs, a directory is put
where its next snapshot goes, so the worker's rename fails and its reason
quotes that path. Before the protocol was typed, a hand-made escaper and
scanner turned the newline into "n"."""
import os
import shutil
import tempfile
import unittest

from ergd_fixture import Ergd, S, spec_json, terminal

EVERY = 100


class FailureReason(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.mkdtemp(prefix="ergd-events-", dir=os.environ.get("ERG_TEST_TMP"))
        self.data = os.path.join(self.tmp, 'da"ta\nD\u00fcnen \u00e9rg \u2713 \\ \u6c99')
        self.ergd = Ergd(self.tmp, data=self.data)

    def tearDown(self):
        self.ergd.stop()
        if os.environ.get("ERG_KEEP_TEST_DIRS") != "1":
            shutil.rmtree(self.tmp, ignore_errors=True)

    def test_a_reason_with_newlines_quotes_and_unicode_arrives_intact(self):
        e = self.ergd
        job = e.submit(spec_json(name="blocked", nx=64, ny=64, steps=1000000,
                                 snapshot_every=EVERY, checkpoint_every=0))
        j = e.wait(job.id, until=lambda j: j.progress.step >= 1 or terminal(j.state))
        self.assertEqual(j.state, S.RUNNING, j.failure_reason + j.log_tail)
        # Three snapshot intervals ahead of the step ergd last heard of (at
        # most a second old): the worker cannot have passed it yet.
        target = (j.progress.step // EVERY + 3) * EVERY
        path = os.path.join(self.data, "jobs", job.id, "run", "snapshots",
                            "step_%08d.h5" % target)
        os.mkdir(path)
        j = e.wait(job.id, timeout=300)
        self.assertEqual(j.state, S.FAILED, j.failure_reason + j.log_tail)
        self.assertLess(j.progress.step, target + 1)
        # The worker's own words, the path in them byte for byte.
        self.assertIn(path + ": rename from temporary file '", j.failure_reason)
        self.assertIn("\n", j.failure_reason)
        self.assertIn('"', j.failure_reason)
        self.assertIn("D\u00fcnen \u00e9rg \u2713 \\ \u6c99", j.failure_reason)
        # And in the stored record a new ergd reads back.
        e.stop()
        e.start()
        self.assertEqual(e.get(job.id).failure_reason, j.failure_reason)


if __name__ == "__main__":
    unittest.main()

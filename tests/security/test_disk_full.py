# SPDX-License-Identifier: Apache-2.0
"""A full disk is a job failure, never an ergd failure.

ergd's data directory is a real 24 MiB tmpfs mounted by the test (CI runs
as root; without root the test is skipped), unmounted whatever happens. A job
writes snapshots until the file system is full:
- the job ends FAILED, its reason naming ENOSPC; ergd stays up and serves
  GetJob and ListJobs;
- while free space is below the reserve (--min-free-disk), submissions get
  RESOURCE_EXHAUSTED, and no job directory is left without its job;
- with no reserve and the disk at 0 bytes free, a submission still gets
  RESOURCE_EXHAUSTED (the write fails) and leaves no orphan directory;
- ergd SIGKILLed and restarted on the full disk starts and serves reads;
- once space is freed, jobs are accepted and run again.
"""
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import unittest

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "server"))

import grpc  # noqa: E402

from ergd_fixture import ALICE, Ergd, S, md, spec_json, terminal  # noqa: E402

MIB = 1 << 20
RESERVE = 8 * MIB


def free_bytes(path):
    v = os.statvfs(path)
    return v.f_bavail * v.f_frsize


def fill(path, leave):
    """Writes path/filler-N files until fewer than `leave` bytes are free."""
    n = 0
    while free_bytes(path) >= leave:
        try:
            with open(os.path.join(path, "filler-%d" % n), "wb") as f:
                f.write(b"\0" * min(MIB, max(4096, free_bytes(path) - leave + 4096)))
        except OSError:
            break
        n += 1


@unittest.skipUnless(os.geteuid() == 0, "mounting a tmpfs needs root")
class DiskFull(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.mkdtemp(prefix="ergd-diskfull-", dir=os.environ.get("ERG_TEST_TMP"))
        self.mnt = os.path.join(self.tmp, "mnt")
        os.mkdir(self.mnt)
        subprocess.run(["mount", "-t", "tmpfs", "-o", "size=24m,mode=0700", "tmpfs", self.mnt],
                       check=True)
        self.addCleanup(self.unmount)
        self.data = os.path.join(self.mnt, "data")
        self.ergd = None

    def unmount(self):
        if self.ergd and self.ergd.proc and self.ergd.proc.poll() is None:
            self.ergd.kill()
        for _ in range(50):
            if subprocess.run(["umount", self.mnt], stderr=subprocess.DEVNULL).returncode == 0:
                break
            time.sleep(0.2)  # a worker that has not exited yet
        else:
            subprocess.run(["umount", "-l", self.mnt])
        shutil.rmtree(self.tmp, ignore_errors=True)

    def start(self, reserve):
        self.ergd = Ergd(self.tmp, ("--min-free-disk", str(reserve)), data=self.data)
        return self.ergd

    def assertAlive(self):
        if self.ergd.proc.poll() is not None:
            with open(self.ergd.log) as f:
                self.fail("ergd exited: " + f.read()[-3000:])

    def assertNoOrphans(self):
        jobs = {j.id for j in self.ergd.stub.ListJobs(S.ListJobsRequest(page_size=1000),
                                                      metadata=md(ALICE), timeout=30).jobs}
        self.assertEqual(set(os.listdir(os.path.join(self.data, "jobs"))), jobs)

    def assertRefused(self, what):
        with self.assertRaises(grpc.RpcError) as err:
            self.ergd.submit(spec_json(name="refused", steps=5))
        self.assertEqual(err.exception.code(), grpc.StatusCode.RESOURCE_EXHAUSTED,
                         err.exception.details())
        self.assertIn(what, err.exception.details())

    def test_a_full_disk_fails_the_job_and_ergd_stays_up(self):
        e = self.start(RESERVE)
        small = e.submit(spec_json(name="small", steps=20))
        self.assertEqual(e.wait(small.id).state, S.SUCCEEDED)
        # 512 x 512 cells, a snapshot and a preview every step: megabytes a step.
        filler = e.submit(spec_json(name="filler", nx=512, ny=512, steps=400, snapshot_every=1,
                                    checkpoint_every=0))
        j = e.wait(filler.id, timeout=300)
        self.assertEqual(j.state, S.FAILED)
        self.assertIn("ENOSPC", j.failure_reason)
        print("the filled job failed:", j.failure_reason, file=sys.stderr)
        self.assertAlive()
        # Reads are served.
        self.assertEqual(e.get(small.id).state, S.SUCCEEDED)
        self.assertEqual(e.get(filler.id).state, S.FAILED)
        events = list(e.stub.WatchJob(S.WatchJobRequest(id=filler.id), metadata=md(ALICE),
                                      timeout=60))
        self.assertEqual(events[-1].state_changed, S.FAILED)
        # Below the reserve: refused, named, nothing left behind.
        fill(self.mnt, RESERVE)
        time.sleep(2.5)  # ergd looks at the free space every 2 s
        self.assertRefused("--min-free-disk")
        self.assertNoOrphans()
        self.assertAlive()

        # No reserve and not a byte free: the write itself fails, cleanly.
        e.kill()
        fill(self.mnt, 1)
        self.assertLess(free_bytes(self.mnt), 4096)
        e = self.start(0)  # ergd starts on the full disk ...
        time.sleep(1.0)
        self.assertAlive()
        self.assertEqual(e.get(small.id).state, S.SUCCEEDED)  # ... and serves reads
        self.assertEqual(e.get(filler.id).state, S.FAILED)
        self.assertRefused("ENOSPC")
        self.assertNoOrphans()
        self.assertAlive()

        # The operator frees space (the fillers, the failed job's snapshots):
        # jobs run again.
        for name in os.listdir(self.mnt):
            if name.startswith("filler-"):
                os.remove(os.path.join(self.mnt, name))
        shutil.rmtree(os.path.join(self.data, "jobs", filler.id, "run", "snapshots"))
        time.sleep(2.5)
        again = e.submit(spec_json(name="again", steps=20))
        j = e.wait(again.id)
        self.assertEqual(j.state, S.SUCCEEDED, j.failure_reason + j.log_tail)
        self.assertNoOrphans()
        e.stop()


if __name__ == "__main__":
    unittest.main()

# SPDX-License-Identifier: Apache-2.0
"""`erg run --resume` never continues from a corrupt or foreign checkpoint.

A run leaves two checkpoints (steps 20 and 30). The newer one is corrupted
for real, one way per test: a bit flipped in a dataset value (through h5py:
the file stays valid HDF5), a bit flipped in the raw bytes of the stored spec
(the digit 50 -> 54, and a byte made non-UTF-8), a bit flipped in the `step`
attribute, a truncation. Each time the resume names the file and the reason,
falls back to the older checkpoint, and ends bitwise equal to an
uninterrupted run. A run whose job.json disagrees with its checkpoints (a
parameter, or an event) is refused with the difference named.
"""
import json
import os
import shutil
import subprocess
import sys
import tempfile
import unittest

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "server"))

import h5py  # noqa: E402
import numpy as np  # noqa: E402

from ergd_fixture import ERG, datasets, spec_json  # noqa: E402

SPEC = spec_json(name="integrity", nx=48, ny=48, steps=40, snapshot_every=40,
                 checkpoint_every=10)
SPEC["model"]["warp_small_radius_m"] = 50


def run(args, check=True):
    r = subprocess.run([ERG, "run"] + args + ["--threads", "2"], capture_output=True, text=True,
                       timeout=300)
    if check and r.returncode != 0:
        raise AssertionError("erg run %s: %d\n%s" % (args, r.returncode, r.stderr))
    return r


def ckpt(d, step):
    return os.path.join(d, "checkpoints", "step_%08d.h5" % step)


def flip_bytes(path, text, at, mask):
    with open(path, "rb") as f:
        b = bytearray(f.read())
    pos = b.find(text)
    assert pos >= 0, "%r not in %s" % (text, path)
    b[pos + at] ^= mask
    with open(path, "wb") as f:
        f.write(b)


class CheckpointResume(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.mkdtemp(prefix="erg-integrity-", dir=os.environ.get("ERG_TEST_TMP"))
        cls.job = os.path.join(cls.tmp, "job.json")
        with open(cls.job, "w") as f:
            json.dump(SPEC, f)
        cls.ref = os.path.join(cls.tmp, "ref")
        run([cls.job, "--out", cls.ref])
        # The interrupted run: 30 of the 40 steps (checkpoints 20 and 30 kept).
        cls.partial = os.path.join(cls.tmp, "partial")
        run([cls.job, "--out", cls.partial, "--steps", "30"])
        assert sorted(os.listdir(os.path.join(cls.partial, "checkpoints"))) == [
            "step_00000020.h5", "step_00000030.h5"]

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.tmp, ignore_errors=True)

    def copy(self):
        d = os.path.join(self.tmp, self.id().split(".")[-1])
        shutil.rmtree(d, ignore_errors=True)
        shutil.copytree(self.partial, d)
        return d

    def resume_falls_back(self, d, reason):
        r = run(["--resume", d, "--steps", "40"])
        self.assertIn("checkpoint step_00000030.h5: ", r.stderr)
        self.assertIn(reason, r.stderr)
        self.assertIn("resuming from step_00000020.h5 (step 20), the newest intact checkpoint",
                      r.stderr)
        got = datasets(os.path.join(d, "snapshots", "step_00000040.h5"))
        want = datasets(os.path.join(self.ref, "snapshots", "step_00000040.h5"))
        self.assertEqual(sorted(got), sorted(want))
        for k in want:
            if k != "@attrs":
                self.assertTrue(np.array_equal(got[k], want[k]), k)
        for k in ("sand_units_total", "airborne_units_total", "bedrock_units_total"):
            self.assertEqual(got["@attrs"][k], want["@attrs"][k], k)

    def test_a_bit_flipped_in_a_dataset_falls_back(self):
        d = self.copy()
        with h5py.File(ckpt(d, 30), "r+") as f:
            v = f["sand_units"][7, 9]
            f["sand_units"][7, 9] = v ^ (1 << 12)
        self.resume_falls_back(d, "checksum of dataset 'sand_units' does not match")

    def test_a_bit_flipped_in_the_stored_spec_falls_back(self):
        d = self.copy()
        # "warp_small_radius_m": 50 -> 54 (one bit of the '0').
        flip_bytes(ckpt(d, 30), b'"warp_small_radius_m": 50', 24, 0x04)
        self.resume_falls_back(d, "checksum of the stored job spec does not match")

    def test_a_non_utf8_byte_in_the_stored_spec_falls_back(self):
        d = self.copy()
        flip_bytes(ckpt(d, 30), b'"warp_small_radius_m": 50', 5, 0x80)
        self.resume_falls_back(d, "checksum of the stored job spec does not match")

    def test_a_bit_flipped_in_an_attribute_falls_back(self):
        d = self.copy()
        with h5py.File(ckpt(d, 30), "r+") as f:
            f.attrs.modify("step", np.int64(30 ^ 4))
        self.resume_falls_back(d, "checksum of the root attributes")

    def test_a_truncated_checkpoint_falls_back(self):
        d = self.copy()
        size = os.path.getsize(ckpt(d, 30))
        with open(ckpt(d, 30), "r+b") as f:
            f.truncate(size // 2)
        self.resume_falls_back(d, "step_00000030.h5")

    def test_no_intact_checkpoint_refuses_the_resume(self):
        d = self.copy()
        for step in (20, 30):
            with open(ckpt(d, step), "r+b") as f:
                f.truncate(1000)
        r = run(["--resume", d, "--steps", "40"], check=False)
        self.assertEqual(r.returncode, 2, r.stderr)
        self.assertIn("holds no intact checkpoint to resume from", r.stderr)

    def test_a_spec_that_disagrees_with_job_json_is_refused_naming_the_difference(self):
        d = self.copy()
        path = os.path.join(d, "job.json")
        with open(path) as f:
            spec = json.load(f)
        spec["model"]["warp_small_radius_m"] = 54
        with open(path, "w") as f:
            json.dump(spec, f)
        r = run(["--resume", d, "--steps", "40"], check=False)
        self.assertEqual(r.returncode, 2, r.stderr)
        self.assertIn("its spec disagrees with the run's job.json", r.stderr)
        self.assertIn("warp_small_radius_m", r.stderr)
        self.assertIn("holds no intact checkpoint", r.stderr)

    def test_events_that_disagree_with_job_json_are_refused(self):
        spec = dict(SPEC, events=[{"step": 5, "sand": {"x_m": 3, "y_m": 3, "radius_m": 2,
                                                        "height": 1}}])
        job = os.path.join(self.tmp, "events.json")
        with open(job, "w") as f:
            json.dump(spec, f)
        d = os.path.join(self.tmp, "events")
        run([job, "--out", d, "--steps", "30"])
        path = os.path.join(d, "job.json")
        with open(path) as f:
            recorded = json.load(f)
        recorded["events"][0]["sand"]["height"] = 2
        with open(path, "w") as f:
            json.dump(recorded, f)
        r = run(["--resume", d, "--steps", "40"], check=False)
        self.assertEqual(r.returncode, 2, r.stderr)
        self.assertIn("its spec disagrees with the run's job.json: events[0]", r.stderr)
        self.assertIn("height", r.stderr)


if __name__ == "__main__":
    unittest.main()

# SPDX-License-Identifier: Apache-2.0
"""erg validate --reuse after an interruption: the full suite runs for hours,
so each scene checkpoints ten times and a scene whose worker was killed is
resumed from its newest intact checkpoint. The resumed scene must end with
the same bits as one never stopped (a checkpoint is output only), a scene
killed before its first checkpoint is run again from step 0, and a run
directory is never taken over without --reuse."""
import io
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import unittest
from contextlib import redirect_stderr
from pathlib import Path

import h5py
import numpy as np

SOURCE = Path(os.environ["ERG_SOURCE_DIR"])
sys.path.insert(0, str(SOURCE / "client" / "validate"))
import validate  # noqa: E402

WORKER = os.environ["ERG_WORKER_BIN"]
STEPS = 2000


def small_scene(path):
    """The quick barchan scene on a smaller torus, one pile, long enough to
    be killed between two checkpoints."""
    job = json.loads((SOURCE / "client/validate/scenes/quick/barchans.json").read_text())
    job["domain"].update(nx=128, ny=96)
    job["run"].update(steps=STEPS, snapshot_every=STEPS // 4)
    job["layers"]["sand"]["piles"] = [{"x_m": 40, "y_m": 48, "height": 4, "radius_m": 15}]
    path.write_text(json.dumps(job))
    return job


def final_fields(run):
    snaps = sorted((run / "snapshots").glob("step_*.h5"))
    with h5py.File(snaps[-1], "r") as f:
        out = {}
        f.visititems(lambda name, obj: out.__setitem__(name, obj[()])
                     if isinstance(obj, h5py.Dataset) else None)
    return snaps[-1].name, out


def run_quietly(*args):
    err = io.StringIO()
    with redirect_stderr(err):
        seconds = validate.run_scene(*args)
    return seconds, err.getvalue()


def kill_when(out, ready, timeout=120):
    """Starts the worker as erg validate does and kills it (SIGKILL: no
    chance to tidy up) once ready(out) holds."""
    job_path = out.parent / "scene.json"
    job = json.loads(job_path.read_text())
    cmd = [WORKER, str(job_path), "--out", str(out), "--threads", "1", "--quiet",
           "--checkpoint-every", str(validate.checkpoint_every(job))]
    p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    t0 = time.time()
    while not ready(out) and p.poll() is None and time.time() - t0 < timeout:
        time.sleep(0.01)
    running = p.poll() is None
    p.send_signal(signal.SIGKILL)
    p.wait()
    return running


class Resume(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.TemporaryDirectory()
        cls.root = Path(cls.tmp.name)
        cls.job_path = cls.root / "scene.json"
        cls.job = small_scene(cls.job_path)
        cls.whole = cls.root / "whole"
        run_quietly(WORKER, cls.job_path, cls.whole, 1, False, 1, 1)
        cls.reference = final_fields(cls.whole)

    @classmethod
    def tearDownClass(cls):
        cls.tmp.cleanup()

    def assert_same_bits(self, run):
        name, fields = final_fields(run)
        ref_name, ref = self.reference
        self.assertEqual(name, ref_name)
        self.assertEqual(sorted(fields), sorted(ref))
        for key in ref:
            self.assertTrue(np.array_equal(fields[key], ref[key]), f"{key} differs")

    def test_a_killed_scene_resumes_from_its_checkpoint_with_the_same_bits(self):
        out = self.root / "killed"
        every = validate.checkpoint_every(self.job)
        # Killed once its second checkpoint exists: well past step 0, well
        # before the end.
        second = f"step_{2 * every:08d}.h5"
        self.assertTrue(kill_when(out, lambda o: (o / "checkpoints" / second).exists()),
                        "the worker finished before it could be killed")
        self.assertFalse(validate.run_complete(out, self.job))
        seconds, log = run_quietly(WORKER, self.job_path, out, 1, True, 1, 1)
        self.assertIn("resuming the interrupted run", log)
        self.assertIn("resum", (Path(str(out) + ".log")).read_text().lower())
        self.assertTrue(validate.run_complete(out, self.job))
        self.assertGreater(seconds, 0)
        self.assert_same_bits(out)

    def test_a_scene_killed_before_any_checkpoint_runs_again(self):
        out = self.root / "early"
        self.assertTrue(kill_when(out, lambda o: (o / "snapshots").exists()))
        self.assertFalse(any((out / "checkpoints").glob("step_*.h5")))
        _, log = run_quietly(WORKER, self.job_path, out, 1, True, 1, 1)
        self.assertIn("interrupted before its first checkpoint; starting it again", log)
        self.assert_same_bits(out)

    def test_a_complete_scene_is_reused_and_an_existing_one_needs_reuse(self):
        seconds, log = run_quietly(WORKER, self.job_path, self.whole, 1, True, 1, 1)
        self.assertIn("reusing", log)
        self.assertEqual(seconds, json.loads(Path(str(self.whole) + ".time.json").read_text())["seconds"])
        with self.assertRaises(SystemExit) as e:
            run_quietly(WORKER, self.job_path, self.whole, 1, False, 1, 1)
        self.assertIn("pass --reuse", str(e.exception))

    def test_a_run_of_a_changed_scene_is_started_again(self):
        # The scene's step changed since the run (as a newer erg's scenes
        # do): the old snapshots and checkpoints are another job's, so the
        # run is not reused, nor resumed, but started again.
        out = self.root / "changed"
        shutil.copytree(self.whole, out)
        shutil.copy(Path(str(self.whole) + ".time.json"), Path(str(out) + ".time.json"))
        job = json.loads(self.job_path.read_text())
        job["model"]["slab_m"] = 2 * job["model"]["slab_m"]
        job["run"].update(steps=40, snapshot_every=20)
        changed = self.root / "changed_scene.json"
        changed.write_text(json.dumps(job))
        self.assertIn("model.slab_m", validate.job_difference(out, job))
        self.assertIsNone(validate.job_difference(self.whole, self.job))
        _, log = run_quietly(WORKER, changed, out, 1, True, 1, 1)
        self.assertIn("holds a run of another job (model.slab_m: ", log)
        self.assertIn("starting it again", log)
        self.assertNotIn("reusing", log)
        snaps = sorted(p.name for p in (out / "snapshots").glob("step_*.h5"))
        self.assertEqual(snaps[-1], "step_00000040.h5")
        self.assertNotIn(f"step_{STEPS:08d}.h5", snaps)
        self.assertIsNone(validate.job_difference(out, job))


if __name__ == "__main__":
    unittest.main()

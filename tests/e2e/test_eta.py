# SPDX-License-Identifier: Apache-2.0
"""The ETA of the worker's progress events (what `erg run` and `erg watch`
show) on a real run: from 5% of the run on, each ETA is within 25% of the
time the run really took to finish from there (worker/sim/moving_rate.h).

The job is a sand sheet, whose steps all cost about the same, sized by a
short first run to take about 15 s here; the run is alone on the machine
(RUN_SERIAL), since other processes on the cores change its rate. On a
machine that other users share, their load changes the rate mid-run too:
the run is tried up to three times, and one run that meets the bound at
every progress event passes (each miss is printed)."""
import json
import os
import shutil
import subprocess
import tempfile
import time
import unittest

WORKER = os.path.join(os.environ["ERG_BIN_DIR"], "erg-worker")

JOB = {
    "name": "eta",
    "domain": {"nx": 512, "ny": 512, "cell_size_m": 1.0},
    "layers": {"bedrock": {"constant": 0}, "sand": {"constant": 1.0}},
    "wind": {"constant": {"speed_mps": 5, "direction_deg": 0}},
    "seed": 3,
    "run": {"steps": 100, "snapshot_every": 0, "checkpoint_every": 0},
}


class Eta(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.mkdtemp(prefix="erg-eta-")

    def tearDown(self):
        shutil.rmtree(self.tmp, ignore_errors=True)

    def run_job(self, steps, name):
        job = dict(JOB, run=dict(JOB["run"], steps=steps))
        path = os.path.join(self.tmp, name + ".json")
        with open(path, "w") as f:
            json.dump(job, f)
        t0 = time.monotonic()
        p = subprocess.Popen([WORKER, path, "--out", os.path.join(self.tmp, name), "--threads", "1",
                              "--progress-fd", "1"], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True)
        events = []  # (seconds since start, step, eta_s)
        for line in p.stdout:
            ev = json.loads(line)
            if "progress" in ev:
                events.append((time.monotonic() - t0, int(ev["step"]), ev["progress"]["eta_s"]))
        err = p.stderr.read()
        self.assertEqual(p.wait(), 0, err)
        return time.monotonic() - t0, events

    def test_eta_within_25_percent_after_5_percent_of_the_run(self):
        # The probe's rate between its first and last progress events (its
        # start-up, MPI and the first step, is not part of the rate).
        _, probe = self.run_job(100, "probe")
        (ta, sa, _), (tb, sb, _) = probe[0], probe[-1]
        rate = (sb - sa) / max(tb - ta, 1e-3)
        steps = max(200, int(15 * rate))
        misses = []
        for attempt in range(3):
            miss = self.check_run(steps, f"run{attempt}")
            if miss is None:
                return
            print("attempt", attempt + 1, "missed:", miss)
            misses.append(miss)
        self.fail("; ".join(misses))

    def check_run(self, steps, name):
        """None when every ETA from 5% of the run on is within 25%, else the first miss."""
        total, events = self.run_job(steps, name)
        checked = 0
        for t, step, eta in events:
            if t < 0.05 * total or step >= steps:
                continue
            truth = total - t
            # 0.3 s: the process's exit after the last step, and timer granularity.
            if abs(eta - truth) > 0.25 * truth + 0.3:
                return (f"at {t:.1f} s of {total:.1f} s (step {step} of {steps}): ETA "
                        f"{eta:.1f} s, the run took {truth:.1f} s more")
            checked += 1
        self.assertGreater(checked, 20, "too few progress events to judge")
        print(f"{steps} steps in {total:.1f} s; {checked} ETAs within 25%")
        return None


if __name__ == "__main__":
    unittest.main()

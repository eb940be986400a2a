# SPDX-License-Identifier: Apache-2.0
"""The deterministic (EXPECTED) twins of the dune examples form the dunes of
their stochastic originals: a sand pile on bare bedrock becomes crescent
barchans with slip faces and horns pointing downwind, a flat sand bed
with 1 m of random relief grows transverse dunes with crests perpendicular
to the wind, and sand patches under two winds 120 degrees apart grow linear
dunes along their resultant. The twins run [N24]'s expected transport with its slab
eps_S = 1 m (examples/*_expected.json); README "Expected or stochastic
transport?" gives the measurements and the shape law that still fails."""
import json
import os
import subprocess
import sys
import tempfile
import unittest
from pathlib import Path

SOURCE = Path(os.environ["ERG_SOURCE_DIR"])
sys.path.insert(0, str(SOURCE / "client" / "validate"))
import measure  # noqa: E402

ERG = os.environ["ERG_BIN"]
THRESHOLDS = json.loads((SOURCE / "client/validate/thresholds.json").read_text())
DETECT = THRESHOLDS["detection"]
REPOSE_DEG = 33.0  # model.repose_deg's default ([N24] 3.8)
LINEAR_STEPS = 400


def run_twin(name, out, steps, snapshot_every, **domain):
    job = json.loads((SOURCE / "examples" / name).read_text())
    job["run"].update({"steps": steps, "snapshot_every": snapshot_every, "checkpoint_every": 0})
    job["domain"].update(domain)
    path = out / name
    path.write_text(json.dumps(job))
    subprocess.run([ERG, "run", str(path), "--out", str(out / "run"), "--threads", "2"],
                   check=True, capture_output=True, text=True, timeout=600)
    snaps = sorted((out / "run" / "snapshots").glob("step_*.h5"))
    return [measure.load_snapshot(p) for p in snaps]


class ExpectedBarchans(unittest.TestCase):
    def test_pile_becomes_crescents_with_slip_faces(self):
        with tempfile.TemporaryDirectory() as tmp:
            snaps = run_twin("barchans_expected.json", Path(tmp), 200, 100)
        last = snaps[-1]
        cell = last["cell_size_m"]
        height = last["sand"] + last["bedrock"]
        bodies = measure.dunes(last["sand"], cell, DETECT["dune_sand_threshold_m"],
                               DETECT["dune_min_cells"])
        self.assertGreater(len(bodies), 0, "no dune left")
        crescents = []
        for d in bodies:
            shape = measure.barchan_shape(d, last["sand"], cell, 0.0)
            own = last["sand"] * 0.0
            own[d["iy"], d["ix"]] = last["sand"][d["iy"], d["ix"]]
            lee = measure.lee_slopes_deg(height, own, cell, 0.0, 0.05)
            slip = lee.size > 0 and lee.max() >= REPOSE_DEG - 3.0
            print(f"body H {shape['height_m']:.2f} m W {shape['width_m']:.0f} m "
                  f"H/W {shape['aspect']:.3f} horn offset {shape['horn_offset_m']:+.1f} m "
                  f"slip face {slip}")
            if shape["horns_downwind"] and slip:
                crescents.append(shape)
        # Most bodies, the largest among them, are crescents.
        self.assertGreaterEqual(len(crescents), (len(bodies) + 1) // 2)
        largest = measure.barchan_shape(bodies[0], last["sand"], cell, 0.0)
        self.assertTrue(largest["horns_downwind"], largest)
        # Sand is conserved to the unit on the way (no event adds any).
        totals = {s["sand_units_total"] + s["airborne_units_total"] for s in snaps}
        self.assertEqual(len(totals), 1, totals)


class ExpectedTransverse(unittest.TestCase):
    def test_flat_bed_grows_transverse_crests(self):
        with tempfile.TemporaryDirectory() as tmp:
            snaps = run_twin("transverse_expected.json", Path(tmp), 500, 250, nx=128, ny=128)
        first, last = snaps[0], snaps[-1]
        relief = lambda s: float((s["sand"] + s["bedrock"]).max() - (s["sand"] + s["bedrock"]).min())
        o = measure.structure_orientation(last["sand"] + last["bedrock"], last["cell_size_m"])
        angle = measure.crest_wind_angle(o["crest_deg"], 0.0)
        print(f"relief {relief(first):.2f} -> {relief(last):.2f} m, crest-wind angle "
              f"{angle:.1f} deg, coherence {o['coherence']:.2f}")
        self.assertGreater(relief(last), 3.0 * relief(first))  # the bed is unstable: dunes grow
        self.assertGreater(o["coherence"], 0.5)  # parallel ridges, not blobs
        self.assertLessEqual(abs(angle - 90.0), 10.0)  # crests across the wind


class ExpectedLinear(unittest.TestCase):
    def test_patches_grow_linear_dunes_along_the_resultant(self):
        # Two winds 120 deg apart with equal fluxes: both modes of Courrech du
        # Pont, Narteau & Gao 2014 put the dunes along the resultant (theta >
        # 90 deg, N = 1), the bisector of the two winds.
        job = json.loads((SOURCE / "examples" / "linear_expected.json").read_text())
        b = job["wind"]["bidirectional"]
        winds = measure.two_winds(b["direction_deg"], b["angle_deg"], b["flux_ratio"])
        expected = measure.fingering_orientation(winds) % 180.0
        self.assertLess(measure.axis_difference(measure.bed_instability_orientation(winds), expected), 1e-6)
        with tempfile.TemporaryDirectory() as tmp:
            snaps = run_twin("linear_expected.json", Path(tmp), LINEAR_STEPS, LINEAR_STEPS // 2,
                             nx=128, ny=128)
        O = THRESHOLDS["orientation"]
        first, last = snaps[0], snaps[-1]
        _, elong0 = measure.autocorrelation_axis(first["sand"], first["cell_size_m"])
        axis, elong = measure.autocorrelation_axis(last["sand"], last["cell_size_m"])
        diff = measure.axis_difference(axis, expected)
        print(f"elongation {elong0:.2f} -> {elong:.2f} times as long as wide, axis {axis:.1f} deg "
              f"(resultant {expected:.1f} deg, {diff:.1f} deg off)")
        self.assertLess(elong0, O["min_elongation"])  # the round patches have no axis
        self.assertGreaterEqual(elong, O["min_elongation"])  # the dunes are elongated
        self.assertLessEqual(diff, O["tolerance_deg"])  # along the resultant
        totals = {s["sand_units_total"] + s["airborne_units_total"] for s in snaps}
        self.assertEqual(len(totals), 1, totals)


if __name__ == "__main__":
    unittest.main()

# SPDX-License-Identifier: Apache-2.0
"""erg validate's scenes as `erg check` sees them: every scene of the full and
the quick suite is a valid job, and none is warned that its step is too
large for the shear stress over relief (sim/resolution.h, step_warning):
a scene whose dunes spread with the step would measure the step, not the
model (docs/physical-units.md, "The step with the stress on"), nor that its
two winds cannot both blow in every period (sim/resolution.h,
wind_period_warnings)."""
import json
import os
import re
import subprocess
import tempfile
import unittest
from pathlib import Path

import numpy as np

ERG = os.environ["ERG_BIN"]
SCENES = Path(os.environ["ERG_SOURCE_DIR"]) / "client" / "validate" / "scenes"


class Scenes(unittest.TestCase):
    def test_every_scene_is_valid_and_its_step_resolved(self):
        paths = sorted(SCENES.glob("*/*.json"))
        self.assertGreaterEqual(len(paths), 20)
        for p in paths:
            with self.subTest(scene=str(p.relative_to(SCENES))):
                r = subprocess.run([ERG, "check", str(p)], capture_output=True, text=True,
                                   timeout=60)
                self.assertEqual(r.returncode, 0, r.stderr[-2000:])
                self.assertNotIn("the step's lift", r.stderr)
                # Two winds alternate in every period of a two-wind scene.
                self.assertNotIn("cannot blow in every period", r.stderr)

    def test_the_isotropy_scenes_are_one_scene_in_both_modes(self):
        # Section 9 compares the two transport modes on the same pile: each
        # EXPECTED isotropy scene is its STOCHASTIC twin with only the name
        # and the transport changed, so an edit to one cannot leave the other
        # behind (docs/dune-forms.md, "EXPECTED at the STOCHASTIC scene's
        # settings").
        for angle in (0, 23, 37, 45):
            with self.subTest(angle=angle):
                stochastic = json.loads((SCENES / "full" / f"isotropy_{angle:02d}.json").read_text())
                expected = json.loads((SCENES / "full" / f"isotropy_{angle:02d}_expected.json").read_text())
                self.assertEqual(stochastic["transport"], "STOCHASTIC")
                self.assertEqual(expected["transport"], "EXPECTED")
                self.assertEqual(expected["name"], stochastic["name"] + "-expected")
                self.assertEqual(dict(expected, name=None, transport=None),
                                 dict(stochastic, name=None, transport=None))

    def assert_quarter_step_twins(self, stochastic, expected):
        """The STOCHASTIC scene is named and run as its EXPECTED twin at a
        quarter of the step: four times the steps over the same years."""
        self.assertEqual((stochastic["transport"], expected["transport"]), ("STOCHASTIC", "EXPECTED"))
        self.assertEqual(expected["name"], stochastic["name"] + "-expected")
        self.assertEqual(stochastic["model"]["slab_m"] * 4, expected["model"]["slab_m"])
        for key in ("steps", "snapshot_every"):
            self.assertEqual(stochastic["run"][key], 4 * expected["run"][key])

    def test_the_fingering_scenes_are_one_scene_in_both_modes(self):
        # Each STOCHASTIC fed source is its EXPECTED twin at a quarter of the
        # step (1/160 of the cell, where the stochastic form converges; the
        # deterministic one does at 1/40): the same years, wind periods and
        # feed in physical time, everything else equal.
        for case in ("120_1", "140_2", "160_5"):
            with self.subTest(case=case):
                stochastic = json.loads((SCENES / "full" / f"orientation_finger_{case}.json").read_text())
                expected = json.loads((SCENES / "full" / f"orientation_finger_{case}_expected.json").read_text())
                self.assert_quarter_step_twins(stochastic, expected)
                b = stochastic["wind"]["bidirectional"]
                self.assertEqual(b["period_steps"], 4 * expected["wind"]["bidirectional"]["period_steps"])
                self.assertEqual(stochastic["events"],
                                 [dict(e, step=4 * e["step"]) for e in expected["events"]])
                same = lambda j: dict(j, name=None, transport=None, events=None, run=None,
                                      model=dict(j["model"], slab_m=None),
                                      wind=dict(j["wind"], bidirectional=dict(j["wind"]["bidirectional"],
                                                                              period_steps=None)))
                self.assertEqual(same(stochastic), same(expected))

    def test_the_bed_isotropy_scenes_are_one_bed_turned(self):
        # Section 11 compares one bed under one wind turned to 0, 23, 37 and
        # 45 deg: the scenes differ in the wind's direction alone, and each
        # STOCHASTIC scene is its EXPECTED twin at a quarter of the step.
        expected = {a: json.loads((SCENES / "full" / f"isotropy_bed_{a:02d}_expected.json").read_text())
                    for a in (0, 23, 37, 45)}
        stochastic = {a: json.loads((SCENES / "full" / f"isotropy_bed_{a:02d}.json").read_text())
                      for a in (0, 23, 37, 45)}
        for a in (0, 23, 37, 45):
            with self.subTest(angle=a):
                e, st = expected[a], stochastic[a]
                self.assertEqual(e["wind"]["constant"]["direction_deg"], a)
                self.assertEqual(st["wind"], e["wind"])
                turned = lambda j: dict(j, name=None, wind=dict(j["wind"], constant=dict(
                    j["wind"]["constant"], direction_deg=None)))
                self.assertEqual(turned(e), turned(expected[0]))
                self.assert_quarter_step_twins(st, e)
                quarter = lambda j: dict(j, name=None, transport=None, run=None,
                                         model=dict(j["model"], slab_m=None))
                self.assertEqual(quarter(st), quarter(e))

    def test_the_transverse_beds_are_one_bed_at_halved_cells(self):
        # Section 4's wavelength law compares one bed at halved cells: the
        # same torus in metres, the slab and the longest hop the same share
        # of a cell, the same years (twice the steps per halving), and
        # everything else equal. The wide bed for the crests is the coarsest
        # one on a torus wide enough to judge them. Each is the EXPECTED
        # one-wind isotropy bed (section 11) on cells that resolve its hop:
        # `erg check` warns of no length lost to the grid there, and does on
        # the 2 m isotropy bed (docs/dune-forms.md, "On cells that resolve
        # the hop").
        full = SCENES / "full"
        beds = [json.loads((full / f"transverse_{n}.json").read_text()) for n in ("coarse", "fine", "finest")]
        crests = json.loads((full / "transverse_crests.json").read_text())
        bed = json.loads((full / "isotropy_bed_00_expected.json").read_text())
        size = lambda j: (j["domain"]["nx"] * j["domain"]["cell_size_m"], j["domain"]["ny"] * j["domain"]["cell_size_m"])
        share = lambda j: {k: round(j["model"][k] / j["domain"]["cell_size_m"], 9) for k in ("slab_m", "max_hop_m")}
        rest = lambda j: dict(j, name=None, domain=None, run=None, model=dict(j["model"], slab_m=None, max_hop_m=None))
        for a, b in zip(beds, beds[1:]):
            self.assertEqual(b["domain"]["cell_size_m"] * 2, a["domain"]["cell_size_m"])
            self.assertEqual(size(a), size(b))
            self.assertEqual(share(a), share(b))
            self.assertEqual({k: 2 * v for k, v in a["run"].items() if k != "previews"},
                             {k: v for k, v in b["run"].items() if k != "previews"})
        for j in beds + [crests]:
            self.assertEqual(rest(j), rest(bed))
            self.assertEqual(share(j), {"slab_m": 1 / 40, "max_hop_m": 16})
        self.assertEqual(dict(crests, name=None, domain=None), dict(beds[0], name=None, domain=None))
        self.assertEqual(crests["domain"]["cell_size_m"], beds[0]["domain"]["cell_size_m"])
        self.assertGreater(size(crests)[1], 10 * size(beds[0])[1])
        lost = "(resolved at domain.cell_size_m <="
        for p in [full / f"transverse_{n}.json" for n in ("coarse", "fine", "finest", "crests")]:
            r = subprocess.run([ERG, "check", str(p)], capture_output=True, text=True, timeout=60)
            self.assertEqual(r.returncode, 0, r.stderr[-2000:])
            self.assertNotIn(lost, r.stderr, p.name)
        r = subprocess.run([ERG, "check", str(full / "isotropy_bed_00_expected.json")], capture_output=True,
                           text=True, timeout=60)
        self.assertIn("the saltation hop", r.stderr)
        self.assertIn(lost, r.stderr)

    def test_the_fed_sources_supply_the_law_s_flux_across_their_width(self):
        # The fingering scenes (physical units) feed their source with what
        # a saturated flux carries across its width, Q_sat 2 R: the feed is
        # set from the flux law and the calibration that `erg check`
        # prints, not chosen for the orientation it gives.
        paths = sorted((SCENES / "full").glob("orientation_finger_*.json"))
        self.assertEqual(len(paths), 6)
        for p in paths:
            with self.subTest(scene=p.name):
                job = json.loads(p.read_text())
                r = subprocess.run([ERG, "check", str(p)], capture_output=True, text=True,
                                   timeout=60)
                self.assertEqual(r.returncode, 0, r.stderr[-2000:])
                m = re.search(r"the law's ([0-9.e+]+) m\^2/yr: .* \(([0-9.e+]+) steps per year\)",
                              r.stderr)
                self.assertIsNotNone(m, r.stderr[-2000:])
                q_sat, steps_per_year = float(m.group(1)), float(m.group(2))
                feeds = [e for e in job["events"] if "sand" in e]
                self.assertGreater(len(feeds), 10)
                every = feeds[1]["step"] - feeds[0]["step"]
                b = feeds[0]["sand"]
                # The brush: full height inside radius - falloff, smoothstep
                # to 0 at the radius (proto/erg/v1/job.proto, Brush).
                radius, falloff = b["radius_m"], b["falloff_m"]
                rr = np.linspace(0.0, radius, 200001)
                t = np.clip((radius - rr) / falloff, 0.0, 1.0)
                volume = b["height"] * np.trapz(t * t * (3 - 2 * t) * 2 * np.pi * rr, rr)
                supply = volume * steps_per_year / every
                self.assertAlmostEqual(supply / (q_sat * 2 * radius), 1.0, delta=0.05)

    def test_a_large_step_with_the_stress_is_warned(self):
        # The check above can fail: the barchan scene with the step it had
        # before is warned, naming the field and the largest slab allowed.
        job = json.loads((SCENES / "full" / "barchans.json").read_text())
        job["model"]["slab_m"] = 0.05
        with tempfile.TemporaryDirectory() as d:
            p = Path(d) / "job.json"
            p.write_text(json.dumps(job))
            r = subprocess.run([ERG, "check", str(p)], capture_output=True, text=True, timeout=60)
        self.assertEqual(r.returncode, 0, r.stderr[-2000:])
        self.assertIn("the step's lift, model.slab_m = 0.05 m", r.stderr)
        self.assertIn("they stop at model.slab_m <= 0.025 m", r.stderr)


if __name__ == "__main__":
    unittest.main()

# SPDX-License-Identifier: Apache-2.0
"""ParaView opens erg's XDMF as its users expect: each snapshot in the X-Y
plane with node data at the cell centres, height ready for Warp By Scalar
along +Z, DIR/run.xdmf one animated run, and DIR/overview.xdmf the run at its
overview level. ParaView's own pvbatch reads the
files (tests/formats/pv_inspect.py) and what it sees is checked against the
snapshots read by h5py. A warped, coloured screenshot is rendered under
an Xvfb of the test's own (paraview_batch.py; ERG_PARAVIEW_SCREENSHOT=FILE
keeps a copy; README's docs/paraview.png is made that way)."""
import os
import shutil
import tempfile
import unittest

import h5py
import numpy as np
from PIL import Image

import run_helper as R
from paraview_batch import inspect as pvbatch


class ParaView(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        for tool in ("pvbatch", "Xvfb"):
            if not shutil.which(tool):
                raise AssertionError(f"{tool} not found: run deploy/bootstrap.sh")
        cls.tmp = tempfile.TemporaryDirectory(prefix="erg_paraview_")
        cls.run_dir = R.make_run(cls.tmp.name)
        cls.snaps = R.snapshots(cls.run_dir)
        cls.files = [R.read(p) for _, p in cls.snaps]
        cls.shot = os.path.join(cls.tmp.name, "shot.png")
        cls.seen = pvbatch(os.path.join(cls.run_dir, "run.xdmf"), cls.shot)

    @classmethod
    def tearDownClass(cls):
        cls.tmp.cleanup()

    def check_step(self, seen, h):
        half = R.CELL / 2
        # The X-Y plane, z = 0, one node per cell centre.
        self.assertEqual(seen["type"], "vtkImageData")
        self.assertEqual(seen["dimensions"], [R.NX, R.NY, 1])
        self.assertEqual(seen["bounds"], [half, R.NX * R.CELL - half, half, R.NY * R.CELL - half,
                                          0.0, 0.0])
        arrays = seen["arrays"]
        self.assertEqual(set(arrays), {"height", "bedrock", "sand", "vegetation", "wind",
                                       "airborne", "shadow", "obstacles", "deposited_m"})
        for name in ("bedrock", "sand", "vegetation", "airborne", "shadow", "obstacles",
                     "deposited_m"):
            a = arrays[name]
            self.assertEqual((a["components"], a["tuples"]), (1, R.NX * R.NY), name)
            self.assertEqual(a["range"][0], [float(h[name].min()), float(h[name].max())], name)
        np.testing.assert_allclose(arrays["height"]["range"][0],
                                   [h["height"].min(), h["height"].max()], rtol=0, atol=1e-5)
        wind = arrays["wind"]
        self.assertEqual(wind["components"], 3)
        self.assertEqual(wind["range"][0], [float(h["wind_x"].min()), float(h["wind_x"].max())])
        self.assertEqual(wind["range"][1], [float(h["wind_y"].min()), float(h["wind_y"].max())])
        self.assertEqual(wind["range"][2], [0.0, 0.0])
        # Point (i, j) is cell (i, j): x east, y north, row 0 south.
        for key, s in seen["samples"].items():
            i, j = map(int, key.split(","))
            self.assertEqual(s["point"], [(i + 0.5) * R.CELL, (j + 0.5) * R.CELL, 0.0], key)
            self.assertEqual(s["sand"], float(h["sand"][j, i]), key)
            self.assertAlmostEqual(s["height"], float(h["height"][j, i]), places=5)
            self.assertEqual(s["wind"][:2], [float(h["wind_x"][j, i]), float(h["wind_y"][j, i])])
        # Warp By Scalar (height, scale 1) lifts along +Z to the heights.
        wb = seen["warped_bounds"]
        self.assertEqual(wb[:4], seen["bounds"][:4])
        self.assertAlmostEqual(wb[4], float(h["height"].min()), places=4)
        self.assertAlmostEqual(wb[5], float(h["height"].max()), places=4)

    def test_run_xdmf_is_the_run_in_time(self):
        want = [float(h["time"][0]) for h in self.files]
        self.assertEqual(want, [10.0 * s for s, _ in self.snaps])
        self.assertEqual(self.seen["times"], want)
        self.assertEqual(len(self.seen["steps"]), len(self.files))
        for seen, h in zip(self.seen["steps"], self.files):
            with self.subTest(time=seen["time"]):
                self.check_step(seen, h)
        # The steps differ: ParaView shows each file, not the first one again.
        self.assertNotEqual(self.seen["steps"][0]["arrays"]["sand"]["range"],
                            self.seen["steps"][-1]["arrays"]["sand"]["range"])

    def test_each_snapshot_opens_alone(self):
        step, path = self.snaps[-1]
        seen = pvbatch(path[:-3] + ".xdmf")
        self.assertEqual(seen["times"], [10.0 * step])
        self.check_step(seen["steps"][0], self.files[-1])

    def test_overview_xdmf_is_the_run_at_its_preview_level(self):
        # DIR/overview.xdmf: every snapshot's overview level (the preview's,
        # at least 1), a point per block, so a run too large for ParaView
        # still opens. 96 x 64 cells: every block of level 1 is whole.
        seen = pvbatch(os.path.join(self.run_dir, "overview.xdmf"))
        self.assertEqual(seen["times"], [float(h["time"][0]) for h in self.files])
        for (_, path), step in zip(self.snaps, seen["steps"]):
            with h5py.File(path, "r") as f:
                g = f["overview/level_1"]
                x, y = g["x"][...], g["y"][...]
                layers = {n: g[n][0] for n in ("bedrock", "sand", "vegetation")}
            with self.subTest(path=path):
                self.assertEqual(step["type"], "vtkImageData")
                self.assertEqual(step["dimensions"], [len(x), len(y), 1])
                self.assertEqual(step["bounds"], [x[0], x[-1], y[0], y[-1], 0.0, 0.0])
                self.assertEqual(set(step["arrays"]), {"height", "bedrock", "sand", "vegetation"})
                for n, v in layers.items():
                    self.assertEqual(step["arrays"][n]["range"][0], [float(v.min()), float(v.max())])
                # Block (i, j) is at its centre, from the level's own coordinates.
                i, j = len(x) // 3, len(y) // 2
                s = step["samples"]["%d,%d" % (i, j)]
                self.assertEqual(s["point"], [x[i], y[j], 0.0])
                self.assertEqual(s["sand"], float(layers["sand"][j, i]))

    def test_screenshot_is_a_picture(self):
        img = np.asarray(Image.open(self.shot).convert("RGB")).astype(int)
        self.assertEqual(img.shape, (800, 1200, 3))
        # Not blank: the terrain covers a good part of the frame in many colours.
        non_white = (img < 250).any(axis=2).mean()
        self.assertGreater(non_white, 0.15)
        self.assertGreater(len(np.unique(img.reshape(-1, 3), axis=0)), 500)
        keep = os.environ.get("ERG_PARAVIEW_SCREENSHOT")
        if keep:
            shutil.copyfile(self.shot, keep)


if __name__ == "__main__":
    unittest.main()

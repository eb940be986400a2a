# SPDX-License-Identifier: Apache-2.0
"""Snapshots as netCDF-4 with CF metadata, read by tools erg did not write:
xarray over h5netcdf (open_mfdataset of a whole run) and ncdump."""
import glob
import os
import re
import subprocess
import tempfile
import unittest

import numpy as np
import xarray as xr

import run_helper as R


class NetCdf(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.TemporaryDirectory(prefix="erg_netcdf_")
        cls.run_dir = R.make_run(cls.tmp.name)
        cls.snaps = R.snapshots(cls.run_dir)

    @classmethod
    def tearDownClass(cls):
        cls.tmp.cleanup()

    def test_open_mfdataset_gives_time_y_x(self):
        ds = xr.open_mfdataset(os.path.join(self.run_dir, "snapshots", "*.h5"), engine="h5netcdf")
        self.assertEqual(dict(ds.sizes), {"time": len(self.snaps), "y": R.NY, "x": R.NX})
        for name in R.LAYERS:
            self.assertEqual(ds[name].dims, ("time", "y", "x"), name)
        # Coordinates: cell centres in metres, simulated days as plain floats
        # (the job's 10 days per step).
        np.testing.assert_array_equal(ds.x.values, (np.arange(R.NX) + 0.5) * R.CELL)
        np.testing.assert_array_equal(ds.y.values, (np.arange(R.NY) + 0.5) * R.CELL)
        self.assertEqual(ds.time.dtype, np.float64)
        np.testing.assert_array_equal(ds.time.values, [10.0 * s for s, _ in self.snaps])
        self.assertEqual(ds.x.attrs["units"], "m")
        self.assertEqual(ds.x.attrs["standard_name"], "projection_x_coordinate")
        self.assertEqual(ds.y.attrs["axis"], "Y")
        self.assertEqual(ds.time.attrs["standard_name"], "time")
        # Variables: units and long names everywhere, standard names where CF has one.
        want = {"bedrock": "m", "sand": "m", "vegetation": "1", "wind_x": "m s-1",
                "wind_y": "m s-1", "airborne": "m", "shadow": "1", "obstacles": "m",
                "deposited_m": "m"}
        for name, units in want.items():
            self.assertEqual(ds[name].attrs["units"], units, name)
            self.assertTrue(ds[name].attrs["long_name"], name)
        self.assertEqual(ds.wind_x.attrs["standard_name"], "eastward_wind")
        self.assertEqual(ds.wind_y.attrs["standard_name"], "northward_wind")
        self.assertEqual(ds.vegetation.attrs["standard_name"], "vegetation_area_fraction")
        self.assertEqual(ds.attrs["Conventions"], "CF-1.10")
        # The values are the file's, in the right order: a point by label.
        for k, (step, path) in enumerate(self.snaps):
            h = R.read(path)
            got = ds.sand.sel(time=10.0 * step, x=(5 + 0.5) * R.CELL, y=(7 + 0.5) * R.CELL)
            self.assertEqual(float(got), float(h["sand"][7, 5]))
            np.testing.assert_array_equal(ds.wind_y.isel(time=k).values, h["wind_y"])
        # The run's sand volume in m^3 from the labelled data, as a reader would.
        vol = (ds.sand * R.CELL * R.CELL).sum(dim=("y", "x")).values
        self.assertTrue(np.all(vol > 0))
        ds.close()

    def test_ncdump_shows_real_dimensions(self):
        p = subprocess.run(["ncdump", "-h", self.snaps[-1][1]], capture_output=True, text=True,
                           timeout=60)
        self.assertEqual(p.returncode, 0, p.stderr)
        out = p.stdout
        self.assertNotIn("phony_dim", out)
        dims = out[out.index("dimensions:"):out.index("variables:")]
        self.assertRegex(dims, r"time = 1 ;")
        self.assertRegex(dims, rf"x = {R.NX} ;")
        self.assertRegex(dims, rf"y = {R.NY} ;")
        for name in R.LAYERS:
            self.assertRegex(out, rf"float {name}\(time, y, x\) ;")
        self.assertRegex(out, r"double x\(x\) ;")
        self.assertRegex(out, r'string sand:units = "m" ;')
        self.assertRegex(out, r'string wind_x:standard_name = "eastward_wind" ;')
        self.assertRegex(out, r':Conventions = "CF-1.10" ;')
        # ncdump reads the data too: the coordinate values.
        p = subprocess.run(["ncdump", "-v", "x", self.snaps[-1][1]], capture_output=True,
                           text=True, timeout=60)
        self.assertEqual(p.returncode, 0, p.stderr)
        xs = re.search(r"x = ([^;]*);", p.stdout.split("data:")[1]).group(1)
        self.assertEqual([float(v) for v in xs.split(",")][:3], [1.0, 3.0, 5.0])


if __name__ == "__main__":
    unittest.main()

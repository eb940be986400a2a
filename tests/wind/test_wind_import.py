# SPDX-License-Identifier: Apache-2.0
"""erg wind import on records written here in the layouts it reads.

CSV records (time,u,v and time,speed,direction) and ERA5 single-levels
netCDF4 files (u10/v10 over time or valid_time, latitude, longitude, packed
as int16 with scale_factor/add_offset as the CDS delivers them), written by
xarray + h5netcdf, are imported; the series and roses are checked against
the record, the printed DP/RDP/RDD against the Fryberger & Dean sums
recomputed here from the flux law and the physics that erg check prints,
the fragment merged into an example job must pass erg check, the sand-rose
PNG is read back with PIL, and bad input must fail with a message naming
the line or field and leave no output file.
"""
import csv
import json
import math
import os
import re
import subprocess
import tempfile
import unittest

import numpy as np
import pandas as pd
import xarray as xr
from PIL import Image

HERE = os.path.dirname(os.path.abspath(__file__))
BIN = os.environ.get("ERG_BIN_DIR", os.path.join(HERE, "../../build/bin"))
ERG = os.path.join(BIN, "erg")
EXAMPLE = os.path.join(HERE, "../../examples/barchans.json")
PETAL = (196, 128, 56)  # the petal colour of io::write_sand_rose_png
RESULTANT = (40, 70, 160)  # its resultant-drift line
YEAR_S = 3.15576e7


def erg(*args, check=True, cwd=None):
    p = subprocess.run([ERG, *args], capture_output=True, text=True, timeout=120, cwd=cwd)
    if check and p.returncode != 0:
        raise AssertionError(f"erg {' '.join(args)} exited {p.returncode}:\n{p.stdout}\n{p.stderr}")
    return p


def write_csv(path, header, rows):
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(header)
        w.writerows(rows)


def hours(n, start="2024-03-01T00:00:00Z"):
    t0 = pd.Timestamp(start)
    return [(t0 + pd.Timedelta(hours=k)).strftime("%Y-%m-%dT%H:%M:%SZ") for k in range(n)]


def write_era5(path, u, v, lat, lon, time_name="valid_time", packed=True):
    """An ERA5 single-levels file: u10/v10 (time, latitude, longitude)."""
    nt = u.shape[0]
    times = pd.date_range("2024-01-01", periods=nt, freq="h")
    ds = xr.Dataset(
        {"u10": ((time_name, "latitude", "longitude"), u.astype("f4"),
                 {"units": "m s**-1", "long_name": "10 metre U wind component"}),
         "v10": ((time_name, "latitude", "longitude"), v.astype("f4"),
                 {"units": "m s**-1", "long_name": "10 metre V wind component"})},
        coords={time_name: times, "latitude": ("latitude", lat), "longitude": ("longitude", lon)})
    enc = {time_name: {"units": "hours since 1900-01-01 00:00:00.0" if time_name == "time"
                       else "seconds since 1970-01-01", "dtype": "int64"}}
    if packed:
        for name in ("u10", "v10"):
            a = ds[name].values
            off = (a.max() + a.min()) / 2
            scale = max((a.max() - a.min()) / 65000, 1e-4)
            enc[name] = {"dtype": "int16", "scale_factor": float(scale), "add_offset": float(off),
                         "_FillValue": np.int16(-32767)}
    ds.to_netcdf(path, engine="h5netcdf", encoding=enc)
    return ds


def physics_of(job_path):
    """The sand of a job as erg check prints it, defaults filled."""
    spec = json.loads(erg("check", job_path).stdout)
    return spec["physics"], spec


def flux_bulk(ph, ustar):
    """Lettau & Lettau 1978 bulk flux, m^2/s (docs/physical-units.md)."""
    d, rho_s, rho, g = ph["grain_diameter_m"], ph["grain_density_kg_m3"], ph["air_density_kg_m3"], ph["gravity_m_s2"]
    ut = ph["threshold_a"] * math.sqrt((rho_s - rho) / rho * g * d)
    if ustar <= ut:
        return 0.0
    q = 4.2 * math.sqrt(d / 0.25e-3) * rho / g * ustar ** 2 * (ustar - ut)
    return q / (ph["packing_fraction"] * rho_s)


def drift(ph, winds, height=10.0, z0=0.0):
    """DP, RDP (m^3/m/yr) and RDD (deg ccw from +x) of (towards_deg, speed, weight)."""
    z0 = z0 or ph["grain_diameter_m"] / 30
    k = ph["von_karman"] / math.log(height / z0)
    dp = rx = ry = 0.0
    for d, s, w in winds:
        q = w * flux_bulk(ph, k * s)
        dp += q
        rx += q * math.cos(math.radians(d))
        ry += q * math.sin(math.radians(d))
    return dp * YEAR_S, math.hypot(rx, ry) * YEAR_S, math.degrees(math.atan2(ry, rx))


def printed_drift(stderr, which):
    m = re.search(rf"drift \({which}\): DP (\S+) m\^3/m/yr, RDP (\S+) m\^3/m/yr, RDP/DP \S+, RDD (\S+) deg",
                  stderr)
    assert m, stderr
    return tuple(float(x) for x in m.groups())


def petal_pixels(png, colour=PETAL):
    img = np.asarray(Image.open(png).convert("RGB")).astype(int)
    ys, xs = np.nonzero(np.all(img == colour, axis=2))
    return img.shape, xs, ys


def longest_petal_bearing(png):
    """Compass bearing (clockwise from north = up) of the longest petal: the
    middle of the petal pixels in the outer tenth of the longest reach."""
    (h, w, _), xs, ys = petal_pixels(png)
    c = (w - 1) / 2
    dx, dy = xs - c, c - ys
    r = np.hypot(dx, dy)
    tip = r > 0.9 * r.max()
    return math.degrees(math.atan2(dx[tip].mean(), dy[tip].mean())) % 360


def angle_diff(a, b):
    return abs((a - b + 180) % 360 - 180)


class WindImport(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory()
        self.d = self.tmp.name
        self.ph, _ = physics_of(self.merged({"wind": {"constant": {"speed_mps": 10}, "speed_is": "WIND_AT_HEIGHT"}}))

    def tearDown(self):
        self.tmp.cleanup()

    def p(self, name):
        return os.path.join(self.d, name)

    def merged(self, fragment, name="merged.json"):
        with open(EXAMPLE) as f:
            job = json.load(f)
        job.update(fragment)
        path = os.path.join(self.d, name)
        with open(path, "w") as f:
            json.dump(job, f)
        return path

    def assert_checks(self, fragment):
        p = erg("check", self.merged(fragment), check=False)
        self.assertEqual(p.returncode, 0, p.stderr)
        return json.loads(p.stdout)

    def test_westerly_blows_towards_plus_x(self):
        """A wind from the west (meteorological 270, u > 0) is an erg wind towards +x."""
        n = 6
        write_csv(self.p("sd.csv"), ["time", "speed", "direction"], [[t, 12, 270] for t in hours(n)])
        write_csv(self.p("uv.csv"), ["time", "u", "v"], [[t, 12, 0] for t in hours(n)])
        for name in ("sd.csv", "uv.csv"):
            p = erg("wind", "import", self.p(name), "--format", "csv", "--step-hours", "1",
                    "--png", self.p(name + ".png"))
            wind = json.loads(p.stdout)["wind"]
            self.assertEqual(wind["speed_is"], "WIND_AT_HEIGHT")
            self.assertEqual(wind["height_m"], 10)
            kf = wind["series"]["keyframes"]
            self.assertEqual([k["step"] for k in kf], list(range(n)))
            for k in kf:
                self.assertAlmostEqual(k["speed_mps"], 12, places=5)
                self.assertAlmostEqual(k.get("direction_deg", 0), 0, places=5)
            dp, rdp, rdd = printed_drift(p.stderr, "record")
            self.assertAlmostEqual(rdd, 0, places=5)
            self.assertAlmostEqual(rdp / dp, 1, places=9)
            # The sand rose's petal points where the wind comes from: west.
            self.assertLess(angle_diff(longest_petal_bearing(self.p(name + ".png")), 270), 3)
            self.assert_checks({"wind": wind})

    def test_rose_and_drift_potentials(self):
        rng = np.random.default_rng(5)
        n = 240
        speed = np.round(rng.uniform(2, 16, n), 3)
        # Mostly from the north-east, some from the south.
        direction = np.where(rng.uniform(size=n) < 0.7, rng.normal(45, 10, n), rng.normal(180, 15, n)) % 360
        direction = np.round(direction, 3)
        write_csv(self.p("rec.csv"), ["time", "speed", "direction"],
                  [[t, s, d] for t, s, d in zip(hours(n), speed, direction)])
        p = erg("wind", "import", self.p("rec.csv"), "--format", "csv", "--rose", "--roughness", "0.001",
                "--height", "10", "--out", self.p("rose.json"), "--png", self.p("rose.png"))
        self.assertEqual(p.stdout, "")
        with open(self.p("rose.json")) as f:
            frag = json.load(f)
        rose = frag["wind"]["rose"]
        self.assertEqual(frag["wind"]["roughness_m"], 0.001)
        self.assertAlmostEqual(sum(e["probability"] for e in rose["entries"]), 1, places=9)
        self.assertEqual(rose["sector_width_deg"], 22.5)
        # The record hour by hour, recomputed here: towards = from + 180.
        towards = [(90 - (d + 180), s, 1 / n) for s, d in zip(speed, direction)]
        want = drift(self.ph, towards, 10, 0.001)
        got = printed_drift(p.stderr, "record")
        self.assertAlmostEqual(got[0] / want[0], 1, places=6)
        self.assertAlmostEqual(got[1] / want[1], 1, places=6)
        self.assertLess(angle_diff(got[2], want[2]), 1e-4)
        # The rose's own DP from its entries; close to the record's (the
        # sectors' spread and mean speeds differ by little).
        want_rose = drift(self.ph, [(e.get("direction_deg", 0), e["speed_mps"], e["probability"])
                                    for e in rose["entries"]], 10, 0.001)
        got_rose = printed_drift(p.stderr, "rose")
        self.assertAlmostEqual(got_rose[0] / want_rose[0], 1, places=5)
        self.assertAlmostEqual(got_rose[1] / want_rose[1], 1, places=5)
        self.assertLess(abs(got_rose[0] / got[0] - 1), 0.1)
        # Sand moves south-west (towards 225 compass = -135 deg ccw from +x).
        self.assertLess(angle_diff(got[2], -135), 45)
        # The rose as printed: the NE sector carries the most hours.
        ne = re.search(r"^  NE\s+45\.0 deg\s+(\S+)%", p.stderr, re.M)
        self.assertIsNotNone(ne, p.stderr)
        share = np.mean(np.round(direction / 22.5) % 16 == 2) * 100
        self.assertAlmostEqual(float(ne.group(1)), share, places=1)
        # Calms: in the rose as speed 0, in no sector.
        write_csv(self.p("calm.csv"), ["time", "u", "v"], [[t, 0 if k % 4 else 9, 0] for k, t in enumerate(hours(8))])
        c = erg("wind", "import", self.p("calm.csv"), "--format", "csv", "--rose", "--png", self.p("c.png"))
        self.assertIn("  calm 75%", c.stderr)
        self.assertRegex(c.stderr, r"  W   270\.0 deg\s+25\.0%")
        entries = json.loads(c.stdout)["wind"]["rose"]["entries"]
        self.assertEqual(sorted((e.get("speed_mps", 0), e["probability"]) for e in entries), [(0, 0.75), (9, 0.25)])
        # The rose PNG: square, north marker black at the top middle, longest
        # petal towards the north-east.
        img = Image.open(self.p("rose.png"))
        self.assertEqual(img.size, (400, 400))
        self.assertEqual(img.convert("RGB").getpixel((200, 5)), (0, 0, 0))
        self.assertLess(angle_diff(longest_petal_bearing(self.p("rose.png")), 45), 12)
        # The resultant line: towards the RDD (compass 90 - RDD), RDP/DP long.
        (h, w, _), xs, ys = petal_pixels(self.p("rose.png"), RESULTANT)
        dx, dy = xs - (w - 1) / 2, (w - 1) / 2 - ys
        self.assertLess(angle_diff(math.degrees(math.atan2(dx.mean(), dy.mean())), 90 - got[2]), 2)
        self.assertAlmostEqual(np.hypot(dx, dy).max() / (0.42 * 400), got[1] / got[0], delta=0.02)
        spec = self.assert_checks(frag)
        self.assertEqual(len(spec["wind"]["rose"]["entries"]), len(rose["entries"]))
        # erg calibrate's law drift of the same rose is the same sum.
        cal = json.loads(erg("calibrate", self.merged(frag, "cal.json"), "--drift-steps", "1",
                             "--ratios", "2").stdout)["drift"]
        self.assertAlmostEqual(cal["law_dp_m2_per_s"] * YEAR_S / got_rose[0], 1, places=6)

    def test_era5_netcdf_point_and_packing(self):
        lat = np.array([30.0, 29.75, 29.5])  # ERA5: north first
        lon = np.array([10.0, 10.25, 10.5, 10.75])
        nt = 12
        u = np.full((nt, 3, 4), -5.0)
        v = np.full((nt, 3, 4), 1.0)
        # At (29.75 N, 10.5 E): a westerly (u > 0) rising hour by hour.
        u[:, 1, 2] = np.linspace(8, 14, nt)
        v[:, 1, 2] = 0.0
        for time_name in ("valid_time", "time"):
            path = self.p(f"era5_{time_name}.nc")
            write_era5(path, u, v, lat, lon, time_name=time_name)
            with xr.open_dataset(path, engine="h5netcdf", mask_and_scale=False) as raw:
                self.assertEqual(raw.u10.dtype, np.int16)  # really packed
                scale = float(raw.u10.attrs["scale_factor"])
            # The nearest point, the same longitude the other way round, indices.
            for pick in (["--point", "29.8,10.45"], ["--point", "29.75,-349.5"], ["--x", "2", "--y", "1"]):
                p = erg("wind", "import", path, "--format", "netcdf", *pick, "--step-hours", "1",
                        "--png", self.p("e.png"))
                self.assertIn("latitude 29.75, longitude 10.5 (--x 2 --y 1)", p.stderr)
                self.assertIn("2024-01-01T00:00:00Z to 2024-01-01T11:00:00Z", p.stderr)
                kf = json.loads(p.stdout)["wind"]["series"]["keyframes"]
                self.assertEqual(len(kf), nt)
                for k, want in zip(kf, u[:, 1, 2]):
                    self.assertLess(abs(k["speed_mps"] - want), scale)
                    self.assertAlmostEqual(k.get("direction_deg", 0), 0, places=3)
        # Two hours a step: one keyframe per step, the sand of both hours.
        p = erg("wind", "import", self.p("era5_time.nc"), "--format", "netcdf", "--x", "2", "--y", "1",
                "--step-hours", "2", "--png", self.p("e.png"))
        kf = json.loads(p.stdout)["wind"]["series"]["keyframes"]
        self.assertEqual([k["step"] for k in kf], list(range(nt // 2)))
        k = self.ph["von_karman"] / math.log(10 / (self.ph["grain_diameter_m"] / 30))
        for j, key in enumerate(kf):
            pair = u[2 * j:2 * j + 2, 1, 2]
            mean_q = np.mean([flux_bulk(self.ph, k * s) for s in pair])
            self.assertAlmostEqual(flux_bulk(self.ph, k * key["speed_mps"]) / mean_q, 1, delta=2e-4)
            self.assertTrue(pair[0] < key["speed_mps"] < pair[1])
        self.assert_checks({"wind": json.loads(p.stdout)["wind"]})

    def test_job_calibrated_steps(self):
        """With --job, a step is the time that job's calibration measures."""
        n = 48
        write_csv(self.p("day.csv"), ["time", "u", "v"], [[t, 11, 3] for t in hours(n)])
        p = erg("wind", "import", self.p("day.csv"), "--format", "csv", "--job", EXAMPLE,
                "--png", self.p("d.png"))
        frag = json.loads(p.stdout)
        cal = json.loads(erg("calibrate", self.merged(frag), "--drift-steps", "1", "--ratios", "2").stdout)
        steps = [k["step"] for k in frag["wind"]["series"]["keyframes"]]
        want = sorted({math.floor(h * 3600 / cal["dt_s"]) for h in range(n)})
        self.assertEqual(steps, want)
        self.assert_checks(frag)

    def test_bad_input(self):
        good = hours(3)
        cases = {
            "missing column": (["time", "speed"], [[t, 5] for t in good], "csv", [],
                               r"line 1: header .* lacks the columns"),
            "unparsable row": (["time", "u", "v"], [[good[0], 1, 2], [good[1], "abc", 2], [good[2], 1, 1]], "csv", [],
                               r"line 3: u 'abc' is not a number"),
            "bad time": (["time", "u", "v"], [[good[0], 1, 2], ["yesterday", 1, 2]], "csv", [],
                         r"line 3: time 'yesterday' is not an ISO 8601"),
            "direction range": (["time", "speed", "direction"], [[good[0], 5, 400]], "csv", [],
                                r"line 2: direction = 400 is outside \[0, 360\]"),
            "time order": (["time", "u", "v"], [[good[1], 1, 2], [good[0], 1, 2]], "csv", [],
                           r"line 3: time .* is not after"),
        }
        for name, (header, rows, fmt, extra, msg) in cases.items():
            with self.subTest(name):
                write_csv(self.p("bad.csv"), header, rows)
                out = self.p("out.json")
                p = erg("wind", "import", self.p("bad.csv"), "--format", fmt, "--step-hours", "1",
                        "--out", out, "--png", self.p("bad.png"), *extra, check=False)
                self.assertNotEqual(p.returncode, 0)
                self.assertRegex(p.stderr, msg)
                self.assertFalse(os.path.exists(out))
                self.assertFalse(os.path.exists(self.p("bad.png")))
        u = np.full((2, 2, 2), 6.0)
        write_era5(self.p("g.nc"), u, u, np.array([30.0, 29.75]), np.array([10.0, 10.25]))
        for args, msg in (
                (["--point", "10,10"], r"--point 10,10 is outside the grid: latitude in \[29.75, 30\], "
                                       r"longitude in \[10, 10.25\]"),
                (["--x", "5", "--y", "0"], r"--x in \[0, 1\] \(longitude\), --y in \[0, 1\]"),
                ([], r"2 x 2 grid points: choose one with --point"),
                (["--format", "xls"], r"--format 'xls' must be csv or netcdf"),
        ):
            with self.subTest(args):
                p = erg("wind", "import", self.p("g.nc"), "--format", "netcdf", *args, "--step-hours", "1",
                        "--out", self.p("o.json"), check=False)
                self.assertNotEqual(p.returncode, 0)
                self.assertRegex(p.stderr, msg)
                self.assertFalse(os.path.exists(self.p("o.json")))
        # A CSV given as netCDF, and a series without a step length.
        write_csv(self.p("ok.csv"), ["time", "u", "v"], [[t, 1, 1] for t in good])
        p = erg("wind", "import", self.p("ok.csv"), "--format", "netcdf", check=False)
        self.assertNotEqual(p.returncode, 0)
        self.assertIn("is not an HDF5 file", p.stderr)
        xr.Dataset({"u10": (("time",), np.zeros(2))}).to_netcdf(self.p("nc3.nc"), format="NETCDF3_CLASSIC",
                                                                 engine="scipy")
        p = erg("wind", "import", self.p("nc3.nc"), "--format", "netcdf", check=False)
        self.assertNotEqual(p.returncode, 0)
        self.assertIn("a netCDF-3 (classic) file", p.stderr)
        p = erg("wind", "import", self.p("ok.csv"), "--format", "csv", check=False)
        self.assertEqual(p.returncode, 2)
        self.assertIn("--step-hours", p.stderr)
        p = erg("wind", "import", self.p("ok.csv"), "--format", "csv", "--rose", "--height", "0.2",
                "--roughness", "0.5", check=False)
        self.assertEqual(p.returncode, 2)
        self.assertIn("--roughness 0.500000 m must be below --height 0.200000 m", p.stderr)
        self.assertEqual([f for f in os.listdir(self.d) if ".tmp-" in f], [])


if __name__ == "__main__":
    unittest.main()

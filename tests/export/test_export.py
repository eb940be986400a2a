# SPDX-License-Identifier: Apache-2.0
"""erg export and map imports, checked with tools erg did not write.

A small run (64 x 48 cells of 2 m) is exported to every format; the files are
read back with gdalinfo -json, Python GDAL (osgeo.gdal) and PIL and compared
with the snapshot read by h5py. GeoTIFF, PNG16 and EXR maps (the GeoTIFF
written by GDAL, with a pixel size that differs from the cell size) are then
imported as initial layers and run with erg run. EXR files are read back by
the OpenEXR C++ API in tests/export/test_exr.cpp.
"""
import json
import os
import subprocess
import tempfile
import unittest

import h5py
import numpy as np
from osgeo import gdal
from PIL import Image

gdal.UseExceptions()

BIN = os.environ.get("ERG_BIN_DIR", os.path.join(os.path.dirname(__file__), "../../build/bin"))
ERG = os.path.join(BIN, "erg")

NX, NY, CELL = 64, 48, 2.0


def erg(*args, check=True):
    p = subprocess.run([ERG, *args], capture_output=True, text=True, timeout=300)
    if check and p.returncode != 0:
        raise AssertionError(f"erg {' '.join(args)} exited {p.returncode}:\n{p.stdout}\n{p.stderr}")
    return p


def job(bedrock=None, sand=None, steps=20):
    return {
        "name": "export-test",
        "domain": {"nx": NX, "ny": NY, "cell_size_m": CELL},
        "layers": {
            "bedrock": bedrock or {"fbm": {"amplitude": 3, "wavelength_m": 64}},
            "sand": sand or {"patches": {"coverage": 0.3, "radius_m": 10, "height": 2}},
        },
        "wind": {"constant": {"speed_mps": 6, "direction_deg": 20}},
        "seed": 3,
        "run": {"steps": steps, "snapshot_every": 10, "checkpoint_every": 0, "previews": False},
    }


def write_job(d, name, spec):
    path = os.path.join(d, name)
    with open(path, "w") as f:
        json.dump(spec, f)
    return path


def read_band(path):
    """Band 1 as an array, rows north first. The dataset is kept alive while
    the band is read (chaining gdal.Open(p).GetRasterBand(1) crashes GDAL's
    Python bindings once the dataset is collected)."""
    ds = gdal.Open(path)
    a = ds.GetRasterBand(1).ReadAsArray()
    ds = None
    return a


def snapshot(out, step):
    with h5py.File(os.path.join(out, "snapshots", f"step_{step:08d}.h5"), "r") as f:
        b = f["bedrock"][0]
        s = f["sand"][0]
        return {"bedrock": b, "sand": s, "height": (b + s).astype(np.float32),
                "spec": f.attrs["job_spec"]}


class ExportTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.TemporaryDirectory()
        cls.d = cls.tmp.name
        cls.rundir = os.path.join(cls.d, "run")
        erg("run", write_job(cls.d, "job.json", job()), "--out", cls.rundir, "--threads", "2")
        cls.snap = snapshot(cls.rundir, 20)

    @classmethod
    def tearDownClass(cls):
        cls.tmp.cleanup()

    def out(self, name):
        return os.path.join(self.d, name)

    # ---- GeoTIFF -------------------------------------------------------------------
    def test_geotiff_read_by_gdalinfo_and_python_gdal(self):
        path = self.out("h.tif")
        erg("export", self.rundir, "--step", "20", "--format", "geotiff", "--out", path)
        info = json.loads(subprocess.run(["gdalinfo", "-json", "-mdd", "all", path],
                                         capture_output=True, text=True, check=True).stdout)
        self.assertEqual(info["size"], [NX, NY])
        gt = info["geoTransform"]
        self.assertEqual(gt[1], CELL)
        self.assertEqual(gt[5], -CELL)
        self.assertEqual(gt[3], NY * CELL)  # north edge
        self.assertEqual(info["metadata"]["IMAGE_STRUCTURE"]["COMPRESSION"], "DEFLATE")
        self.assertEqual(info["metadata"]["IMAGE_STRUCTURE"]["PREDICTOR"], "3")
        band = info["bands"][0]
        self.assertEqual(band["type"], "Float32")
        self.assertEqual(band["block"], [256, 256])  # tiled, not strips
        wkt = info["coordinateSystem"]["wkt"]
        self.assertIn("LOCAL_CS", wkt.replace("ENGCRS", "LOCAL_CS"))
        self.assertIn("metre", wkt)
        md = info["metadata"][""]
        self.assertEqual(md["ERG_STEP"], "20")
        self.assertEqual(md["ERG_LAYER"], "height")
        self.assertEqual(json.loads(md["ERG_JOB_SPEC"]), json.loads(self.snap["spec"]))
        self.assertNotIn("\n", md["ERG_JOB_SPEC"])  # one line
        # Plain gdalinfo stays readable: the spec does not fill the screen.
        text = subprocess.run(["gdalinfo", path], capture_output=True, text=True,
                              check=True).stdout
        self.assertLess(len(text.splitlines()), 60, text)
        self.assertEqual(sum("ERG_JOB_SPEC={" in ln for ln in text.splitlines()), 1, text)
        self.assertFalse(os.path.exists(path + ".aux.xml"))
        # Values: the first image row is north, equal to the snapshot in float32.
        ds = gdal.Open(path)
        a = ds.GetRasterBand(1).ReadAsArray()
        self.assertEqual(a.dtype, np.float32)
        np.testing.assert_array_equal(a[::-1], self.snap["height"])
        srs = ds.GetSpatialRef()
        self.assertEqual(srs.GetLinearUnits(), 1.0)
        self.assertEqual(ds.GetMetadataItem("ERG_TIME_DAYS") is not None, True)

    def test_geotiff_layers_and_latest_step(self):
        for layer in ("sand", "bedrock"):
            path = self.out(f"{layer}.tif")
            erg("export", self.rundir, "--format", "geotiff", "--layer", layer, "--out", path)
            a = read_band(path)
            np.testing.assert_array_equal(a[::-1], self.snap[layer])  # latest = step 20

    def test_region_and_upsample(self):
        path = self.out("r.tif")
        erg("export", self.rundir, "--format", "geotiff", "--region", "60,40,8,12", "--out", path)
        ds = gdal.Open(path)
        a = ds.GetRasterBand(1).ReadAsArray()[::-1]
        self.assertEqual(a.shape, (12, 8))
        h = self.snap["height"]
        # The region wraps across the torus's east and north edges.
        ys = [(40 + j) % NY for j in range(12)]
        xs = [(60 + i) % NX for i in range(8)]
        np.testing.assert_array_equal(a, h[np.ix_(ys, xs)])
        self.assertEqual(ds.GetGeoTransform()[0], 60 * CELL)
        # --upsample 2 --no-amplify: half the pixel size, bilinear between
        # cell centres.
        path2 = self.out("r2.tif")
        erg("export", self.rundir, "--format", "geotiff", "--region", "10,10,8,8", "--upsample", "2",
            "--no-amplify", "--out", path2)
        ds2 = gdal.Open(path2)
        self.assertEqual(ds2.GetGeoTransform()[1], CELL / 2)
        b = ds2.GetRasterBand(1).ReadAsArray()[::-1].astype(np.float64)
        self.assertEqual(b.shape, (16, 16))
        # Sample (1, 1) sits a quarter cell north-east of cell (10, 10)'s centre.
        hh = h.astype(np.float64)
        want = (0.75 * 0.75 * hh[10, 10] + 0.25 * 0.75 * hh[10, 11] + 0.75 * 0.25 * hh[11, 10]
                + 0.25 * 0.25 * hh[11, 11])
        self.assertAlmostEqual(b[1, 1], want, places=4)

    # ---- Amplification ([P19] 6) -------------------------------------------------
    def test_upsampled_height_is_amplified_with_ripples_across_the_wind(self):
        # Open sand 1 m thick on flat rock under one wind at 20 degrees: the
        # upsampled export carries ripples whose wave vector (2-D FFT of the
        # amplified minus the plain interpolated heights) lies along the
        # wind, i.e. crests perpendicular to it.
        spec = job(bedrock={"constant": 0}, sand={"constant": 1}, steps=10)
        spec["domain"] = {"nx": 48, "ny": 48, "cell_size_m": 1.0}
        rundir = self.out("ripples_run")
        erg("run", write_job(self.d, "ripples.json", spec), "--out", rundir, "--threads", "2")
        K, W = 4, 32
        amp, plain = self.out("amp.tif"), self.out("plain.tif")
        for path, extra in ((amp, []), (plain, ["--no-amplify"])):
            erg("export", rundir, "--step", "10", "--format", "geotiff", "--region", f"8,8,{W},{W}",
                "--upsample", str(K), "--out", path, *extra)
        ds = gdal.Open(amp)
        self.assertEqual(ds.GetGeoTransform()[1], 1.0 / K)
        a = ds.GetRasterBand(1).ReadAsArray()[::-1].astype(np.float64)
        ds = None
        b = read_band(plain)[::-1].astype(np.float64)
        self.assertEqual(a.shape, (W * K, W * K))
        r = a - b
        self.assertGreater(r.std(), 0.005, "no ripples in the amplified export")
        self.assertLess(np.abs(r).max(), 0.5, "amplification moved the terrain, not just rippled it")
        win = np.outer(np.hanning(W * K), np.hanning(W * K))
        spec2 = np.abs(np.fft.fft2((r - r.mean()) * win)) ** 2
        spec2[0, 0] = 0
        ky, kx = np.unravel_index(np.argmax(spec2), spec2.shape)
        n = W * K
        kx = kx - n if kx > n // 2 else kx
        ky = ky - n if ky > n // 2 else ky
        angle = np.degrees(np.arctan2(ky, kx)) % 180
        off = min(abs(angle - 20), 180 - abs(angle - 20))
        print(f"amplified export: ripple rms {r.std():.4f} m, wave vector {angle:.1f} deg "
              f"(wind 20 deg)")
        self.assertLess(off, 10, f"ripple wave vector at {angle:.1f} deg, wind at 20 deg")

    def test_amplified_engine_tiles_still_share_their_borders(self):
        path = self.out("at.tif")
        p = erg("export", self.rundir, "--format", "geotiff", "--upsample", "2", "--tiles", "2x1",
                "--out", path)
        self.assertEqual(len(p.stdout.split()), 2)
        t0, t1 = read_band(self.out("at_x0_y0.tif")), read_band(self.out("at_x1_y0.tif"))
        self.assertEqual(t0.shape, (2 * NY + 1, NX + 1))
        np.testing.assert_array_equal(t0[:, -1], t1[:, 0])
        np.testing.assert_array_equal(t1[:, -1], t0[:, 0])  # the torus wraps
        plain = self.out("pt.tif")
        erg("export", self.rundir, "--format", "geotiff", "--upsample", "2", "--tiles", "2x1",
            "--no-amplify", "--out", plain)
        self.assertFalse(np.array_equal(t0, read_band(self.out("pt_x0_y0.tif"))),
                         "--upsample 2 exported the plain interpolation")

    def test_engine_tiles_share_their_borders_on_the_torus(self):
        path = self.out("t.tif")
        p = erg("export", self.rundir, "--format", "geotiff", "--tiles", "2x3", "--out", path)
        names = p.stdout.split()
        self.assertEqual(len(names), 6)
        t = {}
        for i in range(2):
            for j in range(3):
                f = self.out(f"t_x{i}_y{j}.tif")
                self.assertIn(f, names)
                t[i, j] = read_band(f)  # north row first
                self.assertEqual(t[i, j].shape, (NY // 3 + 1, NX // 2 + 1))
        for j in range(3):
            np.testing.assert_array_equal(t[0, j][:, -1], t[1, j][:, 0])
        for i in range(2):
            for j in range(2):  # y0 is the north row of tiles
                np.testing.assert_array_equal(t[i, j][-1, :], t[i, j + 1][0, :])
        # Wrapping: the east tile's extra column is the west tile's first one,
        # the north tiles' extra row (their top) the south tiles' bottom row.
        np.testing.assert_array_equal(t[1, 0][:, -1], t[0, 0][:, 0])
        np.testing.assert_array_equal(t[0, 0][0, :], t[0, 2][-1, :])
        h = self.snap["height"]
        np.testing.assert_array_equal(t[0, 2][::-1][:NY // 3, :NX // 2], h[:NY // 3, :NX // 2])

    # ---- PNG16 ---------------------------------------------------------------------
    def test_png16_with_sidecar_within_one_step(self):
        path = self.out("h.png")
        erg("export", self.rundir, "--format", "png16", "--out", path)
        img = Image.open(path)
        self.assertEqual(img.size, (NX, NY))
        raw = np.array(img, dtype=np.float64)[::-1]
        self.assertEqual(img.mode[:1], "I")
        with open(path + ".json") as f:
            side = json.load(f)
        h = self.snap["height"].astype(np.float64)
        back = side["offset_m"] + side["metres_per_unit"] * raw
        step = side["metres_per_unit"]
        self.assertLessEqual(np.max(np.abs(back - h)), 0.5 * step + 1e-6)
        self.assertAlmostEqual(side["range_m"], float(h.max() - h.min()), places=4)
        self.assertEqual(side["cell_size_m"], CELL)
        self.assertEqual((side["width"], side["height"]), (NX, NY))
        self.assertAlmostEqual(side["unreal"]["scale_z_percent"],
                               side["range_m"] * 12800 / 65535, places=6)
        self.assertEqual(side["unreal"]["scale_x_cm"], CELL * 100)
        self.assertEqual(side["unity"]["terrain_height_m"], side["range_m"])
        self.assertFalse(side["unity"]["resolution_ok"])  # 64 x 48 is not 2^n+1 square
        # --tiles 1x1 on a 32 x 32 region: one engine tile of 33 x 33 samples
        # (the shared border row and column), a resolution Unity accepts.
        p2 = self.out("u.png")
        erg("export", self.rundir, "--format", "png16", "--region", "0,0,32,32", "--tiles", "1x1",
            "--out", p2)
        with open(self.out("u_x0_y0.png.json")) as f:
            u = json.load(f)
        self.assertEqual((u["width"], u["height"]), (33, 33))
        self.assertTrue(u["unity"]["resolution_ok"])
        self.assertEqual(u["unity"]["terrain_width_m"], 32 * CELL)

    # ---- OBJ -----------------------------------------------------------------------
    def test_obj_region_counts_and_heights(self):
        path = self.out("m.obj")
        erg("export", self.rundir, "--format", "obj", "--region", "5,7,10,6", "--normals",
            "--out", path)
        v, vn, f = [], 0, []
        with open(path) as fh:
            for line in fh:
                if line.startswith("v "):
                    v.append([float(x) for x in line.split()[1:]])
                elif line.startswith("vn "):
                    vn += 1
                elif line.startswith("f "):
                    f.append(line.split()[1:])
        self.assertEqual(len(v), 11 * 7)  # the region closed by one more row and column
        self.assertEqual(vn, len(v))
        self.assertEqual(len(f), 2 * 10 * 6)
        self.assertTrue(all(len(x) == 3 for x in f))
        h = self.snap["height"]
        x, y, z = v[0]
        self.assertAlmostEqual(x, 5.5 * CELL)
        self.assertAlmostEqual(y, 7.5 * CELL)
        self.assertAlmostEqual(z, float(h[7, 5]), places=5)
        self.assertAlmostEqual(v[11 * 3 + 4][2], float(h[10, 9]), places=5)
        idx = [int(c.split("//")[0]) for face in f for c in face]
        self.assertEqual((min(idx), max(idx)), (1, len(v)))

    # ---- errors --------------------------------------------------------------------
    def test_clear_errors(self):
        cases = [
            (["--step", "15", "--format", "geotiff"], "no snapshot of that step"),
            (["--format", "geotiff", "--region", "0,0,65,4"], "--region"),
            (["--format", "geotiff", "--region", "70,0,4,4"], "--region"),
            (["--format", "bmp"], "allowed geotiff, png16, exr, obj"),
            (["--format", "png16", "--layer", "wind"], "allowed height, sand"),
            (["--format", "png16", "--tiles", "3"], "expected NxM"),
            (["--format", "obj", "--upsample", "0"], "allowed 1 to 64"),
        ]
        for args, msg in cases:
            p = erg("export", self.rundir, *args, "--out", self.out("bad.tif"), check=False)
            self.assertNotEqual(p.returncode, 0, args)
            self.assertIn(msg, p.stderr, args)
        self.assertFalse(os.path.exists(self.out("bad.tif")))
        p = erg("export", self.out("nowhere"), "--format", "exr", "--out", self.out("x.exr"),
                check=False)
        self.assertIn("not a directory", p.stderr)
        leftovers = [n for n in os.listdir(self.d) if ".tmp-" in n]
        self.assertEqual(leftovers, [])

    # ---- imports -------------------------------------------------------------------
    def gdal_dem(self, name, values, pixel, srs_epsg=32633):
        """A DEM written by GDAL itself (not erg): rows north first."""
        path = self.out(name)
        ny, nx = values.shape
        ds = gdal.GetDriverByName("GTiff").Create(path, nx, ny, 1, gdal.GDT_Float32)
        ds.SetGeoTransform([500000.0, pixel, 0, 4000000.0, 0, -pixel])
        from osgeo import osr
        srs = osr.SpatialReference()
        srs.ImportFromEPSG(srs_epsg)
        ds.SetProjection(srs.ExportToWkt())
        ds.GetRasterBand(1).WriteArray(values[::-1].astype(np.float32))
        ds = None
        return path

    def test_geotiff_dem_with_another_pixel_size_runs(self):
        # 32 x 24 pixels of 4 m cover the 64 x 48 cells of 2 m: resampled.
        jj, ii = np.mgrid[0:24, 0:32]
        dem = 10 + 3 * np.sin(2 * np.pi * ii / 32) * np.cos(2 * np.pi * jj / 24)
        path = self.gdal_dem("dem.tif", dem, 4.0)
        spec = job(bedrock={"map": {"path": "dem.tif"}}, steps=10)
        jp = write_job(self.d, "dem.json", spec)
        p = erg("check", jp)
        self.assertIn("resampled bilinearly (periodic) to 64 x 48 cells of 2 m", p.stderr)
        self.assertIn("of 4 x 4 metre", p.stderr)
        out = self.out("dem-run")
        erg("run", jp, "--out", out, "--threads", "2")
        b = snapshot(out, 0)["bedrock"].astype(np.float64)
        # Cell (x, y)'s centre is at map pixel coordinate (x + 1/2) / 2 - 1/2.
        x = (np.arange(NX) + 0.5) / 2 - 0.5
        y = (np.arange(NY) + 0.5) / 2 - 0.5
        want = 10 + 3 * np.outer(np.cos(2 * np.pi * y / 24), np.sin(2 * np.pi * x / 32))
        self.assertLess(np.max(np.abs(b - want)), 0.1)  # bilinear error of a smooth wave

    def test_resampled_geotiff_is_tiling_independent(self):
        # Like every generator, a resampled map does not depend on the tiling:
        # 1 and 2 ranks give the same bits (tiles of at least the widest halo,
        # hence a 192 x 96 domain of 1 m cells; the DEM has 2 m pixels).
        jj, ii = np.mgrid[0:48, 0:96]
        dem = 5 + 2 * np.sin(2 * np.pi * ii / 48) + np.cos(2 * np.pi * jj / 24)
        self.gdal_dem("dem2.tif", dem, 2.0)
        spec = job(bedrock={"map": {"path": "dem2.tif"}}, steps=4)
        spec["domain"] = {"nx": 192, "ny": 96, "cell_size_m": 1.0}
        jp = write_job(self.d, "dem2.json", spec)
        outs = []
        for ranks in ("1", "2"):
            outs.append(self.out(f"dem2-{ranks}"))
            erg("run", jp, "--out", outs[-1], "--threads", "1", "--ranks", ranks)
        for step in (0, 4):
            a, b = snapshot(outs[0], step), snapshot(outs[1], step)
            for k in ("bedrock", "sand"):
                np.testing.assert_array_equal(a[k], b[k])

    def test_non_tileable_map_is_refused_then_blended(self):
        jj, ii = np.mgrid[0:NY, 0:NX]
        ramp = 0.5 * ii + 0.0 * jj  # a slope: its west and east borders differ by 31.5 m
        self.gdal_dem("ramp.tif", ramp, CELL)
        jp = write_job(self.d, "ramp.json", job(bedrock={"map": {"path": "ramp.tif"}}, steps=2))
        p = erg("check", jp, check=False)
        self.assertEqual(p.returncode, 2)
        self.assertIn("layers.bedrock.map.path = \"ramp.tif\" is not tileable", p.stderr)
        self.assertIn("west and east borders", p.stderr)
        self.assertIn("blend_border_m", p.stderr)
        spec = job(bedrock={"map": {"path": "ramp.tif", "blend_border_m": 16}}, steps=2)
        jp = write_job(self.d, "ramp-blend.json", spec)
        p = erg("check", jp)
        self.assertIn("borders cross-faded over 16 m", p.stderr)
        out = self.out("ramp-run")
        erg("run", jp, "--out", out, "--threads", "2")
        b = snapshot(out, 0)["bedrock"].astype(np.float64)
        self.assertAlmostEqual(float(b[5, 0]), float(b[5, -1]), places=5)  # the seam closed
        self.assertAlmostEqual(float(b[5, 32]), 16.0, places=5)  # the middle untouched

    def test_bad_maps_are_refused_with_the_field_named(self):
        wave = np.fromfunction(lambda j, i: np.sin(2 * np.pi * i / 32), (24, 32))
        self.gdal_dem("deg.tif", wave, 0.001, srs_epsg=4326)
        self.gdal_dem("wide.tif", wave, 3.0)  # 96 m x 72 m; the domain is 128 m x 96 m
        holes = self.gdal_dem("holes.tif", wave, 4.0)
        ds = gdal.Open(holes, gdal.GA_Update)
        ds.GetRasterBand(1).SetNoDataValue(-9999)
        ds.GetRasterBand(1).WriteArray(np.full((1, 1), -9999, np.float32), 3, 2)
        ds = None
        with open(self.out("junk.exr"), "wb") as f:
            f.write(b"not an image" * 10)
        cases = [
            ("deg.tif", "geographic coordinates"),
            ("wide.tif", "covers 96 m x 72 m"),
            ("holes.tif", "has no data"),
            ("junk.exr", "cannot read EXR"),
        ]
        for name, msg in cases:
            jp = write_job(self.d, "bad.json", job(sand={"map": {"path": name}}))
            p = erg("check", jp, check=False)
            self.assertEqual(p.returncode, 2, name)
            self.assertIn(f"layers.sand.map.path = \"{name}\"", p.stderr, name)
            self.assertIn(msg, p.stderr, name)

    def test_png16_and_exr_exports_import_back(self):
        h = self.snap["height"].astype(np.float64)
        png = self.out("in.png")
        erg("export", self.rundir, "--format", "png16", "--out", png)
        with open(png + ".json") as f:
            side = json.load(f)
        exr = self.out("in.exr")
        erg("export", self.rundir, "--format", "exr", "--out", exr)
        png_map = {"path": "in.png", "scale": side["metres_per_unit"] * 65535,
                   "offset": side["offset_m"]}
        for name, m, tol in (("png", png_map, 0.5 * side["metres_per_unit"] + 1e-6),
                             ("exr", {"path": "in.exr"}, 1e-5)):
            jp = write_job(self.d, f"in-{name}.json",
                           job(bedrock={"map": m}, sand={"constant": 0}, steps=1))
            out = self.out(f"in-{name}-run")
            erg("run", jp, "--out", out, "--threads", "2")
            b = snapshot(out, 0)["bedrock"].astype(np.float64)
            self.assertLessEqual(np.max(np.abs(b - h)), tol, name)


if __name__ == "__main__":
    unittest.main()

# SPDX-License-Identifier: Apache-2.0
"""The Python package `erg` (client/python) as a user gets it: pip installs
it offline into a virtual environment of Debian's python3
(--system-site-packages: python3-grpcio, python3-protobuf, python3-xarray,
python3-h5netcdf), without the build tree, and its client code runs in that
environment against a real ergd: submit, watch, status, jobs, steer, cancel,
fetch, open_run; the CLI's environment and config file; README's Python
section as written. Each client program runs in the venv's python; this
test (system python, ergd_fixture) checks what it did through ergd's API."""
import glob
import json
import os
import shutil
import subprocess
import sys
import textwrap
import unittest

import numpy as np

from ergd_fixture import (ALICE, BOB, Ergd, ErgdTest, S, erg_run, md, self_signed_cert, sha256,
                          spec_json, terminal)

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "docs"))
import readme_blocks  # noqa: E402

PACKAGE = os.environ["ERG_PYTHON_PACKAGE"]
VENV = os.environ["ERG_PYTHON_VENV"]
VPY = os.path.join(VENV, "bin", "python")
LONG = dict(nx=128, ny=128, steps=3000, snapshot_every=300, checkpoint_every=100)


def install_package():
    """A fresh venv with the package pip-installed from a copy of
    client/python (pip builds in the source folder; the copy keeps the
    source tree clean). Without a pip of its own (Debian's python3-pip
    comes with the system site packages): seconds less than README's
    `venv` + `V/bin/pip`, which the README test runs as written."""
    shutil.rmtree(VENV, ignore_errors=True)
    subprocess.run(["/usr/bin/python3", "-m", "venv", "--system-site-packages", "--without-pip",
                    VENV], check=True)
    src = VENV + "-src"
    shutil.rmtree(src, ignore_errors=True)
    shutil.copytree(PACKAGE, src, ignore=shutil.ignore_patterns("build", "*.egg-info",
                                                                "__pycache__"))
    subprocess.run([VPY, "-m", "pip", "install", "--no-build-isolation",
                    "--no-index", "--quiet", src], check=True)
    shutil.rmtree(src)


class PythonPackage(ErgdTest):
    @classmethod
    def setUpClass(cls):
        super().setUpClass()
        install_package()
        cls.home = os.path.join(cls.tmpdir, "home")
        os.mkdir(cls.home)

    def env(self, **extra):
        env = {k: v for k, v in os.environ.items()
               if not k.startswith("ERG_") and k != "PYTHONPATH"}
        env.update(HOME=self.home, ERG_SERVER=self.ergd.addr, ERG_TOKEN=ALICE)
        env.update(extra)
        return {k: v for k, v in env.items() if v is not None}

    def py(self, code, env=None, cwd=None, **values):
        """Runs `code` in the venv's python (VALUES as JSON in the variable
        `ARGS`); returns the JSON its last stdout line holds."""
        prog = "import json, sys\nARGS = json.loads(sys.argv[1])\n" + textwrap.dedent(code)
        r = subprocess.run([VPY, "-c", prog, json.dumps(values)], env=env or self.env(),
                           cwd=cwd or self.tmpdir, capture_output=True, text=True, timeout=180)
        self.assertEqual(r.returncode, 0, r.stdout[-2000:] + r.stderr[-3000:])
        return json.loads(r.stdout.strip().split("\n")[-1])

    def test_package_ships_its_stubs_outside_any_build_tree(self):
        out = self.py("""
            import erg, erg._proto.service_pb2_grpc as G
            print(json.dumps([erg.__file__, G.__file__, erg.service_pb2.Job.__module__]))
        """)
        site = os.path.join(VENV, "lib")
        self.assertTrue(out[0].startswith(site), out)
        self.assertTrue(out[1].startswith(site), out)
        self.assertEqual(out[2], "erg._proto.service_pb2")

    def test_submit_watch_status_jobs_fetch_open_run(self):
        d = spec_json(steps=40, snapshot_every=10, name="py-package")
        out = self.py("""
            import os, erg
            c = erg.Client()  # ERG_SERVER, ERG_TOKEN
            job = c.submit(ARGS["spec"])
            kinds, steps, ids = [], [], []
            for ev in c.watch(job.id):
                ids.append(ev.id)
                kinds.append(ev.WhichOneof("kind"))
                if ev.HasField("progress"):
                    steps.append(ev.progress.step)
            st = c.status(job.id)
            listed = [j.id for j in c.jobs()]
            done = [j.id for j in c.jobs(state="succeeded")]
            running = [j.id for j in c.jobs(state=erg.RUNNING)]
            paths = c.fetch(job.id, ARGS["out"], all=True)
            again = c.fetch(job.id, ARGS["out"])  # present and verified: kept
            # A .part is resumed from its end: a right one completes, a
            # corrupt one fails the sha256 check and is deleted.
            with open(paths[-1], "rb") as f:
                data = f.read()
            part = os.path.join(ARGS["out"] + "-resumed", os.path.basename(paths[-1]) + ".part")
            os.makedirs(os.path.dirname(part))
            with open(part, "wb") as f:
                f.write(data[:1000])
            resumed = c.fetch(job.id, os.path.dirname(part), step=40)
            with open(resumed[0], "rb") as f:
                resumed_same = f.read() == data
            os.remove(resumed[0])
            with open(part, "wb") as f:
                f.write(data[:999] + bytes([data[999] ^ 1]))
            try:
                c.fetch(job.id, os.path.dirname(part), step=40)
                corrupt = None
            except erg.Error as e:
                corrupt = [e.code.name, e.details, os.path.exists(part)]
            with open(part, "wb") as f:  # longer than ergd's file: downloaded afresh
                f.write(data + b"x")
            with open(c.fetch(job.id, os.path.dirname(part), step=40)[0], "rb") as f:
                long_same = f.read() == data
            ds = erg.open_run(ARGS["out"])
            local = erg.open_run(ARGS["local"])
            print(json.dumps({
                "id": job.id, "state0": job.state, "kinds": kinds, "steps": steps, "ids": ids,
                "state": erg.service_pb2.JobState.Name(st.state),
                "snapshot_steps": list(st.snapshot_steps), "listed": listed, "done": done,
                "running": running, "paths": paths, "again": again,
                "resumed_same": resumed_same, "corrupt": corrupt, "long_same": long_same,
                "dims": list(ds.sand.dims), "sizes": dict(ds.sizes),
                "x": ds.x.values.tolist(), "y": ds.y.values.tolist(),
                "time": ds.time.values.tolist(), "units": ds.sand.attrs["units"],
                "same_as_local": bool((ds.sand.values == local.sand.values).all()),
                "local_sizes": dict(local.sizes),
                "volume": float((ds.sand.isel(time=-1) * ds.attrs["cell_size_m"] ** 2).sum())}))
        """, spec=d, out=os.path.join(self.tmpdir, "fetched"),
            local=erg_run(d, os.path.join(self.tmpdir, "local"), self.tmpdir))
        self.assertEqual(out["state0"], S.QUEUED)
        self.assertEqual(out["state"], "SUCCEEDED")
        self.assertIn("snapshot_step", out["kinds"])
        self.assertEqual(out["kinds"][-1], "state_changed")
        self.assertEqual(out["ids"], sorted(out["ids"]))
        self.assertEqual(out["steps"], sorted(out["steps"]))
        self.assertEqual(out["steps"][-1], 40)
        # What the client saw is ergd's record.
        j = self.ergd.get(out["id"])
        self.assertEqual(j.state, S.SUCCEEDED)
        self.assertEqual(out["snapshot_steps"], [0, 10, 20, 30, 40])
        self.assertIn(out["id"], out["listed"])
        self.assertIn(out["id"], out["done"])
        self.assertNotIn(out["id"], out["running"])
        # fetch: every snapshot, byte for byte what ergd streams.
        self.assertEqual([os.path.basename(p) for p in out["paths"]],
                         ["step_%08d.h5" % s for s in (0, 10, 20, 30, 40)])
        self.assertEqual(out["again"], out["paths"][-1:])
        self.assertEqual(glob.glob(os.path.join(self.tmpdir, "fetched", "*.part")), [])
        self.assertTrue(out["resumed_same"])
        self.assertEqual(out["corrupt"][0], "DATA_LOSS")
        self.assertIn("sha256 differs", out["corrupt"][1])
        self.assertFalse(out["corrupt"][2])
        self.assertTrue(out["long_same"])
        first, data = self.ergd.fetch_bytes(out["id"])
        with open(out["paths"][-1], "rb") as f:
            self.assertEqual(sha256(f.read()), first.sha256)
        # open_run: (time, y, x), cell centres in metres, model days; the
        # fetched run equals a local `erg run` of the same spec.
        self.assertEqual(out["dims"], ["time", "y", "x"])
        self.assertEqual(out["sizes"], {"time": 5, "y": 64, "x": 64})
        self.assertEqual(out["local_sizes"], out["sizes"])
        np.testing.assert_array_equal(out["x"], np.arange(64) + 0.5)
        np.testing.assert_array_equal(out["y"], np.arange(64) + 0.5)
        days = j.spec.model.time_step_days
        self.assertGreater(days, 0)
        np.testing.assert_allclose(out["time"], [s * days for s in (0, 10, 20, 30, 40)])
        self.assertEqual(out["units"], "m")
        self.assertTrue(out["same_as_local"])
        self.assertGreater(out["volume"], 0)

    def test_steer_and_cancel_a_running_job(self):
        out = self.py("""
            import erg
            c = erg.Client()
            job = c.submit(ARGS["spec"], threads=1)
            for ev in c.watch(job.id):  # until it runs past step 5
                if ev.HasField("progress") and ev.progress.step >= 5:
                    break
            applied = c.steer(job.id, [{"sand": {"x_m": 20, "y_m": 30, "radius_m": 6,
                                                 "height": 1}}])
            with open("events.json", "w") as f:  # as `erg steer ID events.json`
                f.write('{"bedrock": {"x_m": 50, "y_m": 50, "radius_m": 4, "height": 0.5}}')
            applied += c.steer(job.id, "events.json")
            try:
                c.steer(job.id, {"vegetation": {"x_m": 1, "y_m": 1, "radius_m": 3,
                                                "density": 5}})
                refused = None
            except erg.Error as e:
                refused = [e.code.name, e.details]
            cancelled = c.cancel(job.id)
            final = c.wait(job.id)
            try:
                c.status(ARGS["other"])
                other = None
            except erg.Error as e:
                other = e.code.name
            print(json.dumps({"id": job.id, "applied": [a.step for a in applied],
                              "kinds": [a.WhichOneof("action") for a in applied],
                              "refused": refused, "other": other,
                              "final": erg.service_pb2.JobState.Name(final.state)}))
        """, spec=spec_json(name="py-long", **LONG),
            other=self.ergd.submit(spec_json(steps=2, snapshot_every=1), token=BOB).id)
        self.assertEqual(len(out["applied"]), 2)
        self.assertGreaterEqual(out["applied"][0], 5)
        self.assertGreaterEqual(out["applied"][1], out["applied"][0])
        self.assertEqual(out["kinds"], ["sand", "bedrock"])
        self.assertEqual(out["refused"][0], "INVALID_ARGUMENT")
        self.assertIn("density", out["refused"][1])
        self.assertEqual(out["final"], "CANCELLED")
        self.assertEqual(out["other"], "NOT_FOUND")  # another tenant's job
        j = self.ergd.get(out["id"])
        self.assertEqual(j.state, S.CANCELLED)
        # The steering is recorded, at the steps it was applied.
        self.assertEqual([e.step for e in j.spec.events], out["applied"])

    def test_watch_rides_out_ergd_killed_and_restarted(self):
        job_id = self.ergd.submit(spec_json(name="py-survivor", nx=256, ny=256, steps=600,
                                            snapshot_every=300, checkpoint_every=100)).id
        prog = textwrap.dedent("""
            import json, sys, erg
            ids, snaps = [], []
            for ev in erg.Client().watch(sys.argv[1]):
                ids.append(ev.id)
                if ev.HasField("snapshot_step"):
                    snaps.append(ev.snapshot_step)
            print(json.dumps({"ids": ids, "snaps": snaps}))
        """)
        watch = subprocess.Popen([VPY, "-c", prog, job_id], env=self.env(),
                                 stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        out, err = self.ergd.kill_and_restart_under(
            watch, job_id, until=lambda j: j.progress.step >= 50 or terminal(j.state))
        self.assertEqual(watch.returncode, 0, err)
        seen = json.loads(out)
        j = self.ergd.get(job_id)
        self.assertEqual(j.state, S.SUCCEEDED)
        self.assertEqual(j.attempts, 2)  # it was running when ergd died
        # Every event once, in order: what a fresh watch from the start sees.
        self.assertEqual(seen["snaps"], [0, 300, 600])
        self.assertEqual(seen["ids"], [ev.id for ev in self.ergd.stub.WatchJob(
            S.WatchJobRequest(id=job_id), metadata=md(ALICE), timeout=30)])

    def test_connection_settings_are_the_clis(self):
        cfg_dir = os.path.join(self.home, ".config", "erg")
        os.makedirs(cfg_dir, exist_ok=True)
        cfg = os.path.join(cfg_dir, "config")
        with open(cfg, "w") as f:
            f.write("# the CLI's file\nserver = %s   # a comment\ntoken = %s\n" %
                    (self.ergd.addr, BOB))
        os.chmod(cfg, 0o600)
        code = """
            import warnings, erg
            with warnings.catch_warnings(record=True) as w:
                warnings.simplefilter("always")
                c = erg.Client()
            s = c.settings
            tenants = sorted({j.tenant for j in c.jobs()})
            print(json.dumps({"server": s.server, "origins": s.origins, "tenants": tenants,
                              "warnings": [str(x.message) for x in w]}))
        """
        # The config file alone: bob, no warning (mode 0600).
        for token in (ALICE, BOB):
            self.ergd.submit(spec_json(steps=2, snapshot_every=1), token=token)
        out = self.py(code, env=self.env(ERG_SERVER=None, ERG_TOKEN=None))
        self.assertEqual(out["origins"], {"server": cfg, "token": cfg})
        self.assertEqual(out["tenants"], ["bob"])
        self.assertEqual(out["warnings"], [])
        # The environment wins over the file; the file's server still applies.
        out = self.py(code, env=self.env(ERG_SERVER=None))
        self.assertEqual(out["origins"], {"server": cfg, "token": "ERG_TOKEN"})
        self.assertEqual(out["tenants"], ["alice"])
        # A token readable by others is warned about, as by erg.
        os.chmod(cfg, 0o644)
        out = self.py(code, env=self.env(ERG_SERVER=None, ERG_TOKEN=None))
        self.assertEqual(out["warnings"], ["%s holds a token and is readable by others "
                                           "(chmod 600 %s)" % (cfg, cfg)])
        os.chmod(cfg, 0o600)
        # ERG_CONFIG names another file; a relative ca is the file's folder's.
        other = os.path.join(self.tmpdir, "other.conf")
        with open(other, "w") as f:
            f.write("server = example.org\nca = certs/ca.pem\n")
        out = self.py("""
            import erg
            s = erg.resolve_settings()
            print(json.dumps([s.server, s.ca, s.token, s.origins]))
        """, env=self.env(ERG_CONFIG=other, ERG_SERVER=None))
        self.assertEqual(out, ["example.org:7117", os.path.join(self.tmpdir, "certs", "ca.pem"),
                               ALICE, {"server": other, "token": "ERG_TOKEN", "ca": other}])
        # A bad file: the CLI's message, naming the file and line.
        with open(other, "w") as f:
            f.write("server = x\nport = 7117\n")
        out = self.py("""
            import erg
            try:
                erg.Client()
                print(json.dumps(None))
            except ValueError as e:
                print(json.dumps(str(e)))
        """, env=self.env(ERG_CONFIG=other))
        self.assertEqual(out, other + ":2: unknown key 'port' (expected server, token or ca)")
        # ...and erg says the same.
        r = subprocess.run([os.path.join(os.environ["ERG_BIN_DIR"], "erg"), "jobs"],
                           env=self.env(ERG_CONFIG=other), capture_output=True, text=True)
        self.assertIn(out, r.stderr)

    def test_tls_with_the_ca_of_the_config_file(self):
        tmp = os.path.join(self.tmpdir, "tls")
        os.mkdir(tmp)
        cert, key = self_signed_cert(tmp)
        tls = Ergd(tmp, ["--tls-cert", cert, "--tls-key", key], ca=cert)
        try:
            job = tls.submit(spec_json(steps=2, snapshot_every=1), token=BOB)
            conf = os.path.join(tmp, "config")
            with open(conf, "w") as f:  # ca relative to the file's folder
                f.write("server = %s\nca = cert.pem\n" % tls.addr)
            code = """
                import erg
                c = erg.Client(token=ARGS["token"])
                try:
                    print(json.dumps([c.settings.ca, [j.id for j in c.jobs()]]))
                except erg.Error as e:
                    print(json.dumps(e.code.name))
            """
            out = self.py(code, env=self.env(ERG_CONFIG=conf, ERG_SERVER=None), token=BOB)
            self.assertEqual(out, [cert, [job.id]])
            # Without the ca the client speaks plaintext, which a TLS ergd refuses.
            out = self.py(code, env=self.env(ERG_SERVER=tls.addr), token=BOB)
            self.assertEqual(out, "UNAVAILABLE")
        finally:
            tls.stop()

    def test_readme_python_section_as_written(self):
        parts = [b for b in readme_blocks.blocks() if b.name == "python-client"]
        self.assertEqual([b.lang for b in parts], ["sh", "python"])
        scratch = readme_blocks.Scratch(os.path.dirname(os.environ["ERG_BIN_DIR"]))
        scratch.env.update(ERG_SERVER=self.ergd.addr, ERG_TOKEN=ALICE)
        scratch.env.pop("PYTHONPATH", None)
        try:
            r = scratch.run(parts[0], timeout=300)
            self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
            venv_python = os.path.join(scratch.home, "erg-venv", "bin", "python")
            r = subprocess.run([venv_python, "-c", parts[1].code], cwd=scratch.dir,
                               env=scratch.env, capture_output=True, text=True, timeout=300)
            self.assertEqual(r.returncode, 0, r.stdout[-2000:] + r.stderr[-3000:])
            lines = r.stdout.strip().split("\n")
            self.assertIn("SUCCEEDED", lines)
            self.assertIn("('time', 'y', 'x')", r.stdout)
            self.assertTrue(glob.glob(scratch.path("runs", "py-fetched", "step_*.h5")))
        finally:
            scratch.cleanup()


if __name__ == "__main__":
    unittest.main()

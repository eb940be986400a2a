# SPDX-License-Identifier: Apache-2.0
"""A small real run shared by the format tests: 96 x 64 cells of 2 m (not
square, so a swapped axis shows), sand patches on fBm bedrock under one
wind, snapshots at steps 0, 10, 20 and 30, read back with h5py."""
import json
import os
import subprocess

import h5py
import numpy as np

BIN = os.environ.get("ERG_BIN_DIR", os.path.join(os.path.dirname(__file__), "../../build/bin"))
ERG = os.path.join(BIN, "erg")
NX, NY, CELL = 96, 64, 2.0
LAYERS = ("bedrock", "sand", "vegetation", "wind_x", "wind_y", "airborne", "shadow", "obstacles",
          "deposited_m")


def job(steps=30, every=10):
    return {
        "name": "formats-test",
        "domain": {"nx": NX, "ny": NY, "cell_size_m": CELL},
        "layers": {
            "bedrock": {"fbm": {"amplitude": 3, "wavelength_m": 64}},
            "sand": {"patches": {"coverage": 0.4, "radius_m": 12, "height": 2}},
        },
        "wind": {"constant": {"speed_mps": 6, "direction_deg": 20}},
        "seed": 3,
        "run": {"steps": steps, "snapshot_every": every, "checkpoint_every": 0},
    }


def erg(*args, timeout=300):
    p = subprocess.run([ERG, *args], capture_output=True, text=True, timeout=timeout)
    if p.returncode != 0:
        raise AssertionError(f"erg {' '.join(args)} exited {p.returncode}:\n{p.stdout}\n{p.stderr}")
    return p


def make_run(d, spec=None):
    """Runs `spec` (default job()) into d/run and returns the run directory."""
    path = os.path.join(d, "job.json")
    with open(path, "w") as f:
        json.dump(spec or job(), f)
    out = os.path.join(d, "run")
    erg("run", path, "--out", out)
    return out


def snapshots(run):
    """[(step, path)] in step order."""
    names = sorted(n for n in os.listdir(os.path.join(run, "snapshots")) if n.endswith(".h5"))
    return [(int(n[5:-3]), os.path.join(run, "snapshots", n)) for n in names]


def read(path):
    """The snapshot as h5py sees it: layers as [ny][nx] arrays, attributes."""
    with h5py.File(path, "r") as f:
        out = {name: f[name][0] for name in LAYERS if name in f}
        out["attrs"] = {k: f.attrs[k] for k in f.attrs}
        out["x"], out["y"], out["time"] = f["x"][...], f["y"][...], f["time"][...]
    out["height"] = out["bedrock"] + out["sand"]
    return out

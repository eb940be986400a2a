#!/usr/bin/python3
# SPDX-License-Identifier: Apache-2.0
"""erg validate: run the fixed scenes of scenes/full (or scenes/quick) with
erg-worker and measure laws of geomorphology on their heightfields; write
OUT/report.md with one section per law (measured, expected with its source,
pass or fail and by how much) and PNG plots. Thresholds: thresholds.json.

Usually started by `erg validate --out DIR [--quick]`, which passes --worker.
"""
import argparse
import fnmatch
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import measure as M  # noqa: E402

# The scenes every suite has; transverse_finest (a third resolution),
# transverse_crests (a bed on a torus wide enough to judge the crests'
# orientation) and barchans_expected (the barchans in the other transport
# mode) are run when the suite's folder holds them.
SCENES = ("barchans", "transverse_coarse", "transverse_fine")
OPTIONAL = ("transverse_finest", "transverse_crests", "barchans_expected")
# The wavelength law's beds: one torus at halved cells.
TRANSVERSE_CELLS = ("transverse_coarse", "transverse_fine", "transverse_finest")


def transverse_beds(names):
    """The transverse scenes among names: the strips at halved cells (the
    wavelength law) and the other beds (wide ones, for the crest law)."""
    trans = [n for n in names if n.startswith("transverse")]
    return [n for n in trans if n in TRANSVERSE_CELLS], [n for n in trans if n not in TRANSVERSE_CELLS]
# One pile under the same wind at angles to the grid (section 9); run when
# the suite's folder holds them, in each transport mode it has.
ISOTROPY = tuple(f"isotropy_{a:02d}{m}" for m in ("", "_expected") for a in (0, 23, 37, 45))


def log(msg):
    print(f"erg validate: {msg}", file=sys.stderr, flush=True)


# --- running the scenes -----------------------------------------------------------

def run_complete(out, job):
    snaps = sorted((out / "snapshots").glob("step_*.h5"))
    return bool(snaps) and snaps[-1].name == f"step_{job['run']['steps']:08d}.h5"


def _same_value(a, b):
    """A scene's value against the run's job.json (protobuf JSON: int64 as
    strings, numbers as the worker printed them)."""
    if isinstance(b, str) and not isinstance(a, str):
        try:
            b = float(b)
        except ValueError:
            return False
    if isinstance(a, bool) or isinstance(b, bool):
        return a == b
    if isinstance(a, (int, float)) and isinstance(b, (int, float)):
        return math.isclose(a, b, rel_tol=1e-6, abs_tol=0.0)
    return a == b


def job_difference(out, job):
    """The first field the scene sets that the run in OUT (its job.json) has
    with another value, as "field: run's -> scene's"; None when every field
    the scene sets agrees (run.checkpoint_every aside), or when OUT has no
    job.json to compare with. Defaults the scene leaves to the schema are
    not compared."""
    path = out / "job.json"
    if not path.exists():
        return None
    ran = json.loads(path.read_text())

    def walk(a, b, where):
        if isinstance(a, dict):
            if not isinstance(b, dict):
                return f"{where}: {b!r} -> {a!r}"
            for k, v in a.items():
                d = walk(v, b.get(k), f"{where}.{k}" if where else k)
                if d:
                    return d
            return None
        if isinstance(a, list):
            if not isinstance(b, list) or len(a) != len(b):
                return f"{where}: {len(b) if isinstance(b, list) else b!r} -> {len(a)} entries"
            for i, (x, y) in enumerate(zip(a, b)):
                d = walk(x, y, f"{where}[{i}]")
                if d:
                    return d
            return None
        return None if _same_value(a, b) else f"{where}: {b!r} -> {a!r}"

    # validate sets the checkpoints itself (checkpoint_every above), and
    # they are output only.
    run = {k: v for k, v in job.get("run", {}).items() if k != "checkpoint_every"}
    return walk(dict(job, run=run), ran, "")


def checkpoint_every(job):
    """Steps between the checkpoints validate asks of each scene: ten a run,
    so that an interrupted suite (the full one runs for hours) resumes with
    --reuse losing at most a tenth of a scene. A checkpoint is output only:
    the run resumed from it gives the same bits as one never stopped."""
    return max(1, int(job["run"]["steps"]) // 10)


def scene_cost(job):
    """Cells times steps: the order the scenes are run in, cheapest first, so
    that an interrupted suite has finished as many scenes as it could."""
    d = job["domain"]
    return int(d["nx"]) * int(d["ny"]) * int(job["run"]["steps"])


def _time_file(out):
    return Path(str(out) + ".time.json")


def _seconds_so_far(out):
    tf = _time_file(out)
    if not tf.exists():
        return 0.0
    try:
        return float(json.loads(tf.read_text())["seconds"])
    except (ValueError, KeyError, TypeError):
        return 0.0


def _write_seconds(out, seconds):
    tmp = Path(str(_time_file(out)) + ".tmp")
    tmp.write_text(json.dumps({"seconds": round(seconds, 1)}) + "\n")
    os.replace(tmp, _time_file(out))


def run_scene(worker, job_path, out, threads, reuse, index, count):
    """Runs one scene into OUT (erg-worker), or with reuse takes the run
    already there: a complete one as it is, an interrupted one resumed from
    its newest intact checkpoint (the worker's --resume), one that never
    reached a checkpoint started again. Returns the simulation wall time in
    seconds, summed over the invocations that ran it (None if unknown)."""
    job = json.loads(job_path.read_text())
    d = job["domain"]
    before = 0.0
    cmd = [worker, str(job_path), "--out", str(out)]
    if out.exists():
        if not reuse:
            raise SystemExit(f"erg validate: {out} exists; choose a new --out or pass --reuse")
        changed = job_difference(out, job)
        if changed:
            # The scene changed since that run (a newer erg's scenes): its
            # snapshots and checkpoints belong to another job.
            log(f"[{index}/{count}] {job['name']}: {out} holds a run of another job ({changed}); "
                "starting it again")
            shutil.rmtree(out)
            _time_file(out).unlink(missing_ok=True)
    if out.exists():
        if run_complete(out, job):
            log(f"[{index}/{count}] {job['name']}: reusing {out}")
            return _seconds_so_far(out) if _time_file(out).exists() else None
        if any((out / "checkpoints").glob("step_*.h5")):
            before = _seconds_so_far(out)
            log(f"[{index}/{count}] {job['name']}: resuming the interrupted run in {out} "
                "from its newest intact checkpoint")
            cmd = [worker, "--resume", str(out)]
        else:
            log(f"[{index}/{count}] {job['name']}: {out} holds a run interrupted before its "
                "first checkpoint; starting it again")
            shutil.rmtree(out)
            _time_file(out).unlink(missing_ok=True)
    log(f"[{index}/{count}] {job['name']}: {d['nx']} x {d['ny']} cells of {d['cell_size_m']} m, "
        f"{job['run']['steps']} steps")
    cmd += ["--checkpoint-every", str(checkpoint_every(job)), "--progress-fd", "1"]
    if threads:
        cmd += ["--threads", str(threads)]
    env = dict(os.environ)
    env.setdefault("OMP_WAIT_POLICY", "PASSIVE")
    t0 = time.time()
    with open(str(out) + ".log", "a") as errlog:
        p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=errlog, text=True, env=env)
        last = -1
        for line in p.stdout:
            try:
                ev = json.loads(line)
            except ValueError:
                continue
            # erg.v1.WorkerEvent (proto/erg/v1/worker.proto) in protobuf
            # JSON: int64 fields are strings.
            if isinstance(ev, dict) and "progress" in ev:
                step, steps = int(ev.get("step", 0)), int(ev["progress"].get("steps", 1))
                decile = (10 * step) // max(steps, 1)
                if decile != last:
                    last = decile
                    # The time so far, kept for a resume after an interruption.
                    _write_seconds(out, before + time.time() - t0)
                    log(f"[{index}/{count}] {job['name']}: step {step}/{steps} "
                        f"({before + time.time() - t0:.0f} s)")
        rc = p.wait()
    if rc != 0:
        tail = Path(str(out) + ".log").read_text()[-2000:]
        raise SystemExit(f"erg validate: erg-worker failed on {job_path} (exit {rc}):\n{tail}")
    seconds = before + time.time() - t0
    _write_seconds(out, seconds)
    log(f"[{index}/{count}] {job['name']}: done in {seconds:.0f} s")
    return seconds


def snapshots(run_dir):
    return [M.load_snapshot(p) for p in sorted((run_dir / "snapshots").glob("step_*.h5"))]


# --- laws -------------------------------------------------------------------------------

# A law whose scenes were left out of this invocation (--skip).
NOT_RUN = "not run"


def verdict(ok):
    """PASS, FAIL, (ok None) UNRESOLVED: the scene's periodic domain cannot
    resolve the law's tolerance (measure.wavelength_resolution,
    measure.orientation_resolution), or (ok NOT_RUN) NOT RUN: some of the
    law's scenes were skipped."""
    if ok is NOT_RUN:
        return "**NOT RUN**"
    return "**UNRESOLVED**" if ok is None else ("**PASS**" if ok else "**FAIL**")


def word(ok):
    return verdict(ok).strip("*")


def combine(oks):
    """One law over several cases: FAIL if any fails, else UNRESOLVED if any
    is, else PASS."""
    # None is UNRESOLVED; any other false value (numpy's False among them,
    # which `is False` misses) fails.
    oks = list(oks)
    if any(ok is not None and not ok for ok in oks):
        return False
    return None if any(ok is None for ok in oks) else True


def fmt(x, nd=3):
    return f"{x:.{nd}g}" if isinstance(x, float) else str(x)


class Report:
    def __init__(self, out, plot_suffix=""):
        self.out = out
        self.lines = []
        self.summary = []  # (law, verdict, one-line measured)
        # Told apart in plots/ when a law is measured on one scene per transport mode.
        self.plot_suffix = plot_suffix

    def add(self, *lines):
        self.lines.extend(lines)

    def plot(self, fig, name, alt, dpi=110):
        """Writes the figure to plots/NAME and links it here."""
        import matplotlib.pyplot as plt
        fig.tight_layout()
        if self.plot_suffix:
            name = name.replace(".png", f"{self.plot_suffix}.png")
        fig.savefig(plot_path(self.out, name), dpi=dpi)
        plt.close(fig)
        self.add(f"![{alt}](plots/{name})", "")

    def law(self, name, ok, measured):
        # A plain bool (numpy's comparisons give numpy.bool_), so that the
        # summary's `ok is True` counts it; None is UNRESOLVED.
        self.summary.append((name, ok if ok is None or ok is NOT_RUN else bool(ok), measured))


def wind_of(job):
    """The scenes blow one constant wind: the laws are stated for one."""
    if "constant" not in job.get("wind", {}):
        raise SystemExit(f"erg validate: scene {job.get('name')}: the laws need a constant wind")
    return float(job["wind"]["constant"].get("direction_deg", 0.0))


YEAR_S = 365.25 * 86400.0
ERG = "erg"
_CAL = {}


def physical(job):
    return job.get("wind", {}).get("speed_is", "MODEL").upper() in ("SHEAR_VELOCITY", "WIND_AT_HEIGHT")


def model_units_caveat(jobs):
    """What a bed scene in model units shows (docs/dune-forms.md, "What makes
    a bed unstable"): its pattern depends on the slab, so a verdict on it is
    one on the scene's slab. Empty where every scene is in physical units."""
    model = sorted(j.get("name", "an unnamed scene") for j in jobs if not physical(j))
    if not model:
        return ""
    return (" **Model units:** " + ", ".join(model) + " are in model units, where no term of the model "
            "makes a flat bed of sand unstable at small amplitude (the shear-stress perturbation, whose "
            "upwind shift of the stress does, is on in physical units only). Measured on these beds "
            "(docs/dune-forms.md, \"What makes a bed unstable\"): crests grow from lifts a large part of "
            "a cell high (EXPECTED forms crests with lifts of half a cell); with slabs of 1/8 of the "
            "cell or less the EXPECTED bed flattens; the STOCHASTIC lifts' noise roughens it, and "
            "under two winds no pattern forms at 1/40 to 1/640 of the cell, while under one wind "
            "crests across it form at 1/40 (the suite's slab) but none at 1/160. So a verdict on "
            "these scenes is one on their slab; in physical units both transport modes form crests "
            "at slabs where they are converged.")


def calibrate(job_path, ratios=None, drift_steps=20000):
    """`erg calibrate` of a scene (JSON), cached per arguments."""
    key = (str(job_path), ratios, drift_steps)
    if key not in _CAL:
        cmd = [ERG, "calibrate", str(job_path), "--drift-steps", str(drift_steps)]
        if ratios:
            cmd += ["--ratios", ratios]
        p = subprocess.run(cmd, capture_output=True, text=True)
        if p.returncode != 0:
            raise SystemExit(f"erg validate: {' '.join(cmd)} failed:\n{p.stderr[-2000:]}")
        _CAL[key] = json.loads(p.stdout)
    return _CAL[key]


_SCENE_PATHS = {}
_RESOLVED = {}


def resolved(job):
    """The job with every default filled in, as the worker runs it (`erg
    check`), so that no default is repeated here. Cached per job: two jobs
    of one name but different contents are resolved apart."""
    key = json.dumps(job, sort_keys=True)
    if key not in _RESOLVED:
        path = _SCENE_PATHS.get(job.get("name"))
        if path is not None and json.loads(Path(path).read_text()) != job:
            path = None  # changed since it was read from its scene file
        tmp = None
        if path is None:  # a job not read from a scene file, or changed since
            tmp = tempfile.NamedTemporaryFile("w", suffix=".json", delete=False)
            json.dump(job, tmp)
            tmp.close()
            path = tmp.name
        try:
            p = subprocess.run([ERG, "check", str(path)], capture_output=True, text=True)
        finally:
            if tmp:
                os.unlink(tmp.name)
        if p.returncode != 0:
            raise SystemExit(f"erg validate: erg check {path} failed:\n{p.stderr[-2000:]}")
        _RESOLVED[key] = json.loads(p.stdout)
    return _RESOLVED[key]


def slab_m(job):
    return float(resolved(job)["model"]["slab_m"])


def repose_deg(job):
    return float(resolved(job)["model"]["repose_deg"])


def transport_of(job):
    """EXPECTED or STOCHASTIC, with the proto's default where the job says nothing."""
    return resolved(job)["transport"]


def flux_of_scene(job):
    """The model's saturated flux (m^2/yr) under the scene's constant wind, or
    None in model units."""
    if not physical(job):
        return None
    path = _SCENE_PATHS[job["name"]]
    base = calibrate(path, None, 1)
    r = resolved(job)
    w = r["wind"]
    speed = float(w["constant"]["speed_mps"])
    if w["speed_is"] == "WIND_AT_HEIGHT":
        ph = r["physics"]
        d = float(ph["grain_diameter_m"])
        z0 = float(w["roughness_m"]) or d / 30.0  # 0: d / 30 (job.proto, roughness_m)
        speed *= float(ph["von_karman"]) / math.log(float(w["height_m"]) / z0)
    ratio = speed / base["threshold_mps"]
    f = calibrate(path, f"{ratio:.9g}", 1)["flux"][0]
    return f["sim_m2_per_s"] * YEAR_S


def wind_text(job):
    w = job["wind"]["constant"]
    kind = job["wind"].get("speed_is", "MODEL").upper()
    if kind == "SHEAR_VELOCITY":
        return f"of u* = {w['speed_mps']} m/s"
    if kind == "WIND_AT_HEIGHT":
        return f"of {w['speed_mps']} m/s at {job['wind'].get('height_m', 10)} m"
    return f"of {w['speed_mps']} m/s (model units)"


def plot_path(out, name):
    (out / "plots").mkdir(exist_ok=True)
    return out / "plots" / name


def shape_failures(judged, off_aspect, horns_upwind):
    """Which half of the shape law failed, in numbers: how many of the judged
    dunes stand outside the H/W range, and how many have horns that do not
    point downwind (the two halves fail for different causes)."""
    return ([f"H/W outside the range on {off_aspect} of {judged}"] if off_aspect else []) + \
           ([f"horns not downwind on {horns_upwind} of {judged}"] if horns_upwind else [])


def barchan_laws(rep, T, run_dir, job):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    det = T["detection"]
    snaps = snapshots(run_dir)
    cell = snaps[0]["cell_size_m"]
    ny, nx = snaps[0]["sand"].shape
    wind = wind_of(job)
    first = int(len(snaps) * T["barchan_speed"]["fit_from_fraction"])
    first = min(first, len(snaps) - 2)
    window = snaps[first:]
    frames = [M.dunes(s["sand"], cell, det["dune_sand_threshold_m"], det["dune_min_cells"])
              for s in window]
    for snap, frame in zip(window, frames):
        for d in frame:
            d["width_m"] = M.barchan_shape(d, snap["sand"], cell, wind)["width_m"]
    steps = [s["step"] for s in window]
    years = [s["time_years"] for s in window]
    max_jump = 0.25 * min(nx, ny) * cell
    tracks = M.track(frames, (nx * cell, ny * cell), max_jump)
    rows = []
    for t in tracks:
        v_step = M.migration_speed((t["x"], t["y"]), steps, wind)
        v_yr = M.migration_speed((t["x"], t["y"]), years, wind)
        rows.append({"y": t["y"][-1] % (ny * cell), "h": float(np.mean(t["h"])),
                     "w": float(np.nanmean(t["w"])),
                     "vol": float(np.mean(t["v"])), "v_step": v_step, "v_yr": v_yr,
                     "x0": t["x"][0], "x1": t["x"][-1]})
    rows.sort(key=lambda r: r["h"])

    # --- 1. speed against height
    S = T["barchan_speed"]
    qsat = flux_of_scene(job)  # m^2/yr, None in model units
    rep.add("## 1. Barchan migration speed against height", "")
    rep.add(f"Scene `{run_dir.name}`: {len(job['layers']['sand'].get('piles', []))} isolated cones of sand on a "
            f"non-erodible flat bed, one wind {wind_text(job)} towards "
            f"{wind:g} deg, {transport_of(job)} transport. Dunes are the 8-connected bodies of sand thicker "
            f"than {det['dune_sand_threshold_m']} m (periodic labelling), tracked by their "
            f"sand-weighted centroid unwrapped on the torus over steps {steps[0]}-{steps[-1]} "
            f"(the second half of the run); the speed is the least-squares slope of the along-wind "
            f"position, the height the mean peak sand height and W the mean across-wind width over "
            f"the same snapshots."
            + (f" Saturated flux of the scene's wind Q_sat = {qsat:.1f} m^2/yr (the model's flat-bed "
               f"flux through the calibrated time per step, section 7)." if qsat else ""), "")
    rep.add("| dune (y, m) | height H (m) | width W (m) | volume (m^3) | speed (m/step) | speed (m/yr) | c H / Q_sat |",
            "|---|---|---|---|---|---|---|")
    for r in rows:
        r["rate"] = r["v_yr"] * r["h"] / qsat if qsat else float("nan")
        rep.add(f"| {r['y']:.0f} | {r['h']:.2f} | {r['w']:.0f} | {r['vol']:.0f} | {r['v_step']:.4f} | "
                f"{r['v_yr']:.2f} | {r['rate']:.3f} |")
    rep.add("")
    ok_speed = False
    big = [r for r in rows if r["h"] >= S["min_height_m"]]
    if len(big) >= 2 and all(r["v_step"] > 0 for r in rows):
        slope, b, resid = M.loglog_fit([r["h"] for r in big], [r["v_yr"] for r in big])
        dev = slope - S["expected_slope"]
        ok_slope = abs(dev) <= S["tolerance"]
        rates = [r["rate"] for r in big]
        spread = (max(rates) - min(rates)) / float(np.mean(rates)) if qsat else float("nan")
        ok_rate = bool(qsat) and spread <= S["max_rate_spread"]
        ok_speed = ok_slope and ok_rate
        A, H0 = M.cutoff_fit([r["h"] for r in rows], [r["v_yr"] for r in rows])
        rep.add(f"Fit log(speed) = a log(H) + b over the {len(big)} dunes of at least "
                f"{S['min_height_m']:g} m: **a = {slope:.3f}** (rms residual {resid:.3f} in log units). "
                f"Expected a = {S['expected_slope']:g} +/- {S['tolerance']:g}. {verdict(ok_slope)}: the exponent is "
                f"{abs(dev):.2f} {'above' if dev > 0 else 'below'} the expected value"
                + ("" if ok_slope else f", {abs(dev) - S['tolerance']:.2f} outside the tolerance") + ".", "")
        rep.add("Dimensionless rate c H / Q_sat over the same dunes: "
                + (f"{min(rates):.3f}-{max(rates):.3f}, a spread of **{100 * spread:.0f}%** of the mean "
                   f"(allowed {100 * S['max_rate_spread']:.0f}%). {verdict(ok_rate)}." if qsat else
                   f"not measured: the scene's wind is in model units (no Q_sat). {verdict(False)}."), "")
        rep.add(f"Cut-off law fitted over all {len(rows)} dunes, c = A / (H + H0): A = {A:.1f} m^2/yr"
                + (f" = {A / qsat:.2f} Q_sat" if qsat and A == A else "")
                + f", H0 = {H0:.2f} m (Andreotti et al. 2002; Hersen et al. 2002).", "")
        fig, ax = plt.subplots(figsize=(5, 4))
        h = np.array([r["h"] for r in rows])
        v = np.array([r["v_yr"] for r in rows])
        ax.loglog(h, v, "o", label="erg")
        hh = np.linspace(h.min() * 0.9, h.max() * 1.1, 20)
        vb = np.array([r["v_yr"] for r in big])
        hb = np.array([r["h"] for r in big])
        ax.loglog(hh, np.exp(b) * hh ** slope, "-",
                  label=f"fit H >= {S['min_height_m']:g} m, slope {slope:.2f}")
        ax.loglog(hh, vb[0] * (hh / hb[0]) ** -1.0, "--", label="slope -1 (Bagnold)")
        if A == A and A > 0:
            ax.loglog(hh, A / (hh + H0), ":", label=f"A/(H+H0), H0 = {H0:.1f} m")
        ax.set_xlabel("dune height H (m)")
        ax.set_ylabel("migration speed (m/yr)")
        ax.legend(fontsize=7)
        ax.set_title(f"Barchan speed against height ({transport_of(job)})")
        rep.plot(fig, "barchan_speed.png", "barchan speed", dpi=110)
        rep.law("Barchan speed c = a Q / (H + H0)", ok_speed,
                f"slope {slope:.2f} over H >= {S['min_height_m']:g} m (expected -1 +/- {S['tolerance']:g}); "
                + (f"c H / Q_sat spread {100 * spread:.0f}%" if qsat else "no Q_sat (model units)"))
    else:
        rep.add(f"{verdict(False)}: fewer than two dunes of at least {S['min_height_m']:g} m survived "
                f"to be tracked ({len(big)} of {len(rows)}), or one did not move downwind.", "")
        rep.law("Barchan speed c = a Q / (H + H0)", False,
                f"{len(big)} dunes of at least {S['min_height_m']:g} m tracked")
    rep.add(f"Source: {S['source']}.", "")

    # --- 2. shape
    B = T["barchan_shape"]
    repose = repose_deg(job)
    last = snaps[-1]
    height = last["sand"] + last["bedrock"]
    final = M.dunes(last["sand"], cell, det["dune_sand_threshold_m"], det["dune_min_cells"])
    ang, direction = M.steepest_descent(height, cell)
    rel = np.radians(direction - wind)
    rep.add("## 2. Barchan shape", "")
    rep.add(f"Final snapshot (step {last['step']}). Aspect = peak height / horn-to-horn width "
            f"(across-wind extent of the body); horns point downwind when the mean along-wind "
            f"position of the outermost 10% (across the wind) lies downwind of the crest. Only "
            f"dunes with a slip face (a lee cell within {B['slip_face_margin_deg']:g} deg of the "
            f"repose angle {repose:g} deg) are judged. The windward slope (reported, not judged) is the "
            f"mean slope from the crest upwind to the toe (measure.windward_slope): field barchans' "
            f"are about 10 deg, their slip face alone at repose."
            + (" The shape is measured at the scene's step (model.slab_m "
               f"{slab_m(job):g} m): with the shear stress on it is not "
               "converged in the step, each halving of the step down to 1/160 of the cell making these "
               "dunes taller and narrower by 5-10% (docs/physical-units.md, 'The step with the stress "
               "on')." if physical(job) else ""), "")
    rep.add("| dune (y, m) | H (m) | W (m) | H/W | horn offset (m) | horns downwind | slip face | windward slope (deg) |",
            "|---|---|---|---|---|---|---|---|")
    aspects, off_aspect, horns_upwind = [], 0, 0  # over the dunes with a slip face
    for d in final:
        sh = M.barchan_shape(d, last["sand"], cell, wind)
        lee = (np.cos(rel[d["iy"], d["ix"]]) > 0) & (ang[d["iy"], d["ix"]] >= repose - B["slip_face_margin_deg"])
        slip = bool(lee.any())
        rep.add(f"| {d['y_m']:.0f} | {sh['height_m']:.2f} | {sh['width_m']:.0f} | {sh['aspect']:.3f} | "
                f"{sh['horn_offset_m']:+.1f} | {'yes' if sh['horns_downwind'] else 'no'} | "
                f"{'yes' if slip else 'no'} | "
                f"{M.windward_slope(d, last['sand'], height, cell, wind, det['dune_sand_threshold_m']):.1f} |")
        if slip:
            off_aspect += not B["min"] <= sh["aspect"] <= B["max"]
            horns_upwind += not sh["horns_downwind"]
            aspects.append(sh["aspect"])
    rep.add("")
    judged = len(aspects)
    if judged == 0:
        rep.add(f"{verdict(False)}: no dune with a slip face.", "")
        rep.law("Barchan H/W ~ 0.1, horns downwind", False, "no dune with a slip face")
    else:
        failing = "".join(f"; {f}" for f in shape_failures(judged, off_aspect, horns_upwind))
        ok_shape = not failing
        rep.add(f"Expected H/W = {B['expected_aspect']:g} within [{B['min']:g}, {B['max']:g}] and "
                f"horns downwind, for each of the {judged} dunes with a slip face. {verdict(ok_shape)}: "
                f"H/W from {min(aspects):.3f} to {max(aspects):.3f}{failing}.", "")
        rep.law("Barchan H/W ~ 0.1, horns downwind", ok_shape,
                f"H/W {min(aspects):.3f}-{max(aspects):.3f} over {judged} dunes{failing}")
    fig, ax = plt.subplots(figsize=(7, 7 * ny / nx + 0.6))
    im = ax.imshow(last["sand"], origin="lower", extent=(0, nx * cell, 0, ny * cell), cmap="YlOrBr")
    for d in final:
        ax.plot(d["x_m"], d["y_m"], "k+")
    ax.annotate("", xy=(0.95 * nx * cell, 0.97 * ny * cell), xytext=(0.8 * nx * cell, 0.97 * ny * cell),
                arrowprops=dict(arrowstyle="->"))
    ax.text(0.8 * nx * cell, 0.92 * ny * cell, "wind", fontsize=8)
    fig.colorbar(im, ax=ax, label="sand (m)", shrink=0.8)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(f"Barchans at step {last['step']}, {transport_of(job)} (+: centroids)")
    rep.plot(fig, "barchans.png", "barchans", dpi=110)
    rep.add(f"Source: {B['source']}.", "")

    # --- 6 (data): migration rate
    return rows, snaps, repose


def migration_law(rep, T, rows, job):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    R = T["migration_rate"]
    rep.add("## 6. Migration rate in physical units", "")
    qsat = flux_of_scene(job)
    if not qsat:
        rep.add(f"{verdict(False)}: the scene's wind is in model units: a step is model.time_step_days, "
                "a label, and no flux is defined to compare with the field.", "")
        rep.law("Migration rate against Tarfaya", False, "model units")
        return
    rep.add(f"The barchans of section 1 in metres per year (the snapshots' time_years: steps times "
            f"the measured time per step, section 7) against the field law of Tarfaya, "
            f"c = {R['c_coefficient']:g} Q / (W + {R['w0_m']:g} m), evaluated at the model's saturated "
            f"flux Q_sat = {qsat:.1f} m^2/yr (Tarfaya's measured flux: {R['field_flux_m2_per_yr']:g} "
            f"m^2/yr) and each dune's width W.", "")
    if not rows:
        rep.add(f"{verdict(False)}: no dune tracked.", "")
        rep.law("Migration rate against Tarfaya", False, "no dune tracked")
        return
    rep.add("| H (m) | W (m) | erg (m/yr) | Tarfaya law at W (m/yr) | ratio | within x"
            f"{R['max_factor']:g} |", "|---|---|---|---|---|---|")
    ok = True
    ratios = []
    for r in rows:
        field = R["c_coefficient"] * qsat / (r["w"] + R["w0_m"])
        ratio = r["v_yr"] / field
        inside = 1.0 / R["max_factor"] <= ratio <= R["max_factor"]
        ok = ok and inside
        ratios.append(ratio)
        r["field_yr"] = field
        rep.add(f"| {r['h']:.2f} | {r['w']:.0f} | {r['v_yr']:.2f} | {field:.2f} | {ratio:.2f} | "
                f"{'yes' if inside else 'no'} |")
    rep.add("")
    rep.add(f"Expected each ratio in [{1 / R['max_factor']:.2f}, {R['max_factor']:g}]. {verdict(ok)}: "
            f"ratios {min(ratios):.2f}-{max(ratios):.2f}.", "")
    fig, ax = plt.subplots(figsize=(5, 3.5))
    w = np.array([r["w"] for r in rows])
    ww = np.linspace(max(1.0, w.min() * 0.8), w.max() * 1.2, 50)
    law = R["c_coefficient"] * qsat / (ww + R["w0_m"])
    ax.fill_between(ww, law / R["max_factor"], law * R["max_factor"], color="0.9",
                    label=f"Tarfaya law x/ {R['max_factor']:g}")
    ax.plot(ww, law, "k-", lw=0.8)
    ax.plot(w, [r["v_yr"] for r in rows], "o", label="erg")
    ax.set_xlabel("dune width W (m)")
    ax.set_ylabel("migration (m/yr)")
    ax.set_title(f"Migration against Tarfaya ({transport_of(job)})")
    ax.legend(fontsize=7)
    rep.plot(fig, "migration_rate.png", "migration rate", dpi=110)
    rep.add(f"Source: {R['source']}.", "")
    rep.law("Migration rate against Tarfaya", ok, f"erg / field {min(ratios):.2f}-{max(ratios):.2f}")


def flux_law(rep, T, cal, job):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    F = T["flux_law"]
    rep.add("## 7. Flat-bed flux against the flux law", "")
    if cal is None:
        rep.add(f"{verdict(False)}: the scene's wind is in model units; no law to compare.", "")
        rep.law("Flat-bed flux follows the law", False, "model units")
        return
    rep.add(f"`erg calibrate` on the barchan scene's parameters: flat sand, constant u*; the sand "
            f"crossing a line per metre per step (m^2 of bulk sand), divided by the time per step "
            f"measured at u* = {cal['reference_mps']:.3f} m/s ({cal['dt_s']:.0f} s = "
            f"{cal['dt_s'] / 86400:.3f} days), against {cal['law']}, fluid threshold u_t = "
            f"{cal['threshold_mps']:.4f} m/s (Bagnold 1941).", "")
    rep.add("| u* / u_t | u* (m/s) | model (m^2/step) | erg (m^2/yr) | law (m^2/yr) | erg / law |",
            "|---|---|---|---|---|---|")
    ok = True
    worst = 0.0
    for f in cal["flux"]:
        ratio = f["sim_m2_per_s"] / f["law_m2_per_s"]
        worst = max(worst, abs(ratio - 1))
        ok = ok and abs(ratio - 1) <= F["max_relative_error"]
        rep.add(f"| {f['ratio']:.2f} | {f['ustar_mps']:.3f} | {f['model_m2_per_step']:.4f} | "
                f"{f['sim_m2_per_s'] * YEAR_S:.1f} | {f['law_m2_per_s'] * YEAR_S:.1f} | {ratio:.4f} |")
    rep.add("")
    rep.add(f"Expected within {100 * F['max_relative_error']:g}%. {verdict(ok)}: worst "
            f"{100 * worst:.2f}%.", "")
    fig, ax = plt.subplots(figsize=(5, 3.5))
    u = [f["ustar_mps"] for f in cal["flux"]]
    ax.plot(u, [f["law_m2_per_s"] * YEAR_S for f in cal["flux"]], "k-", label="law")
    ax.plot(u, [f["sim_m2_per_s"] * YEAR_S for f in cal["flux"]], "o", label="erg, flat bed")
    ax.axvline(cal["threshold_mps"], color="r", lw=0.8, label="u_t")
    ax.set_xlabel("u* (m/s)")
    ax.set_ylabel("bulk flux (m^2/yr)")
    ax.legend(fontsize=7)
    rep.plot(fig, "flux_law.png", "flux law", dpi=110)
    rep.add(f"Source: {F['source']}.", "")
    rep.law("Flat-bed flux follows the law", ok, f"worst {100 * worst:.2f}% from 1.1 to 3 u_t")


def drift_law(rep, T, drift, name):
    D = T["drift"]
    rep.add("## 8. Wind-rose drift: DP, RDP, RDD", "")
    if drift is None:
        rep.add(f"{verdict(False)}: no wind-rose scene (drift_rose.json) in the suite.", "")
        rep.law("Wind-rose drift matches DP, RDP, RDD", False, "no scene")
        return
    d = drift["drift"]
    rep.add(f"Scene `{name}`: the rose's own draws over {d['steps']} steps, each of its {d['winds']} "
            "winds' flat-bed flux measured (`erg calibrate`) and converted with the measured time per "
            "step, against Fryberger & Dean's numbers from the same law and the rose's probabilities "
            "(per year of wind; bulk m^2/yr).", "")
    e_dp = d["sim_dp_m2_per_s"] / d["law_dp_m2_per_s"] - 1
    e_rdp = d["sim_rdp_m2_per_s"] / d["law_rdp_m2_per_s"] - 1
    e_dir = (d["sim_rdd_deg"] - d["law_rdd_deg"] + 540.0) % 360.0 - 180.0
    rep.add("| quantity | Fryberger & Dean (law) | erg | difference |", "|---|---|---|---|")
    rep.add(f"| DP (m^2/yr) | {d['law_dp_m2_per_s'] * YEAR_S:.2f} | {d['sim_dp_m2_per_s'] * YEAR_S:.2f} | {100 * e_dp:+.2f}% |")
    rep.add(f"| RDP (m^2/yr) | {d['law_rdp_m2_per_s'] * YEAR_S:.2f} | {d['sim_rdp_m2_per_s'] * YEAR_S:.2f} | {100 * e_rdp:+.2f}% |")
    rep.add(f"| RDD (deg) | {d['law_rdd_deg']:.2f} | {d['sim_rdd_deg']:.2f} | {e_dir:+.2f} deg |")
    rep.add(f"| RDP/DP | {d['law_rdp_m2_per_s'] / d['law_dp_m2_per_s']:.3f} | "
            f"{d['sim_rdp_m2_per_s'] / d['sim_dp_m2_per_s']:.3f} | |")
    rep.add("")
    ok = (abs(e_dp) <= D["max_relative_error"] and abs(e_rdp) <= D["max_relative_error"]
          and abs(e_dir) <= D["max_direction_error_deg"])
    rep.add(f"Expected DP and RDP within {100 * D['max_relative_error']:g}%, RDD within "
            f"{D['max_direction_error_deg']:g} deg. {verdict(ok)}.", "")
    rep.add(f"Source: {D['source']}.", "")
    rep.law("Wind-rose drift matches DP, RDP, RDD", ok,
            f"DP {100 * e_dp:+.1f}%, RDP {100 * e_rdp:+.1f}%, RDD {e_dir:+.1f} deg")


def slip_face_law(rep, T, barchan_snaps, finals, repose, job):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    S = T["slip_face"]
    det = T["detection"]
    last = barchan_snaps[-1]
    cell = last["cell_size_m"]
    height = last["sand"] + last["bedrock"]
    lee = M.lee_slopes_deg(height, last["sand"], cell, wind_of(job), det["dune_sand_threshold_m"])
    top = repose + S["max_excess_deg"]
    plo, phi, counts, edges = M.histogram_peak(lee, S["bin_deg"], top)
    peak = 0.5 * (plo + phi)
    # The fullest bin must lie in [repose - margin, repose + allowed residual].
    ok_peak = plo >= repose - S["peak_below_repose_deg"] - 1e-9 and phi <= top + 1e-9
    rep.add("## 3. Slip faces", "")
    rep.add(f"Lee slopes: on the barchans' final snapshot (step {last['step']}), every cell with "
            f"more than {det['dune_sand_threshold_m']} m of sand whose steepest descent (8 "
            f"neighbours, as avalanching sees them) points downwind; {len(lee)} cells, histogram in "
            f"{S['bin_deg']:g} deg bins, the last ending at repose + the allowed residual "
            f"({top:g} deg). Expected: the fullest bin within "
            f"{S['peak_below_repose_deg']:g} deg below the repose angle {repose:g} deg.", "")
    rep.add(f"Fullest bin **{plo:.1f}-{phi:.1f} deg**. {verdict(ok_peak)}"
            + ("" if ok_peak else f": {abs(peak - repose):.1f} deg from the repose angle") + ".", "")
    rep.add("Steepest slope anywhere after each scene's last step, over every pair of neighbours "
            "whose higher cell holds sand (what [N24] eq. 9 bounds); allowed: repose + "
            f"{S['max_excess_deg']:g} deg.", "")
    rep.add(f"| scene | steepest (deg) | sand pairs | above repose | above repose + {S['max_excess_deg']:g} "
            "| within bound |", "|---|---|---|---|---|---|")
    ok_max = True
    worst = 0.0
    for name, snap in finals:
        h = snap["sand"] + snap["bedrock"]
        mx, allang = M.max_sand_slope_deg(h, snap["sand"], snap["cell_size_m"])
        within = mx <= repose + S["max_excess_deg"]
        ok_max = ok_max and within
        worst = max(worst, mx)
        rep.add(f"| {name} | {mx:.2f} | {allang.size} | {int((allang > repose).sum())} | "
                f"{int((allang > repose + S['max_excess_deg']).sum())} | {'yes' if within else 'no'} |")
    rep.add("")
    rep.add(f"{verdict(ok_max)}: steepest {worst:.2f} deg against {repose:g} + {S['max_excess_deg']:g}"
            + ("" if ok_max else f", {worst - repose - S['max_excess_deg']:.2f} deg too steep") + ".", "")
    fig, ax = plt.subplots(figsize=(5, 3.5))
    ax.bar(edges[:-2], counts[:-1], width=S["bin_deg"] * 0.9, align="edge")
    ax.axvline(repose, color="r", label=f"repose {repose:g} deg")
    ax.set_xlim(0, 45)
    ax.set_xlabel("lee slope (deg)")
    ax.set_ylabel("cells")
    ax.legend()
    ax.set_title("Lee slopes of the barchans")
    rep.plot(fig, "lee_slopes.png", "lee slopes", dpi=110)
    rep.add(f"Source: {S['source']}.", "")
    rep.law("Slip faces at repose", ok_peak and ok_max, f"lee mode {plo:.1f}-{phi:.1f} deg, steepest {worst:.2f} deg")


def transverse_measure(R, name, snap, job):
    """Section 4's measurements of one transverse bed's final snapshot."""
    h = snap["sand"] + snap["bedrock"]
    cell = snap["cell_size_m"]
    o = M.structure_orientation(h, cell)
    sp = M.spectrum_wavelength(h, cell)
    ny, nx = h.shape
    wind = wind_of(job)
    # The lattice near the measured wavelength: along the wind (the crests
    # lie across it) and for crests perpendicular to it.
    along = (nx if abs(math.cos(math.radians(wind))) >= abs(math.sin(math.radians(wind))) else ny) * cell
    repose = repose_deg(job)
    return {"name": name, "cell": cell, "h": h, "o": o, "sp": sp, "step": snap["step"],
            "years": snap.get("time_years"),
            "bare": M.bare_fraction(snap["sand"]),
            "faces": M.repose_faces(h, snap["sand"], cell, wind, repose, R["faces_min_sand_m"],
                                    R["faces_within_deg"]),
            "angle": M.crest_wind_angle(o["crest_deg"], wind),
            "spec_angle": M.crest_wind_angle((sp["wavevector_deg"] + 90) % 180, wind),
            "spacing": M.wavelength_resolution(sp["wavelength_m"], along),
            "lattice": M.orientation_resolution(sp["wavelength_m"], nx * cell, ny * cell,
                                                (wind + 90.0) % 180.0, R["angle_tolerance_deg"])}


def transverse_law(rep, T, scenes, crests=()):
    """scenes: (name, final snapshot, job) of one torus from the coarsest
    cells to the finest, for the wavelength law; crests: (name, final
    snapshot, job) of beds on a torus wide enough to judge the crests'
    orientation (a strip one wavelength wide admits only crests across the
    wind). The crest law is judged on every bed whose torus resolves it."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    R = T["transverse"]
    rep.add("## 4. Transverse dunes", "")
    if not scenes:  # the strips left out (--skip): the wide bed alone
        scenes, crests = crests, ()
    res = [transverse_measure(R, *s) for s in scenes]
    cres = [transverse_measure(R, *s) for s in crests]
    c = res[0]
    ny, nx = c["h"].shape
    sand = describe_sand(scenes[0][2])
    years = [r["years"] for r in res]
    when = ("step " + ", ".join(str(r["step"]) for r in res)
            + ("; " + ", ".join(f"{y:.2f}" for y in years) + " years"
               if None not in years and physical(scenes[0][2]) else ""))
    rep.add(f"The same {nx * c['cell']:g} m x {ny * c['cell']:g} m torus of sand"
            + (f" ({sand})" if sand else "")
            + f", one wind towards {wind_of(scenes[0][2]):g} deg, at "
            + ", ".join(f"{r['cell']:g} m" for r in res) + f" cells; final snapshots ({when})"
            + "".join(f"; and {r['name']}, {r['h'].shape[1] * r['cell']:g} m x {r['h'].shape[0] * r['cell']:g} m "
                      f"at {r['cell']:g} m cells (step {r['step']}), for the crests" for r in cres) + ". "
            "Transverse dunes are those of an erodible bed, sand everywhere: the share of bare rock "
            "is listed. "
            "Crest orientation from the structure tensor of the height gradient over the spectrum's "
            "dominant band (|k| within a factor 2 of the spectral peak; coherence 1: parallel ridges; "
            "the band keeps the steep cell-scale noise of stochastic lifts from hiding the crests), "
            "and from the peak of the 2-D power spectrum; wavelength = 1 / power-weighted mean |k| "
            "over the same band. The torus admits only the wavelengths L / |(m, n)| and the crests "
            "across those lattice vectors (docs/dune-forms.md, \"What a periodic domain can "
            "resolve\"): the lattice columns give the relative spacing of the admissible "
            "wavelengths at the measured one along the wind, and the largest gap between the "
            "admissible crest orientations near the transverse one; a law is judged on the beds where "
            "they are at most half its tolerance, and is UNRESOLVED where no bed resolves it, unless "
            "a measurement lies beyond what the lattice alone can move it to (then it FAILs). "
            "The forms (reported, not judged): the shares of the sand cells whose steepest descent "
            f"stands within {R['faces_within_deg']:g} deg of repose or steeper, facing downwind "
            "(slip faces) and upwind (measure.repose_faces); a transverse dune of the field is "
            "asymmetric, a gentle windward face and a slip face at repose in the lee (McKee 1979), "
            "so its share at repose faces downwind."
            + model_units_caveat([j for _, _, j in list(scenes) + list(crests)]), "")
    rep.add("| bed | cells | crest-wind angle, tensor (deg) | coherence | crest-wind angle, spectrum (deg) "
            "| wavelength (m) | spectral peak (m) | lattice: wavelength spacing | lattice: crest gap (deg) "
            "| bare rock | at repose, lee | at repose, windward |",
            "|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in res + cres:
        rep.add(f"| {r['name']} | {r['cell']:g} m | {r['angle']:.1f} | {r['o']['coherence']:.2f} | "
                f"{r['spec_angle']:.1f} | {r['sp']['wavelength_m']:.1f} | "
                f"{r['sp']['peak_wavelength_m']:.1f} | {100 * r['spacing']:.1f}% | "
                f"{r['lattice']['gap_deg']:.1f} | {100 * r['bare']:.1f}% | "
                f"{100 * r['faces'][0]:.1f}% | {100 * r['faces'][1]:.1f}% |")
    rep.add("")
    tol_a = R["angle_tolerance_deg"]
    expected = R["expected_crest_wind_angle_deg"]
    lo = expected - tol_a
    every = res + cres
    judged = [r for r in every if r["lattice"]["gap_deg"] <= 0.5 * tol_a]
    # A bed whose torus cannot judge the law still FAILs it with a crest
    # beyond what the lattice alone can force.
    beyond = [r for r in every if r not in judged
              and r["angle"] < expected - r["lattice"]["lattice_tolerance_deg"]]
    worst = min(judged or every, key=lambda r: r["angle"])
    worst_angle = worst["angle"]
    if beyond:
        ok_angle = False
    elif judged:
        ok_angle = worst_angle >= lo
    else:
        ok_angle = None
    gaps = ", ".join(f"{r['lattice']['gap_deg']:.1f} deg ({r['name']})" for r in every)
    rep.add(f"Crests perpendicular to the wind (structure tensor): expected "
            f"{expected:g} +/- {tol_a:g} deg. {verdict(ok_angle)}: "
            + (f"worst {worst_angle:.1f} deg on " + ", ".join(r["name"] for r in judged)
               + f", whose torus resolves the law (crest gap at most {0.5 * tol_a:g} deg)"
               + ("" if worst_angle >= lo else f", {lo - worst_angle:.1f} deg outside")
               if judged else
               f"no bed's torus resolves the law: the admissible crests near the transverse one are "
               f"{gaps} apart, more than half the tolerance ({0.5 * tol_a:g} deg)")
            + "".join(f"; {r['name']}'s crests stand at {r['angle']:.1f} deg, beyond the "
                      f"{r['lattice']['lattice_tolerance_deg']:.1f} deg its torus can force" for r in beyond)
            + ".", "")
    tol = R["max_wavelength_change"]
    changes, oks = [], []
    for a, b in zip(res, res[1:]):
        change = abs(b["sp"]["wavelength_m"] - a["sp"]["wavelength_m"]) / a["sp"]["wavelength_m"]
        # Each measurement can sit half a lattice spacing from the pattern's own.
        slack = 0.5 * (a["spacing"] + b["spacing"])
        resolved = max(a["spacing"], b["spacing"]) <= 0.5 * tol
        ok = (change < tol) if resolved else (None if change < tol + slack else False)
        changes.append(change)
        oks.append(ok)
        rep.add(f"Wavelength at {b['cell']:g} m cells against {a['cell']:g} m: "
                f"{a['sp']['wavelength_m']:.1f} m -> {b['sp']['wavelength_m']:.1f} m, a change of "
                f"**{100 * change:.1f}%** (allowed < {100 * tol:g}%). {verdict(ok)}"
                + ("" if change < tol else f": {100 * (change - tol):.1f} points over")
                + ("" if resolved else
                   f"; the torus admits wavelengths {100 * a['spacing']:.0f}% and {100 * b['spacing']:.0f}% "
                   f"apart there, more than half the tolerance ({100 * 0.5 * tol:g}%): the lattice alone "
                   f"can change the measurement by up to {100 * slack:.0f}%")
                + ".", "")
    ok_wl = combine(oks)
    panels = res + cres
    fig, axes = plt.subplots(1, len(panels) + 1, figsize=(4 * (len(panels) + 1), 4))
    for ax, r in zip(axes[:-1], panels):
        ny_, nx_ = r["h"].shape
        im = ax.imshow(r["h"], origin="lower", extent=(0, nx_ * r["cell"], 0, ny_ * r["cell"]),
                       cmap="terrain", aspect="auto")
        ax.set_title(f"{r['cell']:g} m cells, step {r['step']}", fontsize=9)
        ax.set_xlabel("x (m), wind ->")
        ax.set_ylabel("y (m)")
        fig.colorbar(im, ax=ax, shrink=0.8, label="height (m)")
    for r in res:
        h = r["h"] - r["h"].mean()
        p = np.abs(np.fft.fft2(h)) ** 2
        ky = np.fft.fftfreq(h.shape[0], d=r["cell"])[:, None]
        kx = np.fft.fftfreq(h.shape[1], d=r["cell"])[None, :]
        k = np.sqrt(kx * kx + ky * ky)
        dk = 1.0 / (h.shape[1] * r["cell"])
        bins = np.arange(0.5 * dk, 0.1, dk)
        idx = np.digitize(k.ravel(), bins)
        radial = np.bincount(idx, weights=p.ravel(), minlength=len(bins) + 1)[1:len(bins)]
        centres = 0.5 * (bins[:-1] + bins[1:])
        axes[-1].semilogy(1.0 / centres, radial / radial.max(), label=f"{r['cell']:g} m cells")
        axes[-1].axvline(r["sp"]["wavelength_m"], ls="--", color=axes[-1].lines[-1].get_color())
    axes[-1].set_xscale("log")
    axes[-1].set_xlabel("wavelength (m)")
    axes[-1].set_ylabel("radial power (normalised)")
    axes[-1].legend()
    axes[-1].set_title("Spectra (dashed: measured wavelength)")
    rep.plot(fig, "transverse.png", "transverse", dpi=90)
    rep.add(f"Source: {R['source']}.", "")
    gap = max(r["lattice"]["gap_deg"] for r in (judged or every))
    rep.law("Transverse crests perpendicular", ok_angle, f"worst crest-wind angle {worst_angle:.1f} deg"
            + (f" on {', '.join(r['name'] for r in judged)}" if cres else "")
            + f"; lattice gap near it {gap:.1f} deg (resolves {tol_a:g} deg at <= {0.5 * tol_a:g})")
    rep.law("Transverse wavelength resolution-independent", ok_wl,
            ("change " + ", ".join(f"{100 * ch:.1f}%" for ch in changes) + " per halving"
             if changes else "one cell size, no halving")
            + " (" + " -> ".join(f"{r['cell']:g}" for r in res) + " m; allowed < "
            + f"{100 * tol:g}%); lattice spacing " + ", ".join(f"{100 * r['spacing']:.0f}%" for r in res)
            + f" (resolves at <= {100 * 0.5 * tol:g}%)")


def isotropy_law(rep, T, scenes):
    """scenes: (name, snapshots, job): one pile, the same wind at angles to the grid."""
    import math
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    I = T["isotropy"]
    det = T["detection"]
    rep.add("## 9. Isotropy: a pile's migration at any angle to the grid", "")
    modes = {}
    for _, _, j in scenes:
        modes.setdefault(transport_of(j), j)
    rep.add("The same sand pile on a non-erodible flat bed under the same wind, blowing at "
            + ", ".join(sorted({f"{wind_of(j):g}" for _, _, j in scenes}, key=float))
            + " deg to the grid's x axis, in each transport mode ("
            + "; ".join(f"{m}: a wind {wind_text(j)}, slabs of {slab_m(j):g} m"
                        for m, j in sorted(modes.items())) + "). The pile "
            f"(all sand thicker than {det['dune_sand_threshold_m']} m: the pile, or the barchans it "
            "calves) is tracked by its sand-weighted centroid, unwrapped on the torus, over the last "
            f"{100 * (1 - I['fit_from_fraction']):.0f}% of the run (after it has reshaped); its "
            "migration direction is that of the displacement, compared with the wind's; the pile is "
            f"lost when fewer than {det['dune_min_cells']} cells stay that thick. The model's equations have no preferred direction, so neither may its "
            "dunes: any difference is the grid's.", "")
    rep.add("| scene | transport | wind (deg) | displacement (m) | migration direction (deg) "
            "| direction - wind (deg) | speed (m/step) | pile volume, first -> last (m^3) |",
            "|---|---|---|---|---|---|---|---|")
    rows = []
    thick = det["dune_sand_threshold_m"]
    for name, snaps, job in scenes:
        wind = wind_of(job)
        cell = snaps[0]["cell_size_m"]
        ny, nx = snaps[0]["sand"].shape
        lx, ly = nx * cell, ny * cell
        first = min(int(len(snaps) * I["fit_from_fraction"]), len(snaps) - 2)
        window = snaps[first:]
        # The centroid of all sand thicker than the dune threshold (the pile,
        # or the barchans it calves), unwrapped from snapshot to snapshot.
        xs, ys, vols = [], [], []
        for snap in window:
            sand = snap["sand"]
            iy, ix = np.nonzero(sand > thick)
            if len(ix) < det["dune_min_cells"]:
                xs = []
                break
            w = sand[iy, ix]
            cx = M.circular_mean(ix, w, nx) * cell
            cy = M.circular_mean(iy, w, ny) * cell
            if xs:
                cx = xs[-1] + M.wrap_delta(cx - xs[-1] % lx, lx)
                cy = ys[-1] + M.wrap_delta(cy - ys[-1] % ly, ly)
            xs.append(cx)
            ys.append(cy)
            vols.append(float(w.sum()) * cell * cell)
        last = window[-1]["sand"]
        v_last = float(last[last > thick].sum()) * cell * cell
        v_first = float(window[0]["sand"][window[0]["sand"] > thick].sum()) * cell * cell
        row = {"name": name, "mode": transport_of(job), "wind": wind,
               "dist": float("nan"), "dir": float("nan"), "err": float("nan"),
               "speed": float("nan"), "x": xs, "y": ys, "v0": v_first, "v1": v_last}
        if xs:
            dx, dy = xs[-1] - xs[0], ys[-1] - ys[0]
            direction = math.degrees(math.atan2(dy, dx)) % 360.0
            row.update(dist=math.hypot(dx, dy), dir=direction,
                       err=M.wrap_delta(direction - wind, 360.0),
                       speed=M.migration_speed((xs, ys), [s["step"] for s in window], wind))
        rows.append(row)
    for r in rows:
        rep.add(f"| {r['name']} | {r['mode']} | {r['wind']:g} | {r['dist']:.1f} | {r['dir']:.1f} | "
                f"{r['err']:+.2f} | {r['speed']:.4f} | {r['v0']:.0f} -> {r['v1']:.0f} |")
    rep.add("")
    tol = I["max_direction_error_deg"]
    laws = []
    for mode in sorted({r["mode"] for r in rows}):
        rs = [r for r in rows if r["mode"] == mode]
        measured = [r for r in rs if r["dist"] == r["dist"] and r["dist"] > 0]
        worst = max((abs(r["err"]) for r in measured), default=float("nan"))
        ok = len(measured) == len(rs) and worst <= tol
        speeds = [r["speed"] for r in measured]
        spread = (max(speeds) - min(speeds)) / float(np.mean(speeds)) if speeds else float("nan")
        rep.add(f"{mode}: migration direction within {tol:g} deg of the wind's at every angle, the pile "
                "kept at every angle. "
                f"{verdict(ok)}: worst {worst:.2f} deg"
                + (f", {worst - tol:.2f} deg outside" if worst > tol else "")
                + (" (the pile was lost at " + ", ".join(f"{r['wind']:g}" for r in rs if r not in measured)
                   + " deg: its sand spread into a sheet thinner than the dune threshold)"
                   if len(measured) < len(rs) else "")
                + f". Speeds along the wind {min(speeds, default=float('nan')):.4f}-"
                f"{max(speeds, default=float('nan')):.4f} m/step (spread {100 * spread:.1f}% of the mean; "
                "reported, not judged).", "")
        laws.append((mode, ok, worst))
    fig, ax = plt.subplots(figsize=(5, 4))
    for r in rows:
        if not r["x"]:
            continue
        a = math.radians(r["wind"])
        x = np.asarray(r["x"]) - r["x"][0]
        y = np.asarray(r["y"]) - r["y"][0]
        along = x * math.cos(a) + y * math.sin(a)
        across = -x * math.sin(a) + y * math.cos(a)
        ax.plot(along, across, "o-", ms=3, label=f"{r['wind']:g} deg, {r['mode'].lower()}")
    ax.axhline(0, color="k", lw=0.5)
    ax.set_xlabel("along the wind (m)")
    ax.set_ylabel("across the wind (m, left positive)")
    ax.set_title("Pile centroid in the wind's frame")
    ax.legend(fontsize=7)
    rep.plot(fig, "isotropy.png", "isotropy", dpi=90)
    rep.add(f"Source: {I['source']}.", "")
    for mode, ok, worst in laws:
        lost = [f"{r['wind']:g}" for r in rows if r["mode"] == mode and not r["dist"] == r["dist"]]
        rep.law(f"Isotropy: pile migrates with the wind ({mode})", ok,
                f"worst direction error {worst:.2f} deg over " + ", ".join(
                    f"{r['wind']:g}" for r in rows if r["mode"] == mode) + " deg"
                + (f"; pile lost at {', '.join(lost)} deg" if lost else ""))


def relief(snap):
    """The height's range over the torus (m)."""
    h = snap["sand"] + snap["bedrock"]
    return float(h.max() - h.min())


def height_panel(ax, height, cell, axes_deg, title, centre=None):
    """One heightfield in metres on both axes at one scale (so that drawn
    angles are true), with lines through `centre` (default: the middle) at
    each (angle in degrees, matplotlib style) of `axes_deg`; nan angles are
    left out."""
    ly, lx = (k * cell for k in height.shape)
    ax.imshow(height, origin="lower", extent=(0, lx, 0, ly), cmap="terrain", aspect="equal")
    cx, cy = centre if centre else (lx / 2, ly / 2)
    for a, style in axes_deg:
        if a != a:
            continue
        u = 0.4 * min(lx, ly) * np.array([math.cos(math.radians(a)), math.sin(math.radians(a))])
        ax.plot([cx - u[0], cx + u[0]], [cy - u[1], cy + u[1]], style, lw=1)
    ax.set_xlim(0, lx)
    ax.set_ylim(0, ly)
    ax.set_title(title, fontsize=7)
    ax.set_xticks([])
    ax.set_yticks([])


def bed_isotropy_law(rep, T, scenes):
    """scenes: (name, snapshots, job): one bed of sand under one wind at
    angles to the grid, in each transport mode: the crests relative to the
    wind and the wavelength must not depend on the angle."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    I = T["isotropy"]
    O = T["orientation"]
    tol, wtol = I["max_crest_difference_deg"], I["max_wavelength_difference"]
    rep.add("## 11. Isotropy of a bed: transverse crests at any angle to the grid", "")
    rep.add("The same bed under the same wind, blowing at "
            + ", ".join(sorted({f"{wind_of(j):g}" for _, _, j in scenes}, key=float))
            + " deg to the grid's x axis, in each transport mode: "
            + "; ".join(sorted({f"{transport_of(j)}: " + describe_layers(j) for _, _, j in scenes}))
            + ". Measured on the last snapshot as in section 10: the crest orientation from the structure "
            "tensor of the height over the spectrum's dominant band, the wavelength as the band's mean. "
            "Each angle is compared with the same mode's scene at 0 deg: the crests relative to the wind "
            f"within {tol:g} deg and the wavelength within {100 * wtol:g}%. A pattern must have formed (the "
            f"relief grew, coherence at least {O['min_coherence']:g}) on a bed that kept sand everywhere. "
            "The torus admits only some crests and wavelengths (docs/dune-forms.md, \"What a periodic "
            "domain can resolve\"): a pair is judged where the admissible crests near each scene's are at "
            f"most {0.5 * tol:g} deg apart and the admissible wavelengths (the modes across the shorter "
            f"side) at most {50 * wtol:g}% apart; elsewhere it is UNRESOLVED, unless the difference exceeds "
            "the tolerance plus half of both scenes' gaps, which the lattice alone cannot make.", "")
    rep.add("| scene | transport | wind (deg) | crest (deg) | crest - wind (deg) | coherence | wavelength (m) "
            "| relief, first -> last (m) | lattice: crest gap (deg), wavelength spacing | against 0 deg: "
            "crest, wavelength | verdict |", "|---|---|---|---|---|---|---|---|---|---|---|")
    rows = []
    for name, snaps, job in scenes:
        first, last = snaps[0], snaps[-1]
        cell = last["cell_size_m"]
        h = last["sand"] + last["bedrock"]
        ny, nx = h.shape
        wind = wind_of(job)
        co = M.crest_orientation(h, cell)
        lat = M.orientation_resolution(co["wavelength_m"], nx * cell, ny * cell, (wind + 90.0) % 180.0, tol)
        rows.append({"name": job["name"], "mode": transport_of(job), "wind": wind, "h": h, "cell": cell,
                     "crest": co["tensor_deg"], "rel": (co["tensor_deg"] - wind) % 180.0,
                     "coherence": co["coherence"], "wavelength": co["wavelength_m"],
                     "relief": (relief(first), relief(last)),
                     "formed": relief(last) > relief(first) and co["coherence"] >= O["min_coherence"],
                     "bare": max(M.bare_fraction(s["sand"]) for s in snaps),
                     "gap": lat["gap_deg"],
                     "spacing": M.wavelength_resolution(co["wavelength_m"], min(nx, ny) * cell)})
    laws = []
    for mode in sorted({r["mode"] for r in rows}):
        rs = sorted((r for r in rows if r["mode"] == mode), key=lambda r: r["wind"])
        ref = rs[0]
        for r in rs:
            r["d_crest"] = M.axis_difference(r["rel"], ref["rel"])
            r["d_wl"] = abs(r["wavelength"] / ref["wavelength"] - 1.0)
            if not (r["formed"] and ref["formed"]) or r["bare"] > 0.0 or ref["bare"] > 0.0:
                r["ok"] = False
            elif max(r["gap"], ref["gap"]) <= 0.5 * tol and max(r["spacing"], ref["spacing"]) <= 0.5 * wtol:
                r["ok"] = bool(r["d_crest"] <= tol and r["d_wl"] <= wtol)
            elif (r["d_crest"] > tol + 0.5 * (r["gap"] + ref["gap"])
                  or r["d_wl"] > wtol + 0.5 * (r["spacing"] + ref["spacing"])):
                r["ok"] = False  # more than the lattice can move a pattern that obeys
            else:
                r["ok"] = None
        judged = rs[1:]
        ok = combine(r["ok"] for r in judged) if judged else None
        worst_c = max((r["d_crest"] for r in judged), default=float("nan"))
        worst_w = max((r["d_wl"] for r in judged), default=float("nan"))
        laws.append((mode, ok, worst_c, worst_w, rs))
    for mode, ok, worst_c, worst_w, rs in laws:
        for r in rs:
            rep.add(f"| {r['name']} | {r['mode']} | {r['wind']:g} | {r['crest']:.1f} | {r['rel']:.1f} | "
                    f"{r['coherence']:.2f} | {r['wavelength']:.1f} | {r['relief'][0]:.1f} -> {r['relief'][1]:.1f}"
                    + ("" if r["formed"] else " (no pattern)")
                    + (f"; bare rock in up to {100 * r['bare']:.1f}%" if r["bare"] > 0 else "")
                    + f" | {r['gap']:.1f}, {100 * r['spacing']:.1f}% | "
                    + ("the reference" if r is rs[0] else f"{r['d_crest']:.1f} deg, {100 * r['d_wl']:.1f}%")
                    + f" | {'-' if r is rs[0] else word(r['ok'])} |")
    rep.add("")
    for mode, ok, worst_c, worst_w, rs in laws:
        rep.add(f"{mode}: {verdict(ok)}: crests relative to the wind within {worst_c:.1f} deg of the 0 deg "
                f"scene's (allowed {tol:g}), wavelengths within {100 * worst_w:.1f}% (allowed {100 * wtol:g}%)"
                + ("; the torus does not resolve the tolerances in " + ", ".join(
                    r["name"] for r in rs[1:] if r["ok"] is None) if any(r["ok"] is None for r in rs[1:]) else "")
                + ".", "")
    ncol = max(len(rs) for *_, rs in laws)
    fig, axes = plt.subplots(len(laws), ncol, figsize=(2.4 * ncol, 2.6 * len(laws)), squeeze=False)
    for row_axes, (mode, _, _, _, rs) in zip(axes, laws):
        for ax in row_axes[len(rs):]:
            ax.axis("off")
        for ax, r in zip(row_axes, rs):
            height_panel(ax, r["h"], r["cell"], (((r["wind"] + 90.0) % 180.0, "w--"), (r["crest"], "r-")),
                         f"{r['wind']:g} deg, {r['mode'][:3].lower()}")
            ly, lx = (k * r["cell"] for k in r["h"].shape)
            w = math.radians(r["wind"])
            ax.annotate("", xy=(0.15 * lx + 0.12 * lx * math.cos(w), 0.85 * ly + 0.12 * lx * math.sin(w)),
                        xytext=(0.15 * lx, 0.85 * ly), arrowprops={"arrowstyle": "->", "color": "k"})
    rep.plot(fig, "isotropy_beds.png", "beds under one wind at angles to the grid (arrow: the wind; "
             "dashed: across it; solid: the measured crests)", dpi=80)
    rep.add(f"Source: {I['bed_source']}.", "")
    for mode, ok, worst_c, worst_w, rs in laws:
        winds = ", ".join(f"{r['wind']:g}" for r in rs)
        unresolved = sum(r["ok"] is None for r in rs[1:])
        rep.law(f"Isotropy: transverse crests at any angle ({mode})", ok,
                f"crests within {worst_c:.1f} deg, wavelengths within {100 * worst_w:.1f}% of the 0 deg "
                f"scene's over {winds} deg"
                + (f"; {unresolved} on a torus too small to resolve it" if unresolved else ""))


def orientation_case(job):
    """The orientation scene's bidirectional wind: (primary, divergence, flux
    ratio, the winds for measure's predictions)."""
    b = job.get("wind", {}).get("bidirectional")
    if b is None:
        raise SystemExit(f"erg validate: scene {job.get('name')}: the orientation law needs a bidirectional wind")
    primary = float(b.get("direction_deg", 0.0))
    theta = float(b["angle_deg"])
    n = float(b.get("flux_ratio", 1.0))
    return primary, theta, n, M.two_winds(primary, theta, n)


def describe_layers(job):
    """The domain, the run and the initial sand, in words, for the report."""
    d = job["domain"]
    return (f"{d['nx']} x {d['ny']} cells of {d['cell_size_m']:g} m, {job['run']['steps']} steps, "
            f"{transport_of(job)} with slabs of {slab_m(job):g} m, {describe_units(job)}, "
            + describe_sand(job))


def describe_units(job):
    """The wind's units in words: physical (a shear velocity, the stress on)
    or the model's."""
    w = job.get("wind", {})
    speeds = sorted({r["speed_mps"] for r in w.values() if isinstance(r, dict) and "speed_mps" in r})
    speed = "/".join(f"{v:g}" for v in speeds)
    if not physical(job):
        return f"model units (winds of {speed} m/s)" if speed else "model units"
    what = ("u*" if w.get("speed_is", "").upper() == "SHEAR_VELOCITY"
            else f"wind at {w.get('height_m', 10):g} m")
    return f"physical units ({what} {speed} m/s)" if speed else "physical units"


def sand_source(job):
    """Where a fingering scene's sand comes from (x, y in metres): the centre
    of the disks that feed it, else of its first pile."""
    feeds = [e["sand"] for e in job.get("events", []) if "sand" in e]
    if feeds:
        return float(feeds[-1]["x_m"]), float(feeds[-1]["y_m"])
    p = job["layers"]["sand"]["piles"][0]
    return float(p["x_m"]), float(p["y_m"])


def describe_sand(job):
    """The initial sand and its sources, in words, for the report."""
    sand = job.get("layers", {}).get("sand", {})
    parts = []
    if "constant" in sand:
        u = sand.get("uniform", {})
        parts.append(f"a bed of {sand['constant']:g} m of sand"
                     + (f" plus {u.get('min', 0):g}-{u.get('max', 0):g} m of uniform random relief" if u else ""))
    for p in sand.get("piles", []):
        parts.append(f"a pile {p['height']:g} m high of {p['radius_m']:g} m radius at ({p['x_m']:g}, {p['y_m']:g}) m "
                     "on bare rock")
    feeds = [e for e in job.get("events", []) if "sand" in e]
    if feeds:
        b = feeds[0]["sand"]
        parts.append(f"fed by {len(feeds)} disks of {b['height']:g} m of sand ({b['radius_m']:g} m radius) at the "
                     f"pile from step {feeds[0]['step']} to {feeds[-1]['step']}")
    return ", ".join(parts)


def orientation_law(rep, T, scenes):
    """scenes: (scene file name, snapshots, job) of orientation_bed_* and
    orientation_finger_*: dunes under two alternating winds against the
    two modes of Courrech du Pont, Narteau & Gao 2014."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    O = T["orientation"]
    det = T["detection"]
    tol = O["tolerance_deg"]
    rep.add("## 10. Dune orientation under two winds", "")
    rep.add("Two winds of the same speed alternate (a bidirectional regime, every "
            f"{', '.join(sorted({str(j['wind']['bidirectional'].get('period_steps', 20)) for _, _, j in scenes}))} steps): "
            "the primary towards "
            + ", ".join(sorted({f"{orientation_case(j)[0]:g}" for _, _, j in scenes}, key=float))
            + " deg from the grid's x axis, the secondary at the divergence angle theta from it, blowing "
            "1 / N of the time so that the flux ratio is N. Courrech du Pont, Narteau & Gao (2014) "
            "predict two orientations, with the crest flux sped up by 1 + gamma |sin(wind - crest)|, "
            f"gamma = {M.SPEED_UP_GAMMA:g} (Gao et al. 2015): in the **bed-instability** mode (a flat "
            "bed of sand with small random relief) the crests align where the gross crest-normal "
            "transport is largest; in the **fingering** mode (a sand source on bare rock) the dune "
            "elongates along the resultant flux at its crest (the crest-normal fluxes cancel). "
            + "".join(sorted({f"Scene {j['name']}: {describe_layers(j)}. " for _, _, j in scenes}))
            + "Measured on the last snapshot: the crest orientation of the bed from the structure tensor "
            "of the height over the spectrum's dominant band, as in section 4 (the 2-D spectrum's "
            "strongest wavevector is listed too; on these domains its directions are harmonics "
            "several degrees apart), the elongation of a finger from the second moments of the "
            f"source's dune: the body of sand thicker than {det['dune_sand_threshold_m']:g} m that holds "
            "the feed's centre (else the body nearest to it), since the mode's dune is the one the source "
            "feeds and the seed pile, once blown off the source, leaves as a dome of its own. Listed too: the "
            "central lobe of the periodic autocorrelation of all the sand thicker than "
            f"{det['dune_sand_threshold_m']:g} m (lags above {O['autocorrelation_level']:g} of its peak), "
            "which mixes the finger with such domes, and the volume-weighted mean axis of the elongated "
            "bodies. An orientation is an "
            "axis (modulo 180 deg), in degrees counter-clockwise from x. The law holds when the measured "
            f"axis is within {tol:g} deg of the prediction and a pattern formed: the bed's relief grew "
            f"and its coherence reached {O['min_coherence']:g}, the source's dune is at least "
            f"{O['min_elongation']:g} times as long as wide. A bed's crests are a periodic pattern, so "
            "the torus admits only the crests across its lattice vectors (m / Lx, n / Ly) near the "
            "measured wavelength (docs/dune-forms.md, \"What a periodic domain can resolve\"); the "
            "lattice column gives the largest gap between them within the tolerance of the "
            f"prediction: a bed is judged where it is at most {0.5 * tol:g} deg, UNRESOLVED elsewhere "
            "unless its crests lie farther from the prediction than the lattice alone can move them. "
            "Fingers are single bodies, not bound to the lattice. The bed-instability mode is that of "
            "an erodible bed, sand everywhere (Courrech du Pont, Narteau & Gao 2014; Gao et al. 2015 "
            "map how the orientation moves towards the fingering mode as the sand runs out): a bed "
            "with bare rock in any snapshot is sand-limited, so it is no test of the mode and FAILs "
            "as a scene." + model_units_caveat([j for name, _, j in scenes if "_bed_" in name]), "")
    rep.add("| scene | transport | mode | theta (deg) | N | predicted (deg) | other mode's (deg) "
            "| measured (deg) | difference (deg) | pattern | also measured | lattice gap (deg) | verdict |",
            "|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    rows = []
    for name, snaps, job in scenes:
        primary, theta, n, winds = orientation_case(job)
        mode = "bed" if "_bed_" in name else "finger"
        bed_pred = M.bed_instability_orientation(winds)
        finger_pred = M.fingering_orientation(winds) % 180.0
        first, last = snaps[0], snaps[-1]
        cell = last["cell_size_m"]
        height = last["sand"] + last["bedrock"]
        if mode == "bed":
            pred, other = bed_pred, finger_pred
            centre = None
            co = M.crest_orientation(height, cell)
            measured = co["tensor_deg"]
            formed = relief(last) > relief(first) and co["coherence"] >= O["min_coherence"]
            pattern = (f"relief {relief(first):.1f} -> {relief(last):.1f} m, coherence "
                       f"{co['coherence']:.2f}, wavelength {co['wavelength_m']:.0f} m")
            also = f"spectrum {co['spectrum_deg']:.1f}"
            # The mode's premise: sand everywhere (an erodible bed). Bare
            # rock in any snapshot makes the bed sand-limited, between the
            # two modes, so it is no test of this one.
            bare = max(M.bare_fraction(s["sand"]) for s in snaps)
            if bare > 0.0:
                pattern += f"; bare rock in up to {100 * bare:.1f}% of the bed: sand ran out"
            ny, nx = height.shape
            lattice = M.orientation_resolution(co["wavelength_m"], nx * cell, ny * cell, pred, tol)
        else:
            pred, other = finger_pred, bed_pred
            bare = 0.0
            # The dunes: sand thicker than the detection threshold (the
            # saltating sheet between them has streaks of its own).
            thick = np.where(last["sand"] > det["dune_sand_threshold_m"], last["sand"], 0.0)
            lobe_axis, lobe = M.autocorrelation_axis(thick, cell, O["autocorrelation_level"])
            bodies = M.elongation_orientation(last["sand"], cell, det["dune_sand_threshold_m"],
                                              det["dune_min_cells"], O["min_elongation"])
            # The law's dune is the one the source feeds: the seed pile,
            # once blown off the source, is a dome of its own, not a finger.
            centre = sand_source(job)
            src = M.source_body(last["sand"], cell, det["dune_sand_threshold_m"], det["dune_min_cells"], centre)
            if src is None:
                measured, formed = float("nan"), False
                pattern = f"no dune: no body thicker than {det['dune_sand_threshold_m']:g} m"
            else:
                measured, formed = src["axis_deg"], src["aspect"] >= O["min_elongation"]
                where = ("at the source" if src["distance_m"] == 0.0 else
                         f"nearest, {src['distance_m']:.0f} m from the source")
                pattern = (f"the source's dune ({where}, {src['volume_m3']:.0f} m^3) "
                           f"{src['aspect']:.2f} times as long as wide")
            also = (f"all sand: lobe {lobe_axis:.1f} ({lobe:.2f} times as long as wide); "
                    + (f"elongated bodies {bodies['axis_deg']:.1f} ({bodies['measured']} of {bodies['bodies']})"
                       if bodies["measured"] else f"no body elongated ({bodies['bodies']} found)"))
            lattice = None
        diff = M.axis_difference(measured, pred)
        if not formed or bare > 0.0:
            ok = False
        elif lattice is None or lattice["gap_deg"] <= 0.5 * tol:
            ok = bool(diff <= tol)
        else:
            # Crests farther off than the lattice alone can move them fail.
            ok = None if diff <= lattice["lattice_tolerance_deg"] else False
        row = {"name": job["name"], "mode": mode, "transport": transport_of(job),
               "theta": theta, "n": n, "primary": primary, "pred": pred, "other": other, "measured": measured,
               "diff": diff, "formed": formed, "bare": bare, "ok": ok, "height": height, "cell": cell,
               "step": last["step"], "lattice": lattice,
               "centre": centre}
        rows.append(row)
        gap = ("-" if lattice is None else f"{lattice['gap_deg']:.1f} (nearest admissible "
               f"{lattice['nearest_deg']:.1f}; can move it {lattice['lattice_tolerance_deg']:.1f})")
        rep.add(f"| {job['name']} | {row['transport']} | {'bed instability' if mode == 'bed' else 'fingering'} "
                f"| {theta:g} | {n:g} | {pred:.1f} | {other:.1f} | {measured:.1f} | {diff:.1f} | "
                f"{pattern}{'' if formed else ' (no pattern)'} | {also} | {gap} | {word(ok)} |")
    rep.add("")
    for mode, title in (("bed", "bed instability"), ("finger", "fingering")):
        for transport in sorted({r["transport"] for r in rows if r["mode"] == mode}):
            rs = [r for r in rows if r["mode"] == mode and r["transport"] == transport]
            ok = combine(r["ok"] for r in rs)
            worst = max((r["diff"] for r in rs if r["diff"] == r["diff"]), default=float("nan"))
            unresolved = [r["name"] for r in rs if r["ok"] is None]
            rep.add(f"{title}, {transport}: {verdict(ok)}: differences "
                    + ", ".join(f"{r['diff']:.1f}" for r in rs) + f" deg (allowed {tol:g})"
                    + ("" if all(r["formed"] for r in rs) else
                       "; no pattern in " + ", ".join(r["name"] for r in rs if not r["formed"]))
                    + ("" if not any(r["bare"] > 0 for r in rs) else
                       "; the sand ran out (bare rock) in " + ", ".join(r["name"] for r in rs if r["bare"] > 0))
                    + ("" if not unresolved else
                       "; the torus does not resolve the tolerance in " + ", ".join(unresolved)) + ".", "")
            rep.law(f"Two-wind orientation, {title} ({transport})", ok,
                    f"worst {worst:.1f} deg from the prediction over {len(rs)} scenes (allowed {tol:g})"
                    + ("" if all(r["formed"] for r in rs) else
                       f"; {sum(not r['formed'] for r in rs)} without a pattern")
                    + ("" if not any(r["bare"] > 0 for r in rs) else
                       f"; {sum(r['bare'] > 0 for r in rs)} whose bed went bare")
                    + ("" if not unresolved else f"; {len(unresolved)} on a torus too small to resolve it"))
    # Orientation against divergence: predictions for the scenes' flux ratios, measured points.
    fig, axes = plt.subplots(1, 2, figsize=(9, 3.8))
    th = np.linspace(92.0, 180.0, 45)
    for ax, mode, title in ((axes[0], "bed", "bed instability: crest"),
                            (axes[1], "finger", "fingering: elongation")):
        rs = [r for r in rows if r["mode"] == mode]
        for n in sorted({r["n"] for r in rs}):
            f = M.bed_instability_orientation if mode == "bed" else (lambda w: M.fingering_orientation(w) % 180.0)
            line, = ax.plot(th, [f(M.two_winds(0.0, t, n)) for t in th], "-", lw=1, label=f"predicted, N = {n:g}")
            for r in rs:
                if r["n"] != n:
                    continue
                # Relative to the primary wind, on the prediction's side of the 180 deg wrap.
                m = (r["pred"] - r["primary"]) % 180.0 + M.wrap_delta(r["measured"] - r["pred"], 180.0)
                ax.plot(r["theta"], m, "o" if r["transport"] == "STOCHASTIC" else "s",
                        mfc="none" if not r["formed"] else line.get_color(), color=line.get_color())
        ax.plot([], [], "ko", label="stochastic")
        ax.plot([], [], "ks", label="expected (hollow: no pattern)")
        ax.set_xlabel("divergence angle theta (deg)")
        ax.set_ylabel("orientation from the primary wind (deg)")
        ax.set_title(title)
        ax.legend(fontsize=6)
    rep.plot(fig, "orientation.png", "orientation against divergence")
    # The last heightfields with the predicted (dashed) and measured (solid) axes.
    ncol = min(6, len(rows))
    nrow = (len(rows) + ncol - 1) // ncol
    fig, axes = plt.subplots(nrow, ncol, figsize=(2.2 * ncol, 2.5 * nrow), squeeze=False)
    for ax in axes.ravel()[len(rows):]:
        ax.axis("off")
    for ax, r in zip(axes.ravel(), rows):
        # A finger's axes through its source, a bed's through the middle.
        height_panel(ax, r["height"], r["cell"], ((r["pred"], "w--"), (r["measured"], "r-")),
                     f"{r['mode']} {r['theta']:g}/{r['n']:g} {r['transport'][:3].lower()}", r["centre"])
    rep.plot(fig, "orientation_fields.png", "orientation scenes, last step", dpi=80)
    rep.add(f"Source: {O['source']}.", "")


def mass_law(rep, T, runs):
    A = T["mass"]
    rep.add("## 5. Mass", "")
    rep.add("For every scene, the exact total of sand on the ground plus airborne sand "
            "(`sand_units_total + airborne_units_total`, integers of 2^-32 m) at every snapshot "
            "from step 0 to the end, against the snapshot before. Intervals holding a timeline "
            "event are listed apart (the fed sources of section 10 add sand by events; each keeps "
            "its first or last snapshot interval free of them, and that one is checked).",
            "")
    rep.add("| scene | snapshots | intervals checked | total at step 0 (units) | total at end (units) "
            "| largest drift (units) | event intervals |", "|---|---|---|---|---|---|---|")
    drifted, unchecked = [], []
    for name, snaps, job in runs:
        events = [int(e.get("step", 0)) for e in job.get("events", [])]
        checked, drifts, skipped = M.mass_balance(snaps, events)
        worst = max((abs(d) for d in drifts), default=0)
        if worst > A["allowed_drift_units"]:
            drifted.append(name)
        if checked == 0 or snaps[0]["step"] != 0:
            unchecked.append(name)
        rep.add(f"| {name} | {len(snaps)} | {checked} | {M.sand_total_units(snaps[0])} | "
                f"{M.sand_total_units(snaps[-1])} | {worst} | {len(skipped)} |")
    rep.add("")
    ok = not drifted and not unchecked
    why = "; ".join(([f"drift in {', '.join(drifted)}"] if drifted else [])
                    + ([f"not checked from step 0 without events in {', '.join(unchecked)}"]
                       if unchecked else []))
    rep.add(f"Expected drift: {A['allowed_drift_units']} units. {verdict(ok)}"
            + (f": {why}" if why else "") + ".", "")
    rep.add(f"Source: {A['source']}.", "")
    rep.law("Mass conserved exactly", ok, "exact" if ok else why)


def merge_by_transport(rep, subs):
    """subs: (job, Report) of the same sections measured on one scene per
    transport mode. Each section gets its heading once and each scene's part
    under its mode; each law is named with its mode."""
    order, parts = [], {}
    for job, sub in subs:
        head = None
        for line in sub.lines:
            if line.startswith("## "):
                head = line
                if head not in parts:
                    order.append(head)
                    parts[head] = []
                parts[head].append((job, []))
            elif head is not None:
                parts[head][-1][1].append(line)
        for name, ok, measured in sub.summary:
            rep.law(f"{name} ({transport_of(job)})", ok, measured)
    for head in order:
        rep.add(head, "")
        for job, lines in parts[head]:
            if len(subs) > 1:
                rep.add(f"**{transport_of(job)} transport** (scene `{job['name']}`):", "")
            while lines and not lines[0]:
                lines = lines[1:]
            rep.add(*lines)


def law_scenes(names, jobs):
    """Each law measured on runs, with its section and the scenes (file
    names) it needs: a law is judged only on all of them. The flux and
    drift laws need no run (erg calibrate), and mass is a law of each scene
    on its own, judged over the scenes that ran."""
    cells, wide = transverse_beds(names)
    trans = cells + wide
    barchans = [n for n in names if n.startswith("barchans")]
    laws = {
        "Slip faces at repose": ("3. Slip faces", barchans + trans),
        # Judged on the wide bed where the suite has one, else on the strips.
        "Transverse crests perpendicular": ("4. Transverse dunes", wide or cells),
        "Transverse wavelength resolution-independent": ("4. Transverse dunes", cells),
    }
    for n in names:
        transport = transport_of(jobs[n])
        if n.startswith("barchans"):
            for law, section in (("Barchan speed c = a Q / (H + H0)", "1. Barchan migration speed against height"),
                                 ("Barchan H/W ~ 0.1, horns downwind", "2. Barchan shape"),
                                 ("Migration rate against Tarfaya", "6. Migration rate in physical units")):
                laws[f"{law} ({transport})"] = (section, [n])
            continue
        if n.startswith("isotropy_bed"):
            law = (f"Isotropy: transverse crests at any angle ({transport})",
                   "11. Isotropy of a bed: transverse crests at any angle to the grid")
        elif n.startswith("isotropy"):
            law = (f"Isotropy: pile migrates with the wind ({transport})",
                   "9. Isotropy: a pile's migration at any angle to the grid")
        elif n.startswith("orientation_"):
            title = "bed instability" if n.startswith("orientation_bed") else "fingering"
            law = (f"Two-wind orientation, {title} ({transport})", "10. Dune orientation under two winds")
        else:
            continue
        laws.setdefault(law[0], (law[1], []))[1].append(n)
    return laws


def mark_not_run(rep, laws, skipped, jobs):
    """Every law with a skipped scene reads NOT RUN, whatever the scenes that
    ran measured (listed after it): a law is stated over all its scenes. A
    law none of whose scenes ran gets its section with the reason."""
    present = {name for name, _, _ in rep.summary}
    noted = {}

    def note(section, text):
        """At the top of the section (made if no law of it ran), above the
        verdicts of the scenes that ran and after the notes before it."""
        if f"## {section}" not in rep.lines:
            rep.add(f"## {section}", "")
        at = rep.lines.index(f"## {section}") + 2 + 2 * noted.get(section, 0)
        noted[section] = noted.get(section, 0) + 1
        rep.lines[at:at] = [text, ""]

    for law, (section, scenes) in laws.items():
        missing = [jobs[n]["name"] for n in scenes if n in skipped]
        if not missing:
            continue
        why = "not run: " + ", ".join(missing)
        said = (f"{law}: {verdict(NOT_RUN)}: its scenes {', '.join(missing)} were left out of this "
                "invocation (`--skip`)")
        if law in present:
            i = [name for name, _, _ in rep.summary].index(law)
            rep.summary[i] = (law, NOT_RUN, f"{rep.summary[i][2]}; {why}")
            note(section, f"{said}; the verdicts below are of the scenes that ran.")
        else:
            # In the summary next to the laws of its section, if any was measured.
            kin = [i for i, (name, _, _) in enumerate(rep.summary) if laws.get(name, ("",))[0] == section]
            rep.summary.insert(kin[-1] + 1 if kin else len(rep.summary), (law, NOT_RUN, why))
            note(section, f"{said}.")


def main():
    ap = argparse.ArgumentParser(prog="erg validate")
    ap.add_argument("--out", required=True)
    ap.add_argument("--quick", action="store_true", help="the small scenes (2-3 minutes)")
    ap.add_argument("--worker", default="erg-worker")
    ap.add_argument("--erg", default="erg", help="the erg binary (erg calibrate)")
    ap.add_argument("--threads", type=int, default=0)
    ap.add_argument("--reuse", action="store_true", help="reuse the runs already in OUT/runs: complete ones as they are, "
                    "interrupted ones resumed from their newest checkpoint")
    ap.add_argument("--scenes", default=None, help="folder of scene jobs (default: scenes/full or scenes/quick)")
    ap.add_argument("--skip", action="append", default=[], metavar="GLOB",
                    help="leave out the scenes whose file name (without .json) matches GLOB; "
                         "the laws that need them read NOT RUN")
    a = ap.parse_args()
    global ERG
    ERG = a.erg
    out = Path(a.out)
    suite = "quick" if a.quick else "full"
    scene_dir = Path(a.scenes) if a.scenes else HERE / "scenes" / suite
    T = json.loads((HERE / "thresholds.json").read_text())
    (out / "runs").mkdir(parents=True, exist_ok=True)
    t_start = time.time()
    jobs, dirs, timings = {}, {}, {}
    names = list(SCENES) + [n for n in OPTIONAL + ISOTROPY if (scene_dir / f"{n}.json").exists()]
    names += sorted(p.stem for p in scene_dir.glob("orientation_*.json"))
    names += sorted(p.stem for p in scene_dir.glob("isotropy_bed_*.json"))
    for name in names:
        jp = scene_dir / f"{name}.json"
        jobs[name] = json.loads(jp.read_text())
        _SCENE_PATHS[jobs[name]["name"]] = jp
        dirs[name] = out / "runs" / jobs[name]["name"]
    skipped = sorted(n for n in names if any(fnmatch.fnmatchcase(n, g) for g in a.skip))
    for g in a.skip:
        if not any(fnmatch.fnmatchcase(n, g) for n in names):
            raise SystemExit(f"erg validate: --skip {g} matches no scene of {scene_dir} "
                             f"(scenes: {', '.join(sorted(names))})")
    ran = [n for n in names if n not in skipped]
    for i, name in enumerate(sorted(ran, key=lambda n: scene_cost(jobs[n])), start=1):
        timings[name] = run_scene(a.worker, scene_dir / f"{name}.json", dirs[name], a.threads,
                                  a.reuse, i, len(ran))
    log("measuring")
    rep = Report(out)
    # The barchan scenes, one per transport mode the suite has: sections 1, 2
    # and 6 measure each, and their laws are named with the mode.
    bnames = [n for n in ran if n.startswith("barchans")]
    bsnaps, repose, subs = {}, {}, []
    for n in bnames:
        sub = Report(out, plot_suffix=n[len("barchans"):])
        rows, bsnaps[n], repose[n] = barchan_laws(sub, T, dirs[n], jobs[n])
        migration_law(sub, T, rows, jobs[n])
        subs.append((jobs[n], sub))
    merge_by_transport(rep, subs)
    tnames = [n for n in ran if n.startswith("transverse")]
    ts = {n: snapshots(dirs[n]) for n in tnames}
    if bnames:
        # The lee histogram on the first barchan scene (the STOCHASTIC one where
        # the suite has it); the steepest slope on every scene's last snapshot.
        finals = ([(jobs[n]["name"], bsnaps[n][-1]) for n in bnames] +
                  [(jobs[n]["name"], ts[n][-1]) for n in ts])
        slip_face_law(rep, T, bsnaps[bnames[0]], finals, repose[bnames[0]], jobs[bnames[0]])
    if tnames:
        strips, wide = transverse_beds(tnames)
        transverse_law(rep, T, [(jobs[n]["name"], ts[n][-1], jobs[n]) for n in strips],
                       [(jobs[n]["name"], ts[n][-1], jobs[n]) for n in wide])
    inames = [n for n in ran if n.startswith("isotropy") and not n.startswith("isotropy_bed")]
    isnaps = {n: snapshots(dirs[n]) for n in inames}
    if inames:
        isotropy_law(rep, T, [(jobs[n]["name"], isnaps[n], jobs[n]) for n in inames])
    ibnames = [n for n in ran if n.startswith("isotropy_bed")]
    ibsnaps = {n: snapshots(dirs[n]) for n in ibnames}
    if ibnames:
        bed_isotropy_law(rep, T, [(jobs[n]["name"], ibsnaps[n], jobs[n]) for n in ibnames])
    onames = [n for n in ran if n.startswith("orientation_")]
    osnaps = {n: snapshots(dirs[n]) for n in onames}
    if onames:
        orientation_law(rep, T, [(n, osnaps[n], jobs[n]) for n in onames])
    mass_law(rep, T, [(jobs[n]["name"], bsnaps[n], jobs[n]) for n in bnames] +
             [(jobs[n]["name"], ts[n], jobs[n]) for n in ts] +
             [(jobs[n]["name"], isnaps[n], jobs[n]) for n in inames] +
             [(jobs[n]["name"], ibsnaps[n], jobs[n]) for n in ibnames] +
             [(jobs[n]["name"], osnaps[n], jobs[n]) for n in onames])
    bjob = jobs["barchans"]
    flux_law(rep, T, calibrate(scene_dir / "barchans.json", None, 1) if physical(bjob) else None, bjob)
    rose = scene_dir / "drift_rose.json"
    rjob = json.loads(rose.read_text()) if rose.exists() else None
    drift_law(rep, T, calibrate(rose, None, int(rjob["run"]["steps"])) if rjob else None,
              rjob["name"] if rjob else "")

    mark_not_run(rep, law_scenes(names, jobs), skipped, jobs)
    # Sections in the order of the report; the body was written in measurement order.
    body = "\n".join(rep.lines)
    parts = ["## " + p for p in body.split("## ") if p.strip()]
    body = "\n".join(sorted(parts, key=lambda p: int(p[3:p.index(".")])))
    passed = sum(1 for _, ok, _ in rep.summary if ok is True)
    unresolved = sum(1 for _, ok, _ in rep.summary if ok is None)
    not_run = sum(1 for _, ok, _ in rep.summary if ok is NOT_RUN)
    meta = [
        f"# erg validation report ({suite} suite)", "",
        f"Generated by `erg validate{' --quick' if a.quick else ''}` "
        f"({time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; scenes in "
        f"`client/validate/scenes/{suite}/`, thresholds and their sources in "
        f"`client/validate/thresholds.json`, measurements in `client/validate/measure.py`). "
        "Simulation wall time on this machine: "
        + ", ".join(f"{jobs[n]['name']} " + (f"{timings[n]:.0f} s" if timings[n] is not None else "?")
                    for n in ran)
        + (f" ({sum(timings.values()):.0f} s in all)" if None not in timings.values() else "")
        + (" (runs reused from an earlier invocation)" if a.reuse else "") + ".", "",
        f"**{passed} of {len(rep.summary)} laws pass.**"
        + (f" {unresolved} cannot be judged on their scenes' tori (UNRESOLVED)." if unresolved else "")
        + (f" {not_run} NOT RUN: their scenes were left out of this invocation (--skip: "
           + ", ".join(jobs[n]["name"] for n in skipped) + ")." if not_run else ""), "",
        "| law | result | measured |", "|---|---|---|",
    ]
    for name, ok, measured in rep.summary:
        meta.append(f"| {name} | {word(ok)} | {measured} |")
    meta.append("")
    text = "\n".join(meta) + "\n" + body + "\n"
    tmp = out / "report.md.tmp"
    tmp.write_text(text)
    os.replace(tmp, out / "report.md")
    log(f"{passed} of {len(rep.summary)} laws pass"
        + (f" ({not_run} not run)" if not_run else "") + f"; report in {out / 'report.md'} "
        f"({time.time() - t_start:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())

# SPDX-License-Identifier: Apache-2.0
"""Measurements of geomorphological laws on erg heightfields.

Every function works on plain numpy arrays laid out as erg's snapshots are
([ny][nx], row 0 = y = 0, periodic in x and y) so that tests/validate proves
each one on synthetic fields with known answers before validate.py applies it
to simulated dunes. Lengths are metres, angles degrees; a wind direction is
where the wind blows towards, counter-clockwise from +x (README, job format).
"""
import math

import numpy as np


# --- snapshots ---------------------------------------------------------------

def layer(f, name):
    """A snapshot layer as [ny][nx] float64: stored (time, y, x) with one time
    (netCDF-4 / CF), or [ny][nx] by erg before that layout."""
    d = f[name]
    return (d[0] if d.ndim == 3 else d[...]).astype(np.float64)


def load_snapshot(path):
    """The fields and exact totals of one snapshot (README: Outputs)."""
    import h5py
    with h5py.File(path, "r") as f:
        a = f.attrs

        def attr(name):
            v = a[name]
            return v.decode() if isinstance(v, bytes) else v

        return {
            "path": str(path),
            "step": int(attr("step")),
            "time_days": float(attr("time_days")),
            # Julian years (the snapshot's own, else from time_days).
            "time_years": float(attr("time_years")) if "time_years" in a
            else float(attr("time_days")) / 365.25,
            "time_step_s": float(attr("time_step_s")) if "time_step_s" in a else None,
            "cell_size_m": float(attr("cell_size_m")),
            "sand": layer(f, "sand"),
            "bedrock": layer(f, "bedrock"),
            # Exact integers: Python ints from the decimal strings.
            "sand_units_total": int(str(attr("sand_units_total"))),
            "airborne_units_total": int(str(attr("airborne_units_total"))),
            "job_spec": str(attr("job_spec")),
        }


# --- connected components on the torus ---------------------------------------

def label_periodic(mask):
    """8-connected components of `mask` on the torus: (labels, count).

    scipy labels the plane; components cut by the seams are then merged with a
    union-find over the pairs of labels facing each other across x = 0 / nx
    and y = 0 / ny (diagonal neighbours across the seam included)."""
    from scipy import ndimage
    labels, n = ndimage.label(mask, structure=np.ones((3, 3), dtype=int))
    parent = list(range(n + 1))

    def find(a):
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    def union_edges(a, b):
        # a, b: facing 1-D label rows; 8-connectivity joins offsets -1, 0, +1.
        for shift in (-1, 0, 1):
            bb = np.roll(b, shift)
            both = (a > 0) & (bb > 0)
            for x, y in set(zip(a[both].tolist(), bb[both].tolist())):
                rx, ry = find(x), find(y)
                if rx != ry:
                    parent[max(rx, ry)] = min(rx, ry)

    union_edges(labels[:, 0], labels[:, -1])
    union_edges(labels[0, :], labels[-1, :])
    roots = np.array([find(i) for i in range(n + 1)])
    uniq = np.unique(roots[1:]) if n else np.array([], dtype=int)
    remap = np.zeros(n + 1, dtype=int)
    for new, r in enumerate(uniq, start=1):
        remap[roots == r] = new
    remap[0] = 0
    return remap[labels], len(uniq)


def circular_mean(coord, weights, period):
    """Weighted mean position of points on a circle of length `period`
    (cells): the angle of the weighted sum of unit vectors, so a pile cut by
    the seam has its centroid where it is, not in the middle of the domain."""
    theta = 2.0 * math.pi * np.asarray(coord, dtype=np.float64) / period
    s = np.sum(weights * np.sin(theta))
    c = np.sum(weights * np.cos(theta))
    return (math.atan2(s, c) / (2.0 * math.pi) * period) % period


def wrap_delta(d, period):
    """The shortest signed displacement equivalent to d on a circle."""
    return (d + 0.5 * period) % period - 0.5 * period


def dunes(sand, cell_size_m, threshold_m, min_cells):
    """The sand bodies thicker than `threshold_m`, largest first: centroid
    (x, y in metres, periodic, sand-weighted), peak height, volume, cell
    count and the label mask."""
    ny, nx = sand.shape
    labels, n = label_periodic(sand > threshold_m)
    out = []
    for k in range(1, n + 1):
        iy, ix = np.nonzero(labels == k)
        if len(ix) < min_cells:
            continue
        w = sand[iy, ix]
        out.append({
            "x_m": circular_mean(ix, w, nx) * cell_size_m,
            "y_m": circular_mean(iy, w, ny) * cell_size_m,
            "height_m": float(w.max()),
            "volume_m3": float(w.sum()) * cell_size_m ** 2,
            "cells": int(len(ix)),
            "ix": ix, "iy": iy,
        })
    out.sort(key=lambda d: -d["volume_m3"])
    return out


def track(frames, domain_m, max_jump_m):
    """Follows dunes through successive frames (lists from dunes()), matching
    each to the nearest centroid of the next frame on the torus; returns one
    track per dune of the first frame that survives every frame: unwrapped
    x, y (metres) and heights per frame."""
    lx, ly = domain_m
    tracks = [{"x": [d["x_m"]], "y": [d["y_m"]], "h": [d["height_m"]],
               "v": [d["volume_m3"]], "w": [d.get("width_m", float("nan"))], "alive": True}
              for d in frames[0]]
    for frame in frames[1:]:
        taken = set()
        for t in tracks:
            if not t["alive"]:
                continue
            px, py = t["x"][-1] % lx, t["y"][-1] % ly
            best, best_d = None, max_jump_m
            for i, d in enumerate(frame):
                if i in taken:
                    continue
                dx = wrap_delta(d["x_m"] - px, lx)
                dy = wrap_delta(d["y_m"] - py, ly)
                dist = math.hypot(dx, dy)
                if dist < best_d:
                    best, best_d = i, dist
            if best is None:
                t["alive"] = False
                continue
            taken.add(best)
            d = frame[best]
            t["x"].append(t["x"][-1] + wrap_delta(d["x_m"] - px, lx))
            t["y"].append(t["y"][-1] + wrap_delta(d["y_m"] - py, ly))
            t["h"].append(d["height_m"])
            t["v"].append(d["volume_m3"])
            t["w"].append(d.get("width_m", float("nan")))
    return [t for t in tracks if t["alive"]]


def along_wind(x, y, wind_deg):
    a = math.radians(wind_deg)
    return np.asarray(x) * math.cos(a) + np.asarray(y) * math.sin(a)


def migration_speed(track_xy, times, wind_deg):
    """Speed along the wind (metres per unit of `times`): least-squares slope
    of the unwrapped along-wind position against time."""
    s = along_wind(track_xy[0], track_xy[1], wind_deg)
    return float(np.polyfit(np.asarray(times, dtype=np.float64), s, 1)[0])


def loglog_fit(x, y):
    """Slope and intercept of log(y) = slope log(x) + b, and the residual
    standard deviation in log units."""
    lx, ly = np.log(np.asarray(x, float)), np.log(np.asarray(y, float))
    slope, b = np.polyfit(lx, ly, 1)
    resid = ly - (slope * lx + b)
    return float(slope), float(b), float(np.sqrt(np.mean(resid ** 2)))


# --- barchan shape ------------------------------------------------------------

def cutoff_fit(h, c):
    """Least-squares fit of c = A / (H + H0) (A = a Q, the cut-off form of
    Andreotti et al. 2002 and Hersen et al. 2002) over H0 >= 0: 1 / c is
    linear in H, 1/c = H / A + H0 / A. Returns (A, H0)."""
    h = np.asarray(h, dtype=np.float64)
    inv = 1.0 / np.asarray(c, dtype=np.float64)
    slope, icept = np.polyfit(h, inv, 1)
    if slope <= 0:
        return float("nan"), float("nan")
    a = 1.0 / slope
    h0 = icept * a
    if h0 < 0:  # constrained: H0 = 0, A = mean of c H
        return float(np.mean(np.asarray(c) * h)), 0.0
    return float(a), float(h0)


def barchan_shape(dune, sand, cell_size_m, wind_deg):
    """Height over horn-to-horn width, and whether the horns point downwind.

    Positions are taken relative to the dune's centroid (wrapped, so a dune
    across the seam is measured whole) and rotated into (along, across) the
    wind. The width is the across-wind extent of the body; the horn tips are
    the cells within 10% of the width from either lateral edge; the horns
    point downwind when the tips' mean along-wind position lies downwind of
    the crest (the highest cell)."""
    ny, nx = sand.shape
    ix, iy = dune["ix"], dune["iy"]
    cx, cy = dune["x_m"] / cell_size_m, dune["y_m"] / cell_size_m
    dx = wrap_delta(ix - cx, nx) * cell_size_m
    dy = wrap_delta(iy - cy, ny) * cell_size_m
    a = math.radians(wind_deg)
    along = dx * math.cos(a) + dy * math.sin(a)
    across = -dx * math.sin(a) + dy * math.cos(a)
    width = float(across.max() - across.min()) + cell_size_m
    h = sand[iy, ix]
    crest_along = float(along[np.argmax(h)])
    edge = 0.1 * width
    tips = (across <= across.min() + edge) | (across >= across.max() - edge)
    horn_along = float(along[tips].mean())
    return {"height_m": float(h.max()), "width_m": width,
            "aspect": float(h.max()) / width,
            "horn_offset_m": horn_along - crest_along,
            "horns_downwind": horn_along > crest_along}


# --- slopes -------------------------------------------------------------------

# The 4 neighbour offsets that, with their opposites, make erg's 8
# (stages/avalanching.h): (dx, dy, distance in cells).
_PAIRS = ((1, 0, 1.0), (0, 1, 1.0), (1, 1, math.sqrt(2.0)), (-1, 1, math.sqrt(2.0)))


def pair_slopes_deg(height, cell_size_m):
    """Slope angle between every cell and each of its 8 neighbours on the
    torus, the quantity avalanching bounds ([N24] eq. 9): a list of
    (angle array, higher-cell-is-this-one array, dx, dy) for 4 offsets."""
    out = []
    for dx, dy, dist in _PAIRS:
        nb = np.roll(np.roll(height, -dy, axis=0), -dx, axis=1)
        diff = height - nb
        out.append((np.degrees(np.arctan(np.abs(diff) / (dist * cell_size_m))), diff, dx, dy))
    return out


def max_sand_slope_deg(height, sand, cell_size_m, min_sand_m=1e-6):
    """The steepest neighbour pair whose higher cell holds sand (a bare
    bedrock cell cannot avalanche sand): the angle that the repose angle
    bounds after relaxation; and the fraction of such sand pairs above a
    given angle is computed by the caller from the returned arrays."""
    angles = []
    for ang, diff, dx, dy in pair_slopes_deg(height, cell_size_m):
        nb_sand = np.roll(np.roll(sand, -dy, axis=0), -dx, axis=1)
        donor_sand = np.where(diff > 0, sand, nb_sand)
        angles.append(ang[donor_sand > min_sand_m])
    allang = np.concatenate(angles) if angles else np.array([0.0])
    return float(allang.max()) if allang.size else 0.0, allang


def steepest_descent(height, cell_size_m):
    """Per cell: the steepest downhill angle to any of the 8 neighbours and
    its direction (degrees ccw from +x)."""
    best = np.zeros_like(height)
    direction = np.zeros_like(height)
    for ddx, ddy, dist in ((1, 0, 1.0), (0, 1, 1.0), (-1, 0, 1.0), (0, -1, 1.0),
                           (1, 1, math.sqrt(2)), (-1, 1, math.sqrt(2)),
                           (-1, -1, math.sqrt(2)), (1, -1, math.sqrt(2))):
        nb = np.roll(np.roll(height, -ddy, axis=0), -ddx, axis=1)
        ang = np.degrees(np.arctan(np.maximum(height - nb, 0.0) / (dist * cell_size_m)))
        better = ang > best
        best = np.where(better, ang, best)
        direction = np.where(better, math.degrees(math.atan2(ddy, ddx)), direction)
    return best, direction


def lee_slopes_deg(height, sand, cell_size_m, wind_deg, min_sand_m, min_angle_deg=1.0):
    """Slopes of the lee sides: cells holding sand whose steepest descent
    points downwind (within 90 degrees of the wind), steeper than
    `min_angle_deg` (flat bed and sheets excluded)."""
    ang, direction = steepest_descent(height, cell_size_m)
    rel = np.radians(direction - wind_deg)
    lee = (np.cos(rel) > 1e-9) & (sand > min_sand_m) & (ang > min_angle_deg)
    return ang[lee]


def histogram_peak(values, bin_deg, top_deg):
    """The fullest bin of a histogram of `bin_deg` bins whose last bin ends
    at `top_deg` (values above it are counted in one overflow bin): (lower
    edge, upper edge, counts, edges). Anchoring the bins at the top keeps a
    slope standing exactly at repose (plus float32 rounding) in the bin just
    below it instead of splitting it by where round numbers fall."""
    nbins = int(math.ceil(top_deg / bin_deg))
    edges = top_deg - bin_deg * np.arange(nbins, -1, -1, dtype=np.float64)
    edges = np.append(edges, max(90.0, top_deg + bin_deg))
    counts, edges = np.histogram(np.clip(values, edges[0], None), bins=edges)
    k = int(np.argmax(counts))
    return float(edges[k]), float(edges[k + 1]), counts, edges


# --- periodic patterns ----------------------------------------------------------

def periodic_gradient(height, cell_size_m):
    gx = (np.roll(height, -1, axis=1) - np.roll(height, 1, axis=1)) / (2 * cell_size_m)
    gy = (np.roll(height, -1, axis=0) - np.roll(height, 1, axis=0)) / (2 * cell_size_m)
    return gx, gy


def structure_orientation(height, cell_size_m):
    """Dominant gradient direction from the structure tensor (degrees in
    [0, 180)), the crest direction (perpendicular) and the coherence
    (lambda1 - lambda2) / (lambda1 + lambda2) in [0, 1]: 1 for parallel
    ridges, 0 for no preferred direction."""
    gx, gy = periodic_gradient(height, cell_size_m)
    jxx, jyy, jxy = float(np.sum(gx * gx)), float(np.sum(gy * gy)), float(np.sum(gx * gy))
    grad_dir = 0.5 * math.degrees(math.atan2(2 * jxy, jxx - jyy)) % 180.0
    tr = jxx + jyy
    disc = math.sqrt((jxx - jyy) ** 2 + 4 * jxy * jxy)
    coherence = disc / tr if tr > 0 else 0.0
    return {"gradient_deg": grad_dir, "crest_deg": (grad_dir + 90.0) % 180.0,
            "coherence": coherence}


def crest_wind_angle(crest_deg, wind_deg):
    """Angle between a crest line and the wind, in [0, 90] (90: transverse)."""
    d = (crest_deg - wind_deg) % 180.0
    return min(d, 180.0 - d)


def spectrum_wavelength(height, cell_size_m):
    """Dominant wavelength (metres) and wavevector direction (degrees in
    [0, 180)) of a periodic field from its 2-D power spectrum.

    The peak is the strongest non-zero wavevector; the wavelength is
    1 / (power-weighted mean |k|) over the wavevectors with |k| within a
    factor 2 of the peak's (the dominant band), so it varies continuously
    rather than in steps of the domain's harmonics."""
    ny, nx = height.shape
    p = np.abs(np.fft.fft2(height - height.mean())) ** 2
    kx = np.fft.fftfreq(nx, d=cell_size_m)[None, :]
    ky = np.fft.fftfreq(ny, d=cell_size_m)[:, None]
    kmag = np.sqrt(kx * kx + ky * ky)
    p[0, 0] = 0.0
    iy, ix = np.unravel_index(int(np.argmax(p)), p.shape)
    kp = float(kmag[iy, ix])
    band = (kmag >= kp / 2) & (kmag <= 2 * kp) & (kmag > 0)
    kmean = float(np.sum(p[band] * np.broadcast_to(kmag, p.shape)[band]) / np.sum(p[band]))
    direction = math.degrees(math.atan2(float(ky[iy, 0]), float(kx[0, ix]))) % 180.0
    return {"wavelength_m": 1.0 / kmean, "peak_wavelength_m": 1.0 / kp,
            "wavevector_deg": direction}


# --- mass ------------------------------------------------------------------------

def sand_total_units(snap):
    """Sand on the ground plus in saltation, exact (Python int)."""
    return snap["sand_units_total"] + snap["airborne_units_total"]


def mass_balance(snaps, event_steps):
    """Exact conservation between successive snapshots: for each interval
    whose steps hold no event, the change in total sand (units) must be 0;
    intervals with events are listed apart (their brushes add or remove
    sand by design). Returns (checked intervals, drifts, skipped)."""
    checked, drifts, skipped = 0, [], []
    for a, b in zip(snaps, snaps[1:]):
        if any(a["step"] <= s <= b["step"] for s in event_steps):
            skipped.append((a["step"], b["step"]))
            continue
        checked += 1
        drifts.append(sand_total_units(b) - sand_total_units(a))
    return checked, drifts, skipped

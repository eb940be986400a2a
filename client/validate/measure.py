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


def windward_slope(dune, sand, height, cell_size_m, wind_deg, threshold_m):
    """The mean slope of a dune's windward face, in degrees: from the crest
    (the highest sand cell) upwind along the wind, cell by cell (nearest
    cell, periodic), to the toe, the last cell whose sand is thicker than
    `threshold_m`; atan((height at the crest - height at the toe) / their
    distance). Field barchans have gentle windward faces (about 10 degrees)
    and a slip face at repose in the lee; a windward face at repose means
    that the flux saturated at the toe and the whole windward erosion is
    there (docs/physical-units.md, "What sets the speed of a dune here")."""
    ny, nx = sand.shape
    ix, iy = dune["ix"], dune["iy"]
    k = int(np.argmax(sand[iy, ix]))
    x0, y0 = float(ix[k]), float(iy[k])
    a = math.radians(wind_deg)
    ex, ey = math.cos(a), math.sin(a)
    top = float(height[iy[k], ix[k]])
    toe, toe_h = 0, top
    for n in range(1, max(nx, ny)):
        cx = int(round(x0 - n * ex)) % nx
        cy = int(round(y0 - n * ey)) % ny
        if sand[cy, cx] <= threshold_m:
            break
        toe, toe_h = n, float(height[cy, cx])
    if toe == 0:
        return 0.0
    return math.degrees(math.atan2(top - toe_h, toe * cell_size_m))


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
    lee = downwind(direction, wind_deg) & (sand > min_sand_m) & (ang > min_angle_deg)
    return ang[lee]


def downwind(direction_deg, wind_deg):
    """Whether a direction points downwind: within 90 degrees of the wind,
    exactly across it excluded."""
    return np.cos(np.radians(direction_deg - wind_deg)) > 1e-9


def repose_faces(height, sand, cell_size_m, wind_deg, repose_deg, min_sand_m, within_deg=0.5):
    """Where the surface stands at repose, and which way it faces: the
    shares of the cells holding more than `min_sand_m` of sand whose
    steepest descent (8 neighbours, as avalanching sees them) is within
    `within_deg` of `repose_deg` or steeper, split into those descending
    downwind (within 90 degrees of the wind: slip faces) and upwind (a
    windward face at repose). A field transverse dune is asymmetric, a
    gentle windward face and a slip face in the lee, so its share at repose
    faces downwind. Returns (lee share, windward share); 0 without sand."""
    ang, direction = steepest_descent(height, cell_size_m)
    held = sand > min_sand_m
    n = int(held.sum())
    if n == 0:
        return 0.0, 0.0
    steep = held & (ang >= repose_deg - within_deg)
    lee = downwind(direction, wind_deg)
    return float((steep & lee).sum()) / n, float((steep & ~lee).sum()) / n


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

def dominant_band(height, cell_size_m):
    """The power spectrum of a periodic field and its dominant band: the
    wavevectors whose |k| lies within a factor 2 of the strongest non-zero
    one's. Returns a dict of power, kx, ky, kmag (cycles per metre, arrays of
    the field's shape), peak (the strongest wavevector's index) and band (a
    mask), or None for a flat field. The one band that the wavelength and
    the crest orientation are both measured over."""
    ny, nx = height.shape
    p = np.abs(np.fft.fft2(height - height.mean())) ** 2
    p[0, 0] = 0.0
    if not np.any(p > 0):
        return None
    kx = np.broadcast_to(np.fft.fftfreq(nx, d=cell_size_m)[None, :], p.shape)
    ky = np.broadcast_to(np.fft.fftfreq(ny, d=cell_size_m)[:, None], p.shape)
    kmag = np.hypot(kx, ky)
    peak = np.unravel_index(int(np.argmax(p)), p.shape)
    kp = float(kmag[peak])
    band = (kmag >= kp / 2) & (kmag <= 2 * kp) & (kmag > 0)
    return {"power": p, "kx": kx, "ky": ky, "kmag": kmag, "peak": peak, "band": band}


def structure_orientation(height, cell_size_m):
    """Dominant gradient direction from the structure tensor (degrees in
    [0, 180)), the crest direction (perpendicular) and the coherence
    (lambda1 - lambda2) / (lambda1 + lambda2) in [0, 1]: 1 for parallel
    ridges, 0 for no preferred direction.

    The tensor is that of the field's dominant band, the wavevectors whose
    |k| lies within a factor 2 of the spectral peak's (the band of
    spectrum_wavelength): by Parseval, sum over that band of P(k) k k^T is
    the summed outer product of the band-passed field's gradient. A tensor
    of the raw cell-to-cell gradient weighs each wavevector by |k|^2, so the
    stochastic lifts' noise at the scale of a cell, small in height but
    steep, outweighs dunes tens of cells long and hides their crests
    (docs/dune-forms.md, "What makes a bed unstable")."""
    b = dominant_band(height, cell_size_m)
    if b is None:
        return {"gradient_deg": 0.0, "crest_deg": 90.0, "coherence": 0.0}
    w, bx, by = b["power"][b["band"]], b["kx"][b["band"]], b["ky"][b["band"]]
    jxx, jyy, jxy = float(np.sum(w * bx * bx)), float(np.sum(w * by * by)), float(np.sum(w * bx * by))
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
    b = dominant_band(height, cell_size_m)
    if b is None:
        raise ValueError("a flat field has no dominant wavelength")
    p, band, kmag = b["power"], b["band"], b["kmag"]
    kmean = float(np.sum(p[band] * kmag[band]) / np.sum(p[band]))
    direction = math.degrees(math.atan2(b["ky"][b["peak"]], b["kx"][b["peak"]])) % 180.0
    kp = float(kmag[b["peak"]])
    return {"wavelength_m": 1.0 / kmean, "peak_wavelength_m": 1.0 / kp,
            "wavevector_deg": direction}


# --- what a periodic domain resolves --------------------------------------------
#
# On a torus of sides Lx x Ly a pattern is a sum of the wavevectors
# (m / Lx, n / Ly) cycles per metre, m and n integers: its wavelength can only
# be 1 / |(m / Lx, n / Ly)| and a straight crest only lie across one of those
# lattice vectors (it must close on itself across the seams). A law that reads
# a wavelength or a crest orientation is judged only where the admissible
# values near the measured one are spaced at most half the law's tolerance
# apart (docs/dune-forms.md, "What a periodic domain can resolve").

def wavelength_resolution(wavelength_m, period_m):
    """Relative spacing of the wavelengths a torus admits near `wavelength_m`
    for a pattern whose crests lie across an axis of length `period_m`: the
    mode number there is k = floor(L / lambda) and the neighbouring admissible
    wavelengths L / k and L / (k + 1) differ by 1 / k of the shorter."""
    return 1.0 / max(1, int(math.floor(period_m / wavelength_m)))


def admissible_crests(wavelength_m, lx_m, ly_m):
    """The crest orientations (degrees in [0, 180), sorted) that a torus of
    lx_m x ly_m admits for a pattern of wavelength `wavelength_m`: those of the
    lattice wavevectors whose length lies within half a mode (0.5 / min(Lx,
    Ly) cycles per metre) of 1 / lambda, the same rounding as the wavelength's."""
    k0 = 1.0 / wavelength_m
    half = 0.5 / min(lx_m, ly_m)
    mmax = int(math.ceil((k0 + half) * lx_m)) + 1
    nmax = int(math.ceil((k0 + half) * ly_m)) + 1
    m = np.arange(-mmax, mmax + 1, dtype=np.float64)[None, :]
    n = np.arange(0, nmax + 1, dtype=np.float64)[:, None]
    kx, ky = np.broadcast_arrays(m / lx_m, n / ly_m)
    # One of each pair +-(m, n): n > 0, or n = 0 and m > 0.
    half_plane = (ky > 0) | ((ky == 0) & (kx > 0))
    shell = half_plane & (np.abs(np.hypot(kx, ky) - k0) <= half)
    crest = (np.degrees(np.arctan2(ky[shell], kx[shell])) + 90.0) % 180.0
    return np.unique(np.round(crest, 9))


def orientation_resolution(wavelength_m, lx_m, ly_m, predicted_deg, tolerance_deg):
    """How finely a torus resolves a crest orientation near `predicted_deg`
    for a pattern of wavelength `wavelength_m`: the largest gap (degrees)
    between neighbouring admissible orientations (admissible_crests) that
    reaches into predicted +/- tolerance; the admissible orientation nearest
    the prediction; and the widest difference from the prediction that the
    lattice alone can force on a pattern that obeys the law within the
    tolerance (the farthest from it of the admissible orientations nearest to
    some orientation inside the window). Returns a dict with gap_deg,
    nearest_deg, lattice_tolerance_deg and admissible (how many in all)."""
    crests = admissible_crests(wavelength_m, lx_m, ly_m)
    if crests.size == 0:
        return {"gap_deg": 180.0, "nearest_deg": float("nan"),
                "lattice_tolerance_deg": 90.0, "admissible": 0}
    # Offsets from the prediction in (-90, 90], sorted, with the wrap.
    off = np.sort((crests - predicted_deg + 90.0) % 180.0 - 90.0)
    ext = np.concatenate([off - 180.0, off, off + 180.0])
    gap = 0.0
    for a, b in zip(ext[:-1], ext[1:]):
        if b >= -tolerance_deg and a <= tolerance_deg:
            gap = max(gap, float(b - a))
    # The admissible orientation nearest each point of the window: those
    # inside it, and the first one outside an edge when it is nearer to that
    # edge than the first one inside.
    t = tolerance_deg
    # At least the tolerance: an obeying pattern may sit anywhere inside it.
    reach = max([t] + [float(abs(x)) for x in ext[np.abs(ext) <= t]])
    below, up_from = float(ext[ext < -t].max()), float(ext[ext >= -t].min())
    if -t - below < up_from + t:
        reach = max(reach, -below)
    above, down_from = float(ext[ext > t].min()), float(ext[ext <= t].max())
    if above - t < t - down_from:
        reach = max(reach, above)
    nearest = float(off[np.argmin(np.abs(off))]) + predicted_deg
    return {"gap_deg": gap, "nearest_deg": nearest % 180.0,
            "lattice_tolerance_deg": min(reach, 90.0), "admissible": int(crests.size)}


# --- mass ------------------------------------------------------------------------

def bare_fraction(sand):
    """The share of cells with no sand at all (bare rock): the exact integer
    sand makes 0.0 exact, so no threshold is needed."""
    return float((np.asarray(sand) <= 0.0).mean())


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


# --- dune orientation under two winds --------------------------------------------
#
# Courrech du Pont, Narteau & Gao 2014 (Geology 42, 743-746): under a
# multidirectional wind, dunes take one of two orientations. The sand flux at
# a crest is the flat-bed flux sped up by 1 + gamma |sin(theta)|, theta the
# angle between the wind and the crest (gamma = 1.6, as in Gao, Narteau,
# Rozier & Courrech du Pont 2015, Sci. Rep. 5, 14677).
# - Bed-instability mode (sand everywhere): the crests align with the
#   orientation alpha that maximises the gross bedform-normal transport
#   sum_i Q_i (1 + gamma |sin(theta_i - alpha)|) |sin(theta_i - alpha)|
#   (Rubin & Hunter 1987, with the crest speed-up).
# - Fingering mode (a sand source on bedrock): the dune elongates along the
#   resultant flux at its crest, the orientation alpha where the
#   crest-normal components of the sped-up fluxes cancel,
#   sum_i Q_i (1 + gamma |sin(theta_i - alpha)|) sin(theta_i - alpha) = 0,
#   with the along-crest component pointing towards alpha.
# A wind is (direction in degrees, flux or any weight proportional to it:
# time fraction times flux).

SPEED_UP_GAMMA = 1.6


def two_winds(primary_deg, divergence_deg, flux_ratio):
    """The two alternating winds of a bidirectional regime (job.proto
    BidirectionalWind): the primary, and the secondary at primary +
    divergence carrying 1 / flux_ratio of the primary's flux."""
    return [(float(primary_deg), float(flux_ratio)), (float(primary_deg + divergence_deg), 1.0)]


def _crest_terms(winds, alpha_rad, gamma):
    """Per orientation alpha: the sped-up fluxes' crest-normal sums (signed and
    gross) and the along-crest sum."""
    normal = np.zeros_like(alpha_rad)
    gross = np.zeros_like(alpha_rad)
    along = np.zeros_like(alpha_rad)
    for direction, q in winds:
        rel = math.radians(direction) - alpha_rad
        s = np.sin(rel)
        crest = q * (1.0 + gamma * np.abs(s))
        normal += crest * s
        gross += crest * np.abs(s)
        along += crest * np.cos(rel)
    return normal, gross, along


def bed_instability_orientation(winds, gamma=SPEED_UP_GAMMA, step_deg=0.01):
    """Crest orientation (degrees in [0, 180)) of the bed-instability mode:
    the maximum of the gross bedform-normal transport with the crest
    speed-up, found on a grid of `step_deg` and refined by a parabola
    through the best point and its neighbours."""
    n = int(round(180.0 / step_deg))
    alpha = np.radians(np.arange(n) * step_deg)
    _, gross, _ = _crest_terms(winds, alpha, gamma)
    k = int(np.argmax(gross))
    g0, g1, g2 = gross[(k - 1) % n], gross[k], gross[(k + 1) % n]
    denom = g0 - 2.0 * g1 + g2
    shift = 0.5 * (g0 - g2) / denom if denom < 0 else 0.0
    return float((k + shift) * step_deg) % 180.0


def fingering_orientation(winds, gamma=SPEED_UP_GAMMA, step_deg=0.5):
    """Elongation direction (degrees in [0, 360), the way the finger grows)
    of the fingering mode: a zero of the crest-normal flux where the
    along-crest flux is positive, refined by bisection. Where several exist
    (not for two winds less than 180 degrees apart), the one closest to the
    resultant of the plain fluxes is taken."""
    def normal_at(a_deg):
        n, _, along = _crest_terms(winds, np.radians(np.array([a_deg])), gamma)
        return float(n[0]), float(along[0])

    grid_deg = np.arange(0.0, 360.0, step_deg)
    normal, _, along = _crest_terms(winds, np.radians(grid_deg), gamma)
    roots = []
    for k in range(len(grid_deg)):
        a, b = grid_deg[k], grid_deg[k] + step_deg
        fa, fb = normal[k], normal[(k + 1) % len(grid_deg)]
        if fa == 0.0:
            if along[k] > 0:
                roots.append(float(a))
            continue
        if fa * fb >= 0.0:
            continue
        for _ in range(60):
            m = 0.5 * (a + b)
            fm, _ = normal_at(m)
            if (fm < 0.0) == (fa < 0.0):
                a, fa = m, fm
            else:
                b = m
        root = 0.5 * (a + b)
        if normal_at(root)[1] > 0.0:
            roots.append(root % 360.0)
    if not roots:
        raise ValueError("no fingering orientation: the crest fluxes cancel")
    rx = sum(q * math.cos(math.radians(d)) for d, q in winds)
    ry = sum(q * math.sin(math.radians(d)) for d, q in winds)
    resultant = math.degrees(math.atan2(ry, rx))
    return min(roots, key=lambda r: abs(wrap_delta(r - resultant, 360.0)))


def axis_difference(a_deg, b_deg):
    """Angle between two axes (orientations modulo 180 degrees), in [0, 90]."""
    d = (a_deg - b_deg) % 180.0
    return min(d, 180.0 - d)


def axial_mean(angles_deg, weights):
    """Weighted mean of axes (modulo 180 degrees) by doubling the angles:
    (mean in [0, 180), resultant length in [0, 1]: 1 when all agree)."""
    a = np.radians(2.0 * np.asarray(angles_deg, dtype=np.float64))
    w = np.asarray(weights, dtype=np.float64)
    c, s = float(np.sum(w * np.cos(a))), float(np.sum(w * np.sin(a)))
    total = float(np.sum(w))
    mean = (0.5 * math.degrees(math.atan2(s, c))) % 180.0
    return mean, (math.hypot(c, s) / total if total > 0 else 0.0)


def principal_axes(w, dx, dy):
    """Weighted second moments of offsets (dx, dy) about their mean: the
    major axis (degrees in [0, 180)) and the major and minor standard
    deviations."""
    w = np.asarray(w, dtype=np.float64)
    w = w / w.sum()
    dx = dx - float(np.sum(w * dx))
    dy = dy - float(np.sum(w * dy))
    sxx, syy, sxy = float(np.sum(w * dx * dx)), float(np.sum(w * dy * dy)), float(np.sum(w * dx * dy))
    axis = (0.5 * math.degrees(math.atan2(2.0 * sxy, sxx - syy))) % 180.0
    half = 0.5 * (sxx + syy)
    disc = math.sqrt(0.25 * (sxx - syy) ** 2 + sxy * sxy)
    return axis, math.sqrt(half + disc), math.sqrt(max(half - disc, 0.0))


def body_elongation(dune, sand, cell_size_m):
    """Elongation axis of one sand body (from dunes()): the major axis of the
    sand-weighted second moments of its cells about its centroid (positions
    wrapped to the nearest image, so a body across the seam is measured
    whole; a body longer than half the domain is not). Returns the axis
    (degrees in [0, 180)), the major and minor standard deviations (m)."""
    ny, nx = sand.shape
    ix, iy = dune["ix"], dune["iy"]
    dx = wrap_delta(ix - dune["x_m"] / cell_size_m, nx) * cell_size_m
    dy = wrap_delta(iy - dune["y_m"] / cell_size_m, ny) * cell_size_m
    return principal_axes(sand[iy, ix], dx, dy)


def elongation_orientation(sand, cell_size_m, threshold_m, min_cells, min_aspect=1.5):
    """The elongation axis of the dunes of a sand-limited field (fingering
    mode): the volume-weighted axial mean of the axes of the bodies thicker
    than `threshold_m` that are elongated (major over minor standard
    deviation at least `min_aspect`). Returns a dict: axis (degrees in
    [0, 180), nan without elongated bodies), agreement (the axial mean's
    resultant length), bodies measured, bodies found, and the per-body rows
    (axis, aspect, volume)."""
    bodies = dunes(sand, cell_size_m, threshold_m, min_cells)
    rows = []
    for d in bodies:
        axis, major, minor = body_elongation(d, sand, cell_size_m)
        aspect = major / minor if minor > 0 else float("inf")
        rows.append({"axis_deg": axis, "aspect": aspect, "volume_m3": d["volume_m3"]})
    long = [r for r in rows if r["aspect"] >= min_aspect]
    if not long:
        return {"axis_deg": float("nan"), "agreement": 0.0, "measured": 0,
                "bodies": len(rows), "rows": rows}
    axis, agreement = axial_mean([r["axis_deg"] for r in long], [r["volume_m3"] for r in long])
    return {"axis_deg": axis, "agreement": agreement, "measured": len(long),
            "bodies": len(rows), "rows": rows}


def source_body(sand, cell_size_m, threshold_m, min_cells, source_m):
    """The dune fed by a sand source (the fingering mode's dune): the body
    thicker than `threshold_m` that holds the source's cell, else the one
    nearest to it on the torus. Bodies that left the source (the seed pile
    blown away as a dome) are not it. Returns a dict: axis (degrees in
    [0, 180)), aspect (major over minor standard deviation), volume (m^3),
    distance from the source's cell to the body's nearest cell (m, 0 when it
    holds it), bodies found; or None without a body."""
    ny, nx = sand.shape
    # The cell that holds the source (cell i spans [i, i + 1) cells).
    sx, sy = math.floor(source_m[0] / cell_size_m) % nx, math.floor(source_m[1] / cell_size_m) % ny
    bodies = dunes(sand, cell_size_m, threshold_m, min_cells)
    best = None
    for d in bodies:
        dist = float(np.min(np.hypot(wrap_delta(d["ix"] - sx, nx), wrap_delta(d["iy"] - sy, ny)))) * cell_size_m
        if best is None or dist < best[0]:
            best = (dist, d)
    if best is None:
        return None
    axis, major, minor = body_elongation(best[1], sand, cell_size_m)
    return {"axis_deg": axis, "aspect": major / minor if minor > 0 else float("inf"),
            "volume_m3": best[1]["volume_m3"], "distance_m": best[0], "bodies": len(bodies)}


def crest_orientation(height, cell_size_m):
    """Crest orientation (degrees in [0, 180)) of a field of ridges (the
    bed-instability mode), measured twice: from the strongest wavevector of
    the 2-D spectrum (crests perpendicular to it) and from the structure
    tensor (with its coherence)."""
    sp = spectrum_wavelength(height, cell_size_m)
    st = structure_orientation(height, cell_size_m)
    return {"spectrum_deg": (sp["wavevector_deg"] + 90.0) % 180.0,
            "tensor_deg": st["crest_deg"], "coherence": st["coherence"],
            "wavelength_m": sp["wavelength_m"]}


def autocorrelation_axis(field, cell_size_m, level=0.5):
    """Elongation axis of a pattern from its periodic autocorrelation (FFT):
    the second moments of the central lobe, the lags connected to zero lag
    where the autocorrelation of the field's departure from its mean stays
    above `level` of its zero-lag value. Needs no segmentation, so bodies
    merged by thin sand tails or wrapping the torus are measured as they
    are. Returns (axis in degrees in [0, 180), major / minor standard
    deviation of the lobe)."""
    from scipy import ndimage
    f = field - field.mean()
    ac = np.real(np.fft.ifft2(np.abs(np.fft.fft2(f)) ** 2))
    if ac[0, 0] <= 0:
        return float("nan"), 1.0
    ac = np.fft.fftshift(ac / ac[0, 0])
    ny, nx = ac.shape
    labels, _ = ndimage.label(ac >= level)
    lobe = labels == labels[ny // 2, nx // 2]
    iy, ix = np.nonzero(lobe)
    axis, major, minor = principal_axes(ac[iy, ix], (ix - nx // 2) * cell_size_m,
                                        (iy - ny // 2) * cell_size_m)
    return axis, (major / minor if minor > 0 else float("inf"))

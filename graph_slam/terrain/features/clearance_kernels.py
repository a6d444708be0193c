"""Compiled loops of the clearance (numba): the grid heights under a toe path and the path
against the features' edges, the same arithmetic in the same order as their numpy formulation
(``tests/test_terrain_feature_kernels.py``). Compiled on first use, cached on disk
(:mod:`graph_slam.terrain.features.kernels`)."""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True, nogil=True)
def highest_cells(xy, radius, offsets, ox, oy, cell, h, var, b, w):  # pragma: no cover
    """Per point (N×2): the highest known cell of ``h`` among those holding the point moved by
    ``radius`` times each offset (the first of equal ones), its σ less the pose part,
    ``√max(var - (b/w)², 0)`` (``b/w`` 0 where not finite, as ``np.nan_to_num``), and its
    i, j; NaN, NaN, 0, 0 where none is known."""
    nx, ny = h.shape
    n = xy.shape[0]
    ground = np.full(n, np.nan)
    sigma = np.full(n, np.nan)
    cells = np.zeros((n, 2), np.int64)
    for p in range(n):
        best, bi, bj = -np.inf, 0, 0
        for k in range(offsets.shape[0]):
            qi = np.floor(((xy[p, 0] + radius * offsets[k, 0]) - ox) / cell)
            qj = np.floor(((xy[p, 1] + radius * offsets[k, 1]) - oy) / cell)
            if not (qi >= 0 and qi < nx and qj >= 0 and qj < ny):
                continue
            i, j = int(qi), int(qj)
            v = h[i, j]
            if np.isfinite(v) and v > best:
                best, bi, bj = v, i, j
        if best > -np.inf:
            ground[p] = best
            cells[p, 0], cells[p, 1] = bi, bj
            corr = b[bi, bj] / w[bi, bj] if w[bi, bj] != 0 else 0.0
            corr = (
                corr
                if np.isfinite(corr)
                else 0.0
                if np.isnan(corr)
                else np.copysign(np.finfo(np.float64).max, corr)
            )
            rest = var[bi, bj] - corr * corr
            sigma[p] = np.sqrt(rest if rest > 0.0 or np.isnan(rest) else 0.0)
    return ground, sigma, cells


@numba.njit(cache=True, nogil=True)
def edge_bands(px, py, edges, band_m, ground, sigma):  # pragma: no cover - compiled
    """Per point: the terrain under it where an edge's step model holds (the last edge, rows of
    ``edges``: x_m, y_m, cos and sin of the yaw, the y range's ends, the heights before and
    beyond, the rise's σ, within ``band_m`` of the point along its normal and inside its y
    range ± 2 cm): the height beyond the line on its far side, before it on its near side,
    and the rise's σ; ``ground`` and ``sigma`` elsewhere. Also which edge (-1: none)."""
    n = px.size
    which = np.full(n, -1, np.int64)
    ground = ground.copy()
    sigma = sigma.copy()
    for e in range(edges.shape[0]):
        x_m, y_m, c, s, lo, hi = (
            edges[e, 0],
            edges[e, 1],
            edges[e, 2],
            edges[e, 3],
            edges[e, 4],
            edges[e, 5],
        )
        for p in range(n):
            d = (px[p] - x_m) * c + (py[p] - y_m) * s
            if abs(d) <= band_m and py[p] >= lo - 0.02 and py[p] <= hi + 0.02:
                which[p] = e
                ground[p] = edges[e, 7] if d >= 0 else edges[e, 6]
                sigma[p] = edges[e, 8]
    return ground, sigma, which


@numba.njit(cache=True, nogil=True)
def _nan_min(a, b):  # pragma: no cover - compiled
    """``np.minimum`` of two numbers (NaN when either is)."""
    if np.isnan(a) or np.isnan(b):
        return np.nan
    return min(a, b)


@numba.njit(cache=True, nogil=True)
def _sign(v):  # pragma: no cover - compiled
    if v > 0:
        return 1.0
    if v < 0:
        return -1.0
    return v  # ±0 or NaN, as np.sign


@numba.njit(cache=True, nogil=True)
def edge_profile_min(px, py, pz, x_m, y_m, cos_yaw, sin_yaw, lo, hi, band_m, near, far):
    """Of the path's points (N each) within ``band_m`` of an edge line along its normal and
    inside its y range (± 2 cm): the one nearest the edge's profile (its vertical face and
    higher surface; the first of equal ones, a NaN distance first), its signed distance and
    the derivatives by the edge's position and by the higher surface's height
    (:func:`graph_slam.terrain.features.clearance._profile`); index -1: no point in the band."""
    z_lo, z_hi = min(near, far), max(near, far)
    best_k, best, best_x, best_h = -1, np.inf, 0.0, 0.0
    for k in range(px.size):
        d = (px[k] - x_m) * cos_yaw + (py[k] - y_m) * sin_yaw
        if not (abs(d) <= band_m and py[k] >= lo - 0.02 and py[k] <= hi + 0.02):
            continue
        z = pz[k]
        high_side = d >= 0 if far >= near else d <= 0
        to_high = abs(z - z_hi) if high_side else np.inf
        dz = z - min(max(z, z_lo), z_hi)
        to_face = np.hypot(d, dz)
        below = z < z_hi if high_side else z < z_lo
        sign = -1.0 if below else 1.0
        dist = sign * _nan_min(to_high, to_face)
        if best_k >= 0 and np.isnan(best):
            break
        if best_k < 0 or np.isnan(dist) or dist < best:
            if to_high <= to_face:
                by_x, by_h = 0.0, -_sign(z - z_hi)
            else:
                by_x = -d / max(to_face, 1e-9)
                by_h = -dz / max(to_face, 1e-9) if z > z_hi else 0.0
            best_k, best, best_x, best_h = k, dist, sign * by_x, sign * by_h
    return best_k, best, best_x, best_h


@numba.njit(cache=True, nogil=True)
def resample(p, step):  # pragma: no cover - compiled
    """A path (N×3, N ≥ 2) linearly resampled at its vertices and every ``step`` of its length
    from its start (:func:`graph_slam.terrain.features.clearance.resample_path`); the path
    itself when its length is not finite and positive."""
    n = p.shape[0]
    s = np.empty(n)
    s[0] = 0.0
    for k in range(n - 1):
        dx, dy, dz = p[k + 1, 0] - p[k, 0], p[k + 1, 1] - p[k, 1], p[k + 1, 2] - p[k, 2]
        s[k + 1] = s[k] + np.sqrt(dx * dx + dy * dy + dz * dz)  # 0 + x is x: as np.cumsum
    if not (np.isfinite(s[-1]) and s[-1] > 0):
        return p.copy()
    u = np.unique(np.concatenate((s, np.arange(0.0, s[-1], step))))
    out = np.empty((u.size, 3))
    for c in range(3):
        out[:, c] = np.interp(u, s, np.ascontiguousarray(p[:, c]))
    return out

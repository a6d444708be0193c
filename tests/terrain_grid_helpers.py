"""Synthetic height grids with known answers for the terrain features' tests.

Each grid is the stride-frame layout of the online grid (2 cm cells, x −0.2..1.8 m, y ±0.6 m);
a cell's height is the mean of the analytic surface over it (8×8 samples: a cell across an
edge is a mixture, as a fused cell is), plus seeded noise; its variance the noise's plus the
samples' spread. Tolerances: the targets (rise 3 mm, tread and nosing 8 mm, slope
0.5°, curb and box height 3 mm, box depth 8 mm).
"""

from __future__ import annotations

import math

import numpy as np

from graph_slam.terrain.features.extract import extract_features

CELL = 0.02
X0, Y0, NX, NY = -0.2, -0.6, 100, 60
RISE_TOL, TREAD_TOL, NOSING_TOL = 0.003, 0.008, 0.008
SLOPE_TOL = math.radians(0.5)


def grid(surface, noise_m=0.0, seed=0, unknown=None):
    """Cell means of ``surface(x, y)`` over its 8×8 samples that ``unknown`` leaves seen (a
    cell with under a quarter of them seen is NaN), seeded noise."""
    sub = (np.arange(8) + 0.5) / 8 * CELL
    xs = X0 + (np.arange(NX)[:, None] * CELL + sub[None, :]).ravel()
    ys = Y0 + (np.arange(NY)[:, None] * CELL + sub[None, :]).ravel()
    xx, yy = np.meshgrid(xs, ys, indexing="ij")
    z = surface(xx, yy).reshape(NX, 8, NY, 8)
    seen = np.ones_like(z, bool) if unknown is None else ~unknown(xx, yy).reshape(z.shape)
    n = seen.sum(axis=(1, 3))
    with np.errstate(invalid="ignore", divide="ignore"):
        h = np.where(seen, z, 0.0).sum(axis=(1, 3)) / n
        var = np.where(seen, (z - h[:, None, :, None]) ** 2, 0.0).sum(axis=(1, 3)) / n
    var = var + max(noise_m, 1e-4) ** 2
    if noise_m:
        h = h + np.random.default_rng(seed).normal(0.0, noise_m, h.shape)
    hidden = n < 16
    return np.where(hidden, np.nan, h), np.where(hidden, np.nan, var)


def features(h, var):
    return extract_features(h, var, (X0, Y0), CELL)


def stairs_surface(first=0.513, rise=0.17, tread=0.28, n=4, yaw_deg=0.0):
    t = math.tan(math.radians(yaw_deg))

    def f(x, y):
        u = x + t * y  # nosing k at x = first + k·tread - tan(yaw)·y
        k = np.clip(np.floor((u - first) / tread) + 1, 0, n)
        return k * rise

    return f


def seen_counts(unknown, per_sample=3):
    """Points per cell of :func:`grid`'s layout: ``per_sample`` for each of its 8×8 samples
    that ``unknown`` leaves seen (points fall evenly on a surface)."""
    sub = (np.arange(8) + 0.5) / 8 * CELL
    xs = X0 + (np.arange(NX)[:, None] * CELL + sub[None, :]).ravel()
    ys = Y0 + (np.arange(NY)[:, None] * CELL + sub[None, :]).ravel()
    xx, yy = np.meshgrid(xs, ys, indexing="ij")
    seen = ~unknown(xx, yy).reshape(NX, 8, NY, 8)
    return per_sample * seen.sum(axis=(1, 3))

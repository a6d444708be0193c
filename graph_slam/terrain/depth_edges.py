"""Depth edges of a depth image: the range of valid depths around a pixel.

A pixel whose neighbourhood spans a large depth range sits on a depth discontinuity (a box's
outline against the floor behind it) and may be a flying pixel; the online terrain's variance
model gives it the depth-edge term (:class:`graph_slam.terrain.online.DepthNoiseModel`,
docs/terrain.md). The neighbourhood: the pixel and ±1, ±2 pixels along u and v of the
full-resolution image; invalid depth (0 or NaN) is never a neighbour.
"""

from __future__ import annotations

import numpy as np

_EDGE_OFFSETS = ((0, 1), (0, -1), (0, 2), (0, -2), (1, 0), (-1, 0), (2, 0), (-2, 0))


def depth_range_at(depth_m: np.ndarray, v_px: np.ndarray, u_px: np.ndarray) -> np.ndarray:
    """Per pixel (v, u) of the full-resolution depth image: the range (max − min) of the valid
    (> 0, finite) depths at the pixel and at ±1, ±2 pixels along u and v (0: no valid
    neighbour)."""
    depth = np.asarray(depth_m)
    h, w = depth.shape
    z0 = depth[v_px, u_px].astype(np.float64)
    lo, hi = z0.copy(), z0.copy()
    for dv, du in _EDGE_OFFSETS:
        vv, uu = np.clip(v_px + dv, 0, h - 1), np.clip(u_px + du, 0, w - 1)
        z = depth[vv, uu].astype(np.float64)
        ok = (z > 0) & np.isfinite(z)
        lo = np.where(ok, np.minimum(lo, z), lo)
        hi = np.where(ok, np.maximum(hi, z), hi)
    return hi - lo


def depth_range_image(depth_m: np.ndarray, step: int) -> np.ndarray:
    """:func:`depth_range_at` for every ``step``-th pixel in v and u at once (the
    ``depth_m[::step, ::step]`` grid): strided views of the image padded with invalid depth,
    no gathers. Invalid depth (0 or NaN) is never a neighbour."""
    depth = np.asarray(depth_m, dtype=np.float32)
    h, w = depth.shape
    pad = np.pad(depth, 2)
    lo = depth[::step, ::step].copy()
    hi = lo.copy()
    nv, nu = lo.shape
    for dv, du in _EDGE_OFFSETS:
        z = pad[2 + dv : 2 + dv + h : step, 2 + du : 2 + du + w : step][:nv, :nu]
        ok = z > 0
        np.minimum(lo, z, out=lo, where=ok)
        np.maximum(hi, z, out=hi, where=ok)
    return (hi - lo).astype(np.float64)

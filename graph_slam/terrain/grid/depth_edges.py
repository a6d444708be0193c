"""Depth edges of a depth image: the range of valid depths around a pixel.

A pixel whose neighbourhood spans a large depth range sits on a depth discontinuity (a box's
outline against the floor behind it) and may be a flying pixel; the online terrain's variance
model gives it the depth-edge term (:class:`graph_slam.terrain.grid.online.DepthNoiseModel`,
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


def _span(n: int, step: int, offset: int) -> tuple[int, int]:
    """Grid indices ``[i0, i1)`` of the ``step``-grid whose neighbour ``i·step + offset`` lies
    inside ``[0, n)``."""
    count = -(-n // step)
    i0 = max(0, -(offset // step))  # ceil(-offset / step)
    i1 = min(count, (n - 1 - offset) // step + 1)
    return i0, max(i0, i1)


def depth_range_image(depth_m: np.ndarray, step: int) -> np.ndarray:
    """:func:`depth_range_at` for every ``step``-th pixel in v and u at once (the
    ``depth_m[::step, ::step]`` grid): each neighbour is a strided view of the image (no copy
    of it: the padded copy was a third of the grid update's time at 424×240); a neighbour
    outside the image or with invalid depth (0 or NaN) is never counted."""
    depth = np.asarray(depth_m, dtype=np.float32)
    h, w = depth.shape
    lo = depth[::step, ::step].copy()
    hi = lo.copy()
    for dv, du in _EDGE_OFFSETS:
        (a0, a1), (b0, b1) = _span(h, step, dv), _span(w, step, du)
        if a1 <= a0 or b1 <= b0:
            continue
        z = depth[a0 * step + dv : (a1 - 1) * step + dv + 1 : step,
                  b0 * step + du : (b1 - 1) * step + du + 1 : step]  # fmt: skip
        ok = z > 0
        np.minimum(lo[a0:a1, b0:b1], z, out=lo[a0:a1, b0:b1], where=ok)
        np.maximum(hi[a0:a1, b0:b1], z, out=hi[a0:a1, b0:b1], where=ok)
    return (hi - lo).astype(np.float64)

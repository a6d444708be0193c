"""The online terrain's per-frame pass over the depth image, compiled (numba).

Per frame the live grid (:class:`graph_slam.terrain.grid.live.LiveTerrain`) takes every
``pixel_step``-th pixel with depth in range, back-projects it, finds the depth range of its
neighbourhood (:mod:`graph_slam.terrain.grid.depth_edges`), moves it into the stride frame and
gives it its cell, its depth variance (range noise and depth-edge term along the ray) and its
pose variance (:func:`graph_slam.terrain.grid.online.z_variance`). Written with numpy
(:func:`~graph_slam.terrain.maps.builder.map_pixels`, :func:`~graph_slam.terrain.maps.builder.map_cloud`,
:func:`~graph_slam.terrain.grid.depth_edges.depth_range_image`,
:func:`~graph_slam.terrain.grid.online.point_terms`) that was about thirty array operations,
1.3 ms per 424×240 frame; this is one loop with the same arithmetic
(``tests/test_terrain_kernels.py`` checks it against them).
"""

from __future__ import annotations

import numba
import numpy as np

from graph_slam.terrain.grid.online import (
    OnlineTerrainConfig,
    PointTerms,
    checked_pose,
    z_variance_terms,
)

_EDGE = ((0, 1), (0, -1), (0, 2), (0, -2), (1, 0), (-1, 0), (2, 0), (-2, 0))


@numba.njit(cache=True, nogil=True)
def frame_terms(
    depth, step, camera, depth_limits, edges, pose, quad, lin, const, grid, noise,
):  # fmt: skip
    """One frame's points and their terms.

    ``depth``: the full-resolution image; every ``step``-th pixel with depth strictly inside
    ``depth_limits`` (min, max) is a point. ``camera``: fx, fy, cx, cy. ``edges``: compute the
    neighbourhood depth range (``noise[4] > 0``). ``pose``: stride_T_camera; the pose variance
    ``pᵀ quad p + lin·p + const`` (None-covariance: zeros). ``grid``: x0, y0, cell, nx, ny.
    ``noise``: σ at 1 m, exponent, floor, edge threshold, edge factor.

    Returns the camera-frame points (K×3), their depth ranges (K; zeros without ``edges``)
    and, for the K' points on the grid, their flat cell, stride-frame z, depth variance and
    pose variance."""
    fx, fy, cx, cy = camera
    h, w = depth.shape
    hs, ws = (h + step - 1) // step, (w + step - 1) // step
    points = np.empty((hs * ws, 3))
    ranges = np.zeros(hs * ws)
    flat = np.empty(hs * ws, np.int64)
    z_s = np.empty(hs * ws)
    var_depth = np.empty(hs * ws)
    var_pose = np.empty(hs * ws)
    x0, y0, cell = grid[0], grid[1], grid[2]
    nx, ny = int(grid[3]), int(grid[4])
    k = 0
    n = 0
    for vs in range(hs):
        v = vs * step
        for us in range(ws):
            u = us * step
            d0 = depth[v, u]
            if not (d0 > depth_limits[0] and d0 < depth_limits[1]):  # in the image's dtype
                continue
            z = np.float64(d0)
            x = (u - cx) * z / fx
            y = (v - cy) * z / fy
            points[k, 0], points[k, 1], points[k, 2] = x, y, z
            r = 0.0
            if edges:
                lo = d0
                hi = d0
                for e in range(8):
                    vv, uu = v + _EDGE[e][0], u + _EDGE[e][1]
                    if vv < 0 or vv >= h or uu < 0 or uu >= w:
                        continue
                    d = depth[vv, uu]
                    if d > 0:
                        lo = min(lo, d)
                        hi = max(hi, d)
                r = np.float64(hi - lo)
            ranges[k] = r
            k += 1
            px = pose[0, 0] * x + pose[0, 1] * y + pose[0, 2] * z + pose[0, 3]
            py = pose[1, 0] * x + pose[1, 1] * y + pose[1, 2] * z + pose[1, 3]
            pz = pose[2, 0] * x + pose[2, 1] * y + pose[2, 2] * z + pose[2, 3]
            i = np.int64(np.floor((px - x0) / cell))
            j = np.int64(np.floor((py - y0) / cell))
            if not (i >= 0 and i < nx and j >= 0 and j < ny):
                continue
            flat[n] = i * ny + j
            z_s[n] = pz
            ray_z = (x * pose[2, 0] + y * pose[2, 1] + z * pose[2, 2]) / z
            sigma = noise[0] * z ** noise[1] + noise[2]
            var_range = sigma * sigma
            if edges and r > noise[3]:
                var_range = var_range + noise[4] * (r * r) / 3.0
            var_depth[n] = ray_z * ray_z * var_range
            qp0 = x * quad[0, 0] + y * quad[1, 0] + z * quad[2, 0]  # (p Q)_j
            qp1 = x * quad[0, 1] + y * quad[1, 1] + z * quad[2, 1]
            qp2 = x * quad[0, 2] + y * quad[1, 2] + z * quad[2, 2]
            var_pose[n] = (qp0 * x + qp1 * y + qp2 * z) + (lin[0] * x + lin[1] * y + lin[2] * z)
            var_pose[n] += const
            n += 1
    return (
        points[:k].copy(), ranges[:k].copy(), flat[:n].copy(), z_s[:n].copy(),
        var_depth[:n].copy(), var_pose[:n].copy(),
    )  # fmt: skip


def frame_point_terms(
    cfg: OnlineTerrainConfig,
    depth_m: np.ndarray,
    intrinsics,
    depth_limits_m: tuple[float, float],
    stride_T_camera: np.ndarray,
    cov: np.ndarray | None,
) -> tuple[np.ndarray, np.ndarray | None, PointTerms]:
    """One frame's map cloud (every ``cfg.pixel_step``-th pixel with depth strictly inside
    ``depth_limits_m``, camera frame), its depth ranges (None without the edge term) and its
    :func:`point_terms`, in one compiled pass over the depth image
    (:func:`graph_slam.terrain.grid.kernels.frame_terms`)."""
    depth = np.asarray(depth_m)
    pose = np.ascontiguousarray(checked_pose(stride_T_camera))
    if cov is None:
        quad, lin, const = np.zeros((3, 3)), np.zeros(3), 0.0
    else:
        quad, lin, const = z_variance_terms(pose[:3, :3], np.asarray(cov, np.float64))
    noise = cfg.depth_noise
    edges = noise.edge_factor > 0
    nx, ny = cfg.shape
    camera = (intrinsics.fx_px, intrinsics.fy_px, intrinsics.cx_px, intrinsics.cy_px)
    points, ranges, flat, z_m, var_depth, var_pose = frame_terms(
        depth, cfg.pixel_step, camera, np.array(depth_limits_m, dtype=depth.dtype), edges,
        pose, quad, lin, const,
        np.array([cfg.x_range_m[0], cfg.y_range_m[0], cfg.cell_m, nx, ny], np.float64),
        np.array([noise.sigma_at_1m_m, noise.exponent, noise.sigma_floor_m,
                  noise.edge_threshold_m, noise.edge_factor]),
    )  # fmt: skip
    return points, ranges if edges else None, PointTerms(flat, z_m, var_depth, var_pose)

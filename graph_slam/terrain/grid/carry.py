"""The terrain ahead kept across the foot strike: the previous stride's grid moved into the new
stride frame through the estimated relative pose, its variance grown by that pose's
uncertainty (docs/terrain.md, "Carry across the foot strike")."""

from __future__ import annotations

import numpy as np

from graph_slam.terrain.grid.online import CellSums, OnlineTerrainConfig, z_variance
from graph_slam.terrain.grid.view import TerrainView

MIN_COVERED_FRACTION = 0.5
"""A new cell is carried when known old cells cover at least this fraction of it."""


def carry_map(
    cfg: OnlineTerrainConfig, old: TerrainView, new_T_old: np.ndarray, cov_new_T_old: np.ndarray
) -> CellSums:
    """The prior of the new stride's map: each known cell of ``old`` (its centre at its height)
    moved by ``new_T_old``, kept when it lands on the grid at x ≥ ``carry_min_x_m``, with its
    variance grown by ``cov_new_T_old`` (6×6, rotation first, right perturbation
    ``new_T_old exp(ξ)``). Its depth-noise part stays independent, its pose part and the
    relative pose's add up (correlated).

    A moved cell rarely lands on one new cell: it is shared among the (up to) four new cells
    its square overlaps, by the area of each overlap (bilinear weights of its moved centre), as
    a fused cell holds the points over its area; a new cell's height is its shares' mean by area
    (:func:`_share_sums`). Binned to the one cell holding its moved centre, a cell landed up to
    half a cell (1 cm) away, and a box edge with it. A new cell less than half covered by known
    old cells is left unknown."""
    known = old.known.ravel()
    nx, ny = cfg.shape
    if not known.any():
        return CellSums.empty(nx * ny)
    xc, yc = old.cell_centers_m()
    xx, yy = np.meshgrid(xc, yc, indexing="ij")
    s = old.sums
    p_old = np.column_stack([xx.ravel(), yy.ravel(), old.height_m.ravel()])[known]
    w = s.w[known]
    var_noise = s.a[known] / w**2  # the points' depth noise, averaged
    std_corr = s.b[known] / w
    spread = np.maximum(old.variance_m2.ravel()[known] - var_noise - std_corr**2, 0.0)
    rotation, t = new_T_old[:3, :3], new_T_old[:3, 3]
    p_new = p_old @ rotation.T + t
    var_pose = std_corr**2 + z_variance(p_old, rotation, cov_new_T_old)
    u = (p_new[:, 0] - cfg.x_range_m[0]) / cfg.cell_m - 0.5
    v = (p_new[:, 1] - cfg.y_range_m[0]) / cfg.cell_m - 0.5
    i0, j0 = np.floor(u).astype(np.int64), np.floor(v).astype(np.int64)
    fu, fv = u - i0, v - j0
    parts: list[list[np.ndarray]] = [[] for _ in range(7)]
    for di, dj, area in (
        (0, 0, (1 - fu) * (1 - fv)), (1, 0, fu * (1 - fv)), (0, 1, (1 - fu) * fv), (1, 1, fu * fv),
    ):  # fmt: skip
        i, j = i0 + di, j0 + dj
        keep = (i >= 0) & (i < nx) & (j >= 0) & (j < ny) & (area > 1e-3)
        keep &= cfg.x_range_m[0] + (i + 0.5) * cfg.cell_m >= cfg.carry_min_x_m
        for out, val in zip(parts, (i * ny + j, area, p_new[:, 2], var_noise, spread, var_pose,
                                    s.last_t_s[known]), strict=True):  # fmt: skip
            out.append(val[keep])
    flat, area, z, noise, spread, pose, last = (np.concatenate(x) for x in parts)
    # a new cell mostly over unknown old cells (the shadow behind a box, the old map's border)
    # takes nothing: a small share would stand for the whole cell
    covered = np.bincount(flat, area, nx * ny)[flat] >= MIN_COVERED_FRACTION
    flat, area, z, noise, spread, pose, last = (
        x[covered] for x in (flat, area, z, noise, spread, pose, last)
    )
    return _share_sums(nx * ny, flat, area, z, noise, spread, pose, last)


def _share_sums(n, flat, area, z, noise, spread, pose, last) -> CellSums:
    """The sums of the carried shares (old cells' parts landing in new cells).

    The shares of a new cell are parts of its area, not repeated measurements of one height:
    its height is their mean by area over the variance of each share's height as its part's
    mean, its depth noise and pose part (``u = area / (noise + pose)``), **not** its spread. A
    cell across a step edge has a large spread (the two treads'), and weighted by its whole
    variance it lost its share to the level cells beside it: the edge moved toward a cell
    boundary (4-5 mm on the simulated stairs up, up to 8 mm by the shift's fraction of a
    cell). A cell held only by a depth edge's flying pixels (depth noise σ of centimetres)
    still weighs next to nothing. The new cell weighs ``coverage / v`` against new points (one
    point of ``v``, the ``u``-weighted mean of its shares' whole variances, spread included);
    its depth noise and pose part are its shares' ``u``-weighted combinations (the noise
    averaging as independent, the pose σ as correlated), and the spread stays spread (in
    ``Σwz²``), the mixture of the shares' heights adding to it. A cell carried whole keeps
    its height and each part of its variance."""
    var = noise + spread + pose
    u = area / np.maximum(noise + pose, 1e-30)
    u_sum = np.bincount(flat, u, n)
    safe = np.where(u_sum > 0, u_sum, 1.0)
    v_cell = np.bincount(flat, u * var, n) / safe
    coverage = np.bincount(flat, area, n)
    scale = coverage / (np.where(v_cell > 0, v_cell, 1.0) * safe)
    w = u * scale[flat]
    sums = [
        np.bincount(flat, x, n)
        for x in (w, w * z, w * w * noise, w * np.sqrt(pose), w * (z * z + spread + noise),
                  w * noise)
    ]  # fmt: skip
    last_t = np.full(n, np.nan)
    np.fmax.at(last_t, flat, last)
    # carried cells count no point of the new stride
    return CellSums(sums[0], sums[1], sums[2], sums[3], np.zeros(n, np.int64), last_t,
                    sums[4], sums[5])  # fmt: skip

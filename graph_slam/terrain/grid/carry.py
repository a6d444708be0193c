"""The terrain ahead kept across the foot strike: the previous stride's grid moved into the new
stride frame through the estimated relative pose, its variance grown by that pose's
uncertainty (docs/terrain.md, "Carry across the foot strike")."""

from __future__ import annotations

import dataclasses

import numpy as np

from graph_slam.terrain.grid.online import (
    CellSums,
    OnlineTerrainConfig,
    PointTerms,
    z_variance,
)
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
    a fused cell holds the points over its area. Each share enters as one point whose weight
    is the share's fraction of the cell's (its depth-noise variance grown to match: the pose
    part is the whole cell's). Binned to the one cell holding its moved centre, a cell landed
    up to half a cell (1 cm) away, and a box edge with it. A new cell less than half covered
    by known old cells is left unknown."""
    known = old.known.ravel()
    if not known.any():
        return CellSums.empty(int(np.prod(cfg.shape)))
    xc, yc = old.cell_centers_m()
    xx, yy = np.meshgrid(xc, yc, indexing="ij")
    s = old.sums
    p_old = np.column_stack([xx.ravel(), yy.ravel(), old.height_m.ravel()])[known]
    w = s.w[known]
    var_ind = old.variance_m2.ravel()[known] - (s.b[known] / w) ** 2  # depth noise + spread
    std_corr = s.b[known] / w
    rotation, t = new_T_old[:3, :3], new_T_old[:3, 3]
    p_new = p_old @ rotation.T + t
    var_pose = std_corr**2 + z_variance(p_old, rotation, cov_new_T_old)
    var_all = np.maximum(var_ind, 0.0) + var_pose
    nx, ny = cfg.shape
    u = (p_new[:, 0] - cfg.x_range_m[0]) / cfg.cell_m - 0.5
    v = (p_new[:, 1] - cfg.y_range_m[0]) / cfg.cell_m - 0.5
    i0, j0 = np.floor(u).astype(np.int64), np.floor(v).astype(np.int64)
    fu, fv = u - i0, v - j0
    last_old = s.last_t_s[known]
    flats, zs, vds, vps, lasts, areas = [], [], [], [], [], []
    for di, dj, area in (
        (0, 0, (1 - fu) * (1 - fv)), (1, 0, fu * (1 - fv)), (0, 1, (1 - fu) * fv), (1, 1, fu * fv),
    ):  # fmt: skip
        i, j = i0 + di, j0 + dj
        keep = (i >= 0) & (i < nx) & (j >= 0) & (j < ny) & (area > 1e-3)
        keep &= cfg.x_range_m[0] + (i + 0.5) * cfg.cell_m >= cfg.carry_min_x_m
        a = area[keep]
        flats.append(i[keep] * ny + j[keep])
        areas.append(a)
        zs.append(p_new[keep, 2])
        vds.append(var_all[keep] / a - var_pose[keep])
        vps.append(var_pose[keep])
        lasts.append(last_old[keep])
    flat, area = np.concatenate(flats), np.concatenate(areas)
    # a new cell mostly over unknown old cells (the shadow behind a box, the old map's border)
    # takes nothing: a small share would stand for the whole cell
    covered = np.bincount(flat, area, nx * ny)[flat] >= MIN_COVERED_FRACTION
    terms = PointTerms(*(np.concatenate(x)[covered] for x in (flats, zs, vds, vps)))
    carried = CellSums.empty(nx * ny).plus(terms, np.concatenate(lasts)[covered])
    # carried cells count no point of the new stride
    return dataclasses.replace(carried, count=carried.count * 0)

"""The terrain ahead kept across the foot strike: the previous stride's grid moved into the new
stride frame through the estimated relative pose, its variance grown by that pose's
uncertainty (docs/terrain.md, "Carry across the foot strike")."""

from __future__ import annotations

import dataclasses

import numpy as np

from graph_slam.terrain.online import (
    CellSums,
    OnlineTerrainConfig,
    PointTerms,
    TerrainView,
    cell_index,
    z_variance,
)


def carry_map(
    cfg: OnlineTerrainConfig, old: TerrainView, new_T_old: np.ndarray, cov_new_T_old: np.ndarray
) -> CellSums:
    """The prior of the new stride's map: each known cell of ``old`` (its centre at its height)
    moved by ``new_T_old``, kept when it lands on the grid at x ≥ ``carry_min_x_m``, with its
    variance grown by ``cov_new_T_old`` (6×6, rotation first, right perturbation
    ``new_T_old exp(ξ)``). Each carried cell enters as one point: its depth-noise part stays
    independent, its pose part and the relative pose's add up (correlated)."""
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
    var_rel = z_variance(p_old, rotation, cov_new_T_old)
    flat, inside = cell_index(cfg, p_new[:, :2])
    keep = inside & (p_new[:, 0] >= cfg.carry_min_x_m)
    terms = PointTerms(flat[keep], p_new[keep, 2], var_ind[keep], (std_corr**2 + var_rel)[keep])
    last = s.last_t_s[known][keep]
    carried = CellSums.empty(int(np.prod(cfg.shape))).plus(terms, last)
    # carried cells count no point of the new stride
    return dataclasses.replace(carried, count=carried.count * 0)

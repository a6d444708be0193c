"""The terrain ahead kept across the foot strike: the previous stride's grid moved into the new
stride frame through the estimated relative pose, its variance grown by that pose's
uncertainty (docs/terrain.md, "Carry across the foot strike")."""

from __future__ import annotations

import numpy as np

from graph_slam.terrain.grid.online import CellSums, OnlineTerrainConfig, z_variance
from graph_slam.terrain.grid.view import TerrainView

MIN_COVERED_FRACTION = 0.5
"""A new cell is carried when known old cells cover at least this fraction of it."""
MIN_STEP_M = 0.03
"""A cell between neighbours along x this far apart in height, its own between theirs, holds a
step (the features' least rise): it is carried as two pieces (:func:`_pieces`)."""


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
    w = s.w[known]
    var_noise = s.a[known] / w**2  # the points' depth noise, averaged
    std_corr = s.b[known] / w
    spread = np.maximum(old.variance_m2.ravel()[known] - var_noise - std_corr**2, 0.0)
    k, start, length, z_old, spread = _pieces(old, known, spread)
    x_old = xx.ravel()[known][k] + (start + length / 2 - 0.5) * old.cell_m
    p_old = np.column_stack([x_old, yy.ravel()[known][k], z_old])
    rotation, t = new_T_old[:3, :3], new_T_old[:3, 3]
    p_new = p_old @ rotation.T + t
    var_pose = std_corr[k] ** 2 + z_variance(p_old, rotation, cov_new_T_old)
    lo = (p_new[:, 0] - cfg.x_range_m[0]) / cfg.cell_m - length / 2  # the piece along x
    hi = lo + length
    v = (p_new[:, 1] - cfg.y_range_m[0]) / cfg.cell_m - 0.5
    i0, j0 = np.floor(lo).astype(np.int64), np.floor(v).astype(np.int64)
    over_x = (np.minimum(hi, i0 + 1) - lo, np.maximum(hi - (i0 + 1), 0.0))
    fv = v - j0
    parts: list[list[np.ndarray]] = [[] for _ in range(7)]
    for di, dj in ((0, 0), (1, 0), (0, 1), (1, 1)):
        area = over_x[di] * (fv if dj else 1 - fv)
        i, j = i0 + di, j0 + dj
        keep = (i >= 0) & (i < nx) & (j >= 0) & (j < ny) & (area > 1e-3)
        keep &= cfg.x_range_m[0] + (i + 0.5) * cfg.cell_m >= cfg.carry_min_x_m
        for out, val in zip(parts, (i * ny + j, area, p_new[:, 2], var_noise[k], spread,
                                    var_pose, s.last_t_s[known][k]), strict=True):  # fmt: skip
            out.append(val[keep])
    flat, area, z, noise, spread, pose, last = (np.concatenate(x) for x in parts)
    # a new cell mostly over unknown old cells (the shadow behind a box, the old map's border)
    # takes nothing: a small share would stand for the whole cell
    covered = np.bincount(flat, area, nx * ny)[flat] >= MIN_COVERED_FRACTION
    flat, area, z, noise, spread, pose, last = (
        x[covered] for x in (flat, area, z, noise, spread, pose, last)
    )
    return _share_sums(nx * ny, flat, area, z, noise, spread, pose, last)


def _pieces(old: TerrainView, known: np.ndarray, spread: np.ndarray):
    """The known old cells as pieces along x: ``(cell, start, length, height, spread)``, the
    cell's index among the known ones, where the piece begins in it and its length (cell
    units). A cell between two known neighbours along x at least ``MIN_STEP_M`` apart, its
    height between theirs, holds a step: the far neighbour's surface over the fraction ``f``
    of its length that its height says (``f = (h - h_near) / (h_far - h_near)``, the features'
    edge model) and the near one's over the rest, each piece at its surface's height (its
    spread less the step's ``f (1 - f) Δh²``). Every other cell is one piece at its height.
    Shared by its mean alone, a cell across a nosing spread its mixture over the two new cells
    it overlaps (on the simulated stairs up the carried cells' height RMSE 14.2 mm, 12.4 with
    the pieces). An edge whose points fall in two cells (a riser's, on a cell boundary) leaves
    two such cells side by side; each is split against the other's mixed height, which only
    roughly places the step."""
    h = old.height_m
    nb = np.full((2, *h.shape), np.nan)
    nb[0, 1:] = h[:-1]
    nb[1, :-1] = h[1:]
    h_k, before, after = h.ravel()[known], nb[0].ravel()[known], nb[1].ravel()[known]
    step = after - before
    with np.errstate(divide="ignore", invalid="ignore"):
        f = (h_k - before) / step
    mixed = np.isfinite(f) & (np.abs(step) >= MIN_STEP_M) & (f > 0.02) & (f < 0.98)
    idx = np.arange(int(known.sum()))
    plain = ~mixed
    m = idx[mixed]
    fm = f[mixed]
    rest = np.maximum(spread[mixed] - fm * (1 - fm) * step[mixed] ** 2, 0.0)
    return (
        np.concatenate([idx[plain], m, m]),
        np.concatenate([np.zeros(plain.sum()), np.zeros(m.size), 1 - fm]),
        np.concatenate([np.ones(plain.sum()), 1 - fm, fm]),
        np.concatenate([h_k[plain], before[mixed], after[mixed]]),
        np.concatenate([spread[plain], rest, rest]),
    )


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

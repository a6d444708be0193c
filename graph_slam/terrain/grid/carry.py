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
    spread less the step's ``f (1 - f) Δh²``). Two such cells side by side (an edge whose points
    fall in both: a riser's, on a cell boundary), between neighbours that far apart, hold one
    step where their fractions together put it (``x_end - cell (f1 + f2)``, as the features
    read it). Every other cell is one piece at its height. Shared by its mean alone, a cell
    across a nosing spread its mixture over the two new cells it overlaps (on the simulated
    stairs up the carried cells' height RMSE 14.2 mm; 12.4 with single cells split, 9.6 with
    pairs too)."""
    cut, z1, z2, frac, dh = _step_cells(old.height_m)
    rest = np.maximum(spread - (frac * (1 - frac) * dh**2).ravel()[known], 0.0)
    cut_k, z1_k, z2_k = cut.ravel()[known], z1.ravel()[known], z2.ravel()[known]
    idx = np.arange(int(known.sum()))
    two = cut_k < 1
    return (
        np.concatenate([idx, idx[two]]),
        np.concatenate([np.zeros(idx.size), cut_k[two]]),
        np.concatenate([cut_k, 1 - cut_k[two]]),
        np.concatenate([z1_k, z2_k[two]]),
        np.concatenate([rest, rest[two]]),
    )


def _step_cells(h: np.ndarray):
    """Per cell of a height grid: the cut along x (cell units) between its near piece at ``z1``
    and its far piece at ``z2`` (a cut of 1: one piece, NaN ``z2``), the cell's own fraction
    of the far surface and the step's height (for its spread), by the rules of
    :func:`_pieces`."""
    nx = h.shape[0]

    def shifted(k: int) -> np.ndarray:  # h[i + k] at i (NaN off the grid)
        out = np.full(h.shape, np.nan)
        if k > 0:
            out[:-k] = h[k:]
        else:
            out[-k:] = h[: nx + k]
        return out

    hm1, hp1, hp2 = shifted(-1), shifted(1), shifted(2)
    with np.errstate(divide="ignore", invalid="ignore"):  # NaN: unknown neighbours
        f_one = (h - hm1) / (hp1 - hm1)
        step2 = hp2 - hm1
        fa, fb = (h - hm1) / step2, (hp1 - hm1) / step2
        fa, fb = np.where(np.isfinite(fa), fa, np.nan), np.where(np.isfinite(fb), fb, np.nan)
    pair = np.isfinite(fa) & np.isfinite(fb) & (np.abs(step2) >= MIN_STEP_M)
    pair &= (fa > 0.02) & (fa <= fb) & (fb < 0.98)
    pair[1:] &= ~pair[:-1]  # a run of mixed cells: its first pair
    second = np.zeros_like(pair)
    second[1:] = pair[:-1]
    single = np.isfinite(f_one) & (np.abs(hp1 - hm1) >= MIN_STEP_M) & (f_one > 0.02)
    single &= (f_one < 0.98) & ~pair & ~second
    # piece 1: [0, cut) at z1; piece 2: [cut, 1) at z2 (none where cut is 1)
    cut, z1, z2 = np.ones(h.shape), h.copy(), np.full(h.shape, np.nan)
    frac = np.zeros(h.shape)  # the cell's own share of the far surface (its spread's part)
    cut[single], z1[single], z2[single] = 1 - f_one[single], hm1[single], hp1[single]
    frac[single] = f_one[single]
    big = np.where(pair, fa + fb, np.nan)  # the far surface's length over the pair (cells)
    near, far = hm1, hp2
    lo = pair & (big <= 1)  # the step in the second cell
    hi = pair & (big > 1)  # in the first
    cut[hi], z1[hi], z2[hi] = 2 - big[hi], near[hi], far[hi]
    z1[lo] = near[lo]
    frac[pair] = fa[pair]
    lo2, hi2 = np.zeros_like(lo), np.zeros_like(hi)
    lo2[1:], hi2[1:] = lo[:-1], hi[:-1]
    near2, far2, big2 = shifted(-2), shifted(1), np.full(h.shape, np.nan)
    big2[1:] = big[:-1]
    cut[lo2], z1[lo2], z2[lo2] = 1 - big2[lo2], near2[lo2], far2[lo2]
    z1[hi2] = far2[hi2]
    fb2 = np.full(h.shape, np.nan)
    fb2[1:] = fb[:-1]
    frac[second] = fb2[second]
    step_pair = np.where(pair, step2, np.nan)
    step_pair[1:] = np.where(second[1:], step2[:-1], step_pair[1:])
    dh = np.nan_to_num(np.where(pair | second, step_pair, z2 - z1))
    return cut, z1, z2, frac, dh


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

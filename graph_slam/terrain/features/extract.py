"""The feature extraction of :mod:`graph_slam.terrain.features.model` (the steps of its docstring)."""

from __future__ import annotations

import math

import numba
import numpy as np

from graph_slam.errors import MappingError
from graph_slam.terrain.features.kinds import boxes_of, chains_of
from graph_slam.terrain.features.model import (
    EdgeLine,
    FeatureConfig,
    Ramp,
    TerrainFeatures,
    _Grid,
)

_DEFAULT = FeatureConfig()


def features_of_view(view, config: FeatureConfig | None = None, source: str = "online"):
    """The features of a :class:`~graph_slam.terrain.grid.view.TerrainView` (online or re-fused)."""
    s = view.sums
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = (s.b / s.w).reshape(view.shape)
        noise = (np.sqrt(s.a) / s.w).reshape(view.shape)
    return extract_features(
        view.height_m, view.variance_m2, view.origin_xy_m, view.cell_m,
        corr_sigma_m=corr, noise_sigma_m=noise, config=config, t_s=view.t_s,
        stride_index=view.stride_index, source=source, count=view.count,
    )  # fmt: skip


def extract_features(
    height_m: np.ndarray,
    variance_m2: np.ndarray,
    origin_xy_m,
    cell_m: float,
    *,
    corr_sigma_m: np.ndarray | None = None,
    noise_sigma_m: np.ndarray | None = None,
    config: FeatureConfig | None = None,
    t_s: float = float("nan"),
    stride_index: int = -1,
    source: str = "online",
    count: np.ndarray | None = None,
) -> TerrainFeatures:
    """Stairs, ramps, curbs and boxes of a height grid (NaN: unknown). ``variance_m2``: each
    cell's height variance; ``corr_sigma_m``: the part of its σ common to the grid (the pose's;
    zero when None); ``noise_sigma_m``: the part from its points' depth noise (a cell where it
    exceeds ``max_noise_sigma_m`` is taken as not seen; None: every cell with a height);
    ``count``: the points per cell (where a shadow begins inside the last cell seen; None:
    ``shadow_cell_seen``)."""
    cfg = config or _DEFAULT
    h = np.asarray(height_m, dtype=np.float64)
    var = np.asarray(variance_m2, dtype=np.float64)
    if h.ndim != 2 or var.shape != h.shape:
        raise MappingError(f"features: height {h.shape} and variance {var.shape} grids differ")
    corr = np.zeros_like(h) if corr_sigma_m is None else np.asarray(corr_sigma_m, np.float64)
    noisy = None
    if noise_sigma_m is not None:
        with np.errstate(invalid="ignore"):  # held only by a depth edge's flying pixels
            noisy = np.isfinite(h) & ~(np.asarray(noise_sigma_m) <= cfg.max_noise_sigma_m)
    cnt = None if count is None else np.asarray(count, dtype=np.float64).reshape(h.shape)
    g = _Grid(h, var, np.nan_to_num(corr), float(origin_xy_m[0]), float(origin_xy_m[1]), cell_m,
              noisy, cnt)  # fmt: skip
    out = TerrainFeatures(stride_index, float(t_s), source)
    if g.known.sum() < cfg.min_window_cells:
        return out
    slope, rms, valid = _local_planes(g, cfg)
    level = valid & (slope < math.tan(math.radians(cfg.level_max_deg))) & (rms < cfg.fit_rms_max_m)
    sloped = (
        valid
        & (slope >= math.tan(math.radians(cfg.ramp_min_deg)))
        & (slope <= math.tan(math.radians(cfg.ramp_max_deg)))
        & (rms < cfg.fit_rms_max_m)
    )
    labels, terraces = _terraces(g, level, cfg)
    edges = _edges(g, labels, terraces, cfg)
    boxes, used = boxes_of(edges, terraces, cfg)
    rest = [e for k, e in enumerate(edges) if k not in used]
    stairs, curbs, parts = chains_of(rest, g, labels, terraces, cfg)
    boxes += parts
    ramps = _ramps(g, sloped, labels, terraces, cfg)
    return TerrainFeatures(
        stride_index, float(t_s), source, tuple(stairs), tuple(ramps), tuple(curbs), tuple(boxes)
    )


@numba.njit(cache=True, nogil=True)
def _plane_kernel(h, known, half, min_cells):  # pragma: no cover - compiled
    """Per cell: slope (height per cell), RMS residual of the plane over its window, valid."""
    nx, ny = h.shape
    slope = np.zeros((nx, ny))
    rms = np.zeros((nx, ny))
    valid = np.zeros((nx, ny), dtype=np.bool_)
    for i in range(nx):
        for j in range(ny):
            if not known[i, j]:
                continue
            n = sx = sy = sz = sxx = sxy = syy = sxz = syz = szz = 0.0
            z0 = h[i, j]
            for a in range(max(i - half, 0), min(i + half + 1, nx)):
                for b in range(max(j - half, 0), min(j + half + 1, ny)):
                    if known[a, b]:
                        x, y, z = a - i, b - j, h[a, b] - z0
                        n += 1.0
                        sx += x
                        sy += y
                        sz += z
                        sxx += x * x
                        sxy += x * y
                        syy += y * y
                        sxz += x * z
                        syz += y * z
                        szz += z * z
            if n < min_cells:
                continue
            mx, my, mz = sx / n, sy / n, sz / n
            cxx, cxy, cyy = sxx / n - mx * mx, sxy / n - mx * my, syy / n - my * my
            cxz, cyz, czz = sxz / n - mx * mz, syz / n - my * mz, szz / n - mz * mz
            det = cxx * cyy - cxy * cxy
            if det <= 1e-9:
                continue
            gx = (cyy * cxz - cxy * cyz) / det
            gy = (cxx * cyz - cxy * cxz) / det
            slope[i, j] = np.sqrt(gx * gx + gy * gy)
            rms[i, j] = np.sqrt(max(czz - gx * cxz - gy * cyz, 0.0))
            valid[i, j] = True
    return slope, rms, valid


def _local_planes(g: _Grid, cfg: FeatureConfig):
    """Per cell: slope (tan) and RMS residual of the plane over its window; enough cells."""
    h = np.where(g.known, g.h, 0.0)
    slope, rms, valid = _plane_kernel(h, g.known, cfg.window_cells // 2, cfg.min_window_cells)
    return slope / g.cell, rms, valid


def _terraces(g: _Grid, level: np.ndarray, cfg: FeatureConfig):
    """Components of level cells, and per component its height, σ parts and extent."""
    from scipy import ndimage

    labels, n = ndimage.label(level)
    if n == 0:
        return labels, {}
    flat = labels.ravel()
    sizes = np.bincount(flat, minlength=n + 1)
    w = np.where(level, 1.0 / np.maximum(g.var, 1e-12), 0.0).ravel()
    var_ind = np.maximum(g.var - g.corr**2, 0.0).ravel()
    hv = np.where(level, g.h, 0.0).ravel()
    sw = np.bincount(flat, w, n + 1)
    height = np.bincount(flat, w * hv, n + 1) / np.maximum(sw, 1e-300)
    ind = np.sqrt(np.bincount(flat, w * w * var_ind, n + 1)) / np.maximum(sw, 1e-300)
    corr = np.bincount(flat, w * g.corr.ravel(), n + 1) / np.maximum(sw, 1e-300)
    keep = sizes >= cfg.min_terrace_cells
    keep[0] = False
    labels = np.where(keep[labels], labels, 0)
    labels = _grow(g, labels, height, cfg)
    objs = ndimage.find_objects(labels)
    out = {}
    for k in np.flatnonzero(keep):
        sx, sy = objs[k - 1]
        out[int(k)] = {
            "h": float(height[k]), "ind": float(ind[k]), "corr": float(corr[k]),
            "i": (sx.start, sx.stop - 1), "j": (sy.start, sy.stop - 1), "n": int(sizes[k]),
        }  # fmt: skip
    return labels, out


def _grow(g: _Grid, labels: np.ndarray, height: np.ndarray, cfg: FeatureConfig) -> np.ndarray:
    """Each terrace grown by up to ``grow_cells`` cells (4-neighbours) into the known cells
    within ``grow_tol_m`` of its height: the cells by an edge are not level (their window
    holds the step) but those still on the surface are the terrace's, so that it ends at the
    edge (its height stays that of its level cells)."""
    lab = labels.copy()
    nx, ny = lab.shape
    h = np.where(g.known, g.h, np.nan)
    for _ in range(cfg.grow_cells):
        free = g.known & (lab == 0)
        if not free.any():
            break
        for di, dj in ((1, 0), (-1, 0), (0, 1), (0, -1)):
            nb = np.zeros_like(lab)
            nb[max(di, 0) : nx + min(di, 0), max(dj, 0) : ny + min(dj, 0)] = lab[
                max(-di, 0) : nx + min(-di, 0), max(-dj, 0) : ny + min(-dj, 0)
            ]
            with np.errstate(invalid="ignore"):
                take = free & (nb > 0) & (np.abs(h - height[nb]) <= cfg.grow_tol_m)
            lab[take] = nb[take]
            free &= ~take
    return lab


def _transitions(g: _Grid, labels: np.ndarray, terraces: dict, cfg: FeatureConfig):
    """Every pair of terraces met along a row (x) within the gap: row j, labels, edge x and
    its σ, occluded flag."""
    jj, ii = np.nonzero(labels.T)  # sorted by row j, then by i
    lab = labels[ii, jj]
    nxt = slice(1, None)
    same_row = jj[:-1] == jj[nxt]
    gap = ii[nxt] - ii[:-1]
    cand = np.flatnonzero(same_row & (lab[:-1] != lab[nxt]) & (gap <= cfg.max_gap_cells + 1))
    if cand.size == 0:
        return []
    ha = np.array([terraces[la]["h"] for la in lab[cand]])
    hb = np.array([terraces[lb]["h"] for lb in lab[cand + 1]])
    rise = hb - ha
    ok = np.abs(rise) >= cfg.min_rise_m
    cand, ha, rise = cand[ok], ha[ok], rise[ok]
    if cand.size == 0:
        return []
    i1, i2, j = ii[cand], ii[cand + 1], jj[cand]
    width = cfg.max_gap_cells + 2
    idx = i1[:, None] + np.arange(width)[None, :]
    inside = idx <= i2[:, None]
    idx = np.minimum(idx, g.h.shape[0] - 1)
    hw = g.h[idx, j[:, None]]
    vw = g.var[idx, j[:, None]]
    # beyond a drop, a cell of flying pixels is not seen; up a riser, the cells across it are
    # mixtures of the two surfaces and of the riser, whatever their noise
    flying = g.noisy[idx, j[:, None]] & (rise < 0)[:, None]
    f = np.clip((hw - ha[:, None]) / rise[:, None], 0.0, 1.0)
    flying |= _sparse_far(g, idx, i1, j, f, rise, cfg)
    unknown = inside & (~np.isfinite(hw) | flying)
    f = np.where(unknown, 1.0, np.where(inside, f, 0.0))
    occluded = unknown.any(axis=1)
    # Occluded: the cells past the last one mostly of the near surface, before the first cell
    # not seen, are the far surface's (flying pixels of the edge fill the shadow's first cells
    # with heights in between: counted as fractions they put the edge up to a cell late).
    pos = np.arange(width)[None, :]
    first_unknown = np.where(occluded, np.argmax(unknown, axis=1), width)[:, None]
    near = inside & ~unknown & (f < 0.5) & (pos < first_unknown)
    last_near = np.max(np.where(near, pos, 0), axis=1)[:, None]
    f = np.where(occluded[:, None] & (pos > last_near) & inside, 1.0, f)
    x = g.x0 + (i2 + 1) * g.cell - g.cell * f.sum(axis=1)
    seen, counted = _seen_part(g, i1 + last_near[:, 0], j, cfg)
    x = x - np.where(occluded, 1.0 - seen, 0.0) * g.cell
    noise = np.where(inside & ~unknown, np.nan_to_num(vw) / rise[:, None] ** 2, 0.0).sum(axis=1)
    sigma = g.cell * np.sqrt(noise)
    carried = _carried(g, i1, i2, j)
    return [
        (int(a), int(b), float(yy), float(xx), float(ss), bool(oc), bool(ct), bool(ca))
        for a, b, yy, xx, ss, oc, ct, ca in zip(
            lab[cand], lab[cand + 1], g.y_of(j), x, sigma, occluded, counted, carried,
            strict=True,
        )
    ]


def _sparse_far(g: _Grid, idx, i1, j, f, rise, cfg: FeatureConfig) -> np.ndarray:
    """Per row and cell of the window: beyond a drop, a cell mostly of the far surface (f at
    least 0.5) holding under ``shadow_sparse_fraction`` of the mean count of the two near
    cells before the edge (those up to ``i1``): the shadow, seen from a few late viewpoints
    only (``FeatureConfig.shadow_sparse_fraction``)."""
    out = np.zeros(idx.shape, dtype=bool)
    if g.count is None or cfg.shadow_sparse_fraction <= 0 or len(i1) == 0:
        return out
    c = g.count
    before = np.stack([c[np.maximum(i1 - k, 0), j] for k in (0, 1)], axis=1).astype(float)
    ok = (before.min(axis=1) >= cfg.shadow_count_min) & (rise < 0)
    ref = before.mean(axis=1)[:, None]
    return ok[:, None] & (f >= 0.5) & (c[idx, j[:, None]] < cfg.shadow_sparse_fraction * ref)


def _carried(g: _Grid, i1: np.ndarray, i2: np.ndarray, j: np.ndarray) -> np.ndarray:
    """Per row: whether the cells on both sides of the edge hold no point of this stride
    (carried from the previous one); False when the counts are not known."""
    if g.count is None:
        return np.zeros(len(i1), bool)
    return (g.count[i1, j] == 0) & (g.count[i2, j] == 0)


def _centre_x(g: _Grid, terrace: dict) -> float:
    """The middle of a terrace's extent along x."""
    return g.x0 + (terrace["i"][0] + terrace["i"][1] + 1) * g.cell / 2


def _seen_part(g: _Grid, i: np.ndarray, j: np.ndarray, cfg: FeatureConfig):
    """Per row: the part of cell ``(i, j)`` (the last seen before a shadow) that lies before
    the shadow, and whether the counts gave it (else ``shadow_cell_seen``): its points over
    the mean of the two cells before it (``FeatureConfig.shadow_from_counts``)."""
    seen = np.full(len(i), cfg.shadow_cell_seen)
    if g.count is None or not cfg.shadow_from_counts or len(i) == 0:
        return seen, np.zeros(len(i), bool)
    c = g.count
    before = np.stack([c[np.maximum(i - k, 0), j] for k in (1, 2)], axis=1)
    before = np.where((i[:, None] - np.array([1, 2])) >= 0, before, 0.0)
    ref = before.mean(axis=1)
    ok = before.min(axis=1) >= cfg.shadow_count_min
    with np.errstate(invalid="ignore", divide="ignore"):
        part = np.clip(c[i, j] / ref, 0.0, 1.0)
    return np.where(ok, part, seen), ok


def _fit_line(
    y: np.ndarray,
    x: np.ndarray,
    s: np.ndarray,
    occluded: bool,
    y_ref: float = 0.0,
    common_sigma_m: float = 0.0,
):
    """x = x̄ + b (y - ȳ) through the rows (3σ outliers out), reported at ``y_ref`` clipped into
    the rows seen; ``common_sigma_m``: an error every row shares (it does not average out)."""
    keep = np.ones(len(y), bool)
    for _ in range(2):
        yy, xx = y[keep], x[keep]
        ym = yy.mean()
        syy = float(((yy - ym) ** 2).sum())
        b = float(((yy - ym) * (xx - xx.mean())).sum() / syy) if syy > 0 else 0.0
        res = x - (xx.mean() + b * (y - ym))
        scale = max(1.4826 * float(np.median(np.abs(res[keep]))), float(np.median(s)), 1e-4)
        new = np.abs(res) <= 3 * scale
        if new.sum() < 2 or (new == keep).all():
            break
        keep = new
    yy, xx, ss = y[keep], x[keep], s[keep]
    n = len(yy)
    ym, xm = float(yy.mean()), float(xx.mean())
    syy = float(((yy - ym) ** 2).sum())
    b = float(((yy - ym) * (xx - xm)).sum() / syy) if syy > 0 else 0.0
    res = xx - (xm + b * (yy - ym))
    var = max(float((res**2).sum()) / max(n - 2, 1), float(np.mean(ss**2)))
    sb = math.sqrt(var / syy) if syy > 0 else math.inf
    lo, hi = float(yy.min()), float(yy.max())
    yr = min(max(y_ref, lo), hi)
    sigma = math.sqrt(var / n + ((yr - ym) * sb) ** 2 + common_sigma_m**2)
    yaw = math.atan(-b)
    return EdgeLine(
        x_m=xm + b * (yr - ym), y_m=yr, yaw_rad=yaw, sigma_m=sigma * math.cos(yaw),
        yaw_sigma_rad=sb / (1 + b * b), y_range_m=(lo, hi), rows=n, occluded=occluded,
    )  # fmt: skip


def _edges(g: _Grid, labels, terraces: dict, cfg: FeatureConfig) -> list[dict]:
    """Per terrace pair met in enough rows: its edge line, rise and σ."""
    pairs: dict[tuple[int, int], list] = {}
    for a, b, y, x, s, oc, ct, ca in _transitions(g, labels, terraces, cfg):
        pairs.setdefault((a, b), []).append((y, x, s, oc, ct, ca))
    out = []
    for (a, b), rows in pairs.items():
        if len(rows) < cfg.min_edge_rows:
            continue
        y, x, s, oc, ct, ca = (np.array(v) for v in zip(*rows, strict=True))
        occluded = bool(oc.mean() > 0.5)
        # where the shadow begins inside the last cell seen: the same guess in every row, or
        # the counts' ratio (its error common to the rows too: the density's trend)
        counted = occluded and bool(ct[oc].mean() > 0.5)
        part_sigma = cfg.shadow_count_sigma if counted else cfg.shadow_cell_sigma
        common = g.cell * part_sigma if occluded else 0.0
        if ca.mean() > 0.5:  # moved here with the previous stride's cells
            common = math.hypot(common, cfg.carried_edge_sigma_m)
        line = _fit_line(y, x, s, occluded, common_sigma_m=common)
        ta, tb = terraces[a], terraces[b]
        tilt = cfg.stride_tilt_sigma_rad * abs(_centre_x(g, tb) - _centre_x(g, ta))
        out.append({
            "a": a, "b": b, "line": line, "rise": tb["h"] - ta["h"],
            "rise_sigma": math.sqrt(ta["ind"] ** 2 + tb["ind"] ** 2
                                    + (ta["corr"] - tb["corr"]) ** 2 + tilt**2),
        })  # fmt: skip
    out.sort(key=lambda e: e["line"].x_m)
    return out


def _ramps(g: _Grid, sloped, labels, terraces: dict, cfg: FeatureConfig) -> list[Ramp]:
    """One plane per component of sloped cells; its start line on the terrace it is entered
    from (the adjacent terrace nearest the heel)."""
    from scipy import ndimage

    comp, n = ndimage.label(sloped)
    out = []
    for k in range(1, n + 1):
        i, j = np.nonzero(comp == k)
        if i.size < cfg.min_ramp_cells:
            continue
        x, y, z = g.x_of(i), g.y_of(j), g.h[i, j]
        w = 1.0 / np.maximum(g.var[i, j], 1e-12)
        xm, ym = float(np.average(x, weights=w)), float(np.average(y, weights=w))
        a = np.column_stack([np.ones_like(x), x - xm, y - ym])
        normal = a.T @ (a * w[:, None])
        if np.linalg.cond(normal) > 1e12:
            continue  # cells along one line: no plane
        coef = np.linalg.solve(normal, a.T @ (w * z))
        res = z - a @ coef
        dof = max(i.size - 3, 1)
        s2 = float((w * res**2).sum() / dof)
        cov = np.linalg.inv(normal) * s2
        gx, gy = float(coef[1]), float(coef[2])
        grad = math.hypot(gx, gy)
        along = ((x - xm) * gx + (y - ym) * gy) / max(grad, 1e-12)
        if grad < math.tan(math.radians(cfg.ramp_min_deg)) or np.ptp(along) < cfg.min_ramp_length_m:
            continue  # the flanks of an edge, not a ramp
        jac = np.array([gx, gy]) / max(grad, 1e-12)
        # a pose's tilt tilts the whole plane: the pose part of the cells' σ (correlated, it
        # does not average) changes along the slope by about that tilt's σ per metre
        c = g.corr[i, j]
        tilt = abs(float(np.polyfit(along, c, 1)[0])) if np.ptp(c) > 0 else 0.0
        slope_sigma = math.hypot(math.sqrt(float(jac @ cov[1:, 1:] @ jac)), tilt) / (
            1 + grad * grad
        )
        perp = np.array([-gy, gx]) / max(grad * grad, 1e-12)
        yaw_sigma = math.sqrt(max(float(perp @ cov[1:, 1:] @ perp), 0.0))
        start = _ramp_start(g, comp == k, labels, terraces, coef, (xm, ym), cov)
        out.append(
            Ramp(
                slope_rad=math.atan(grad),
                slope_sigma_rad=slope_sigma,
                uphill_yaw_rad=math.atan2(gy, gx),
                uphill_yaw_sigma_rad=yaw_sigma,
                start=start,
                n_cells=int(i.size),
                rms_m=float(np.sqrt(np.mean(res**2))),
                x_range_m=(float(x.min() - g.cell / 2), float(x.max() + g.cell / 2)),
            )
        )
    return out


def _ramp_start(g: _Grid, mask, labels, terraces: dict, coef, centre, cov) -> EdgeLine | None:
    from scipy import ndimage

    ring = ndimage.binary_dilation(mask, iterations=4) & ~mask
    c, gx, gy = (float(v) for v in coef)
    if abs(gx) < 1e-6:
        return None
    xm, ym = centre
    # the terrace the ramp is entered from lies before it along x: a terrace met only beyond
    # it (the landing at its top, the ramp's start out of view) gives no start line
    near = [t for t in np.unique(labels[ring]) if t in terraces
            and float(np.mean(g.x_of(np.nonzero(ring & (labels == t))[0]))) < xm]  # fmt: skip
    if not near:
        return None
    t = min(near, key=lambda t: terraces[t]["i"][0])
    j = np.nonzero(mask)[1]
    lo, hi = float(g.y_of(j.min())), float(g.y_of(j.max()))
    yr = min(max(0.0, lo), hi)
    h0 = terraces[t]["h"]
    x = xm + (h0 - c - gy * (yr - ym)) / gx
    # σ of the line's position from the plane's offset and the terrace height
    var_c = float(cov[0, 0]) + terraces[t]["ind"] ** 2
    b = -gy / gx
    return EdgeLine(
        x_m=float(x), y_m=yr, yaw_rad=math.atan(-b), sigma_m=math.sqrt(var_c) / math.hypot(gx, gy),
        yaw_sigma_rad=float("nan"), y_range_m=(lo, hi), rows=int(np.unique(j).size),
    )  # fmt: skip

"""The feature extraction of :mod:`graph_slam.terrain.features.model` (the steps of its docstring)."""

from __future__ import annotations

import math

import numba
import numpy as np

from graph_slam.errors import MappingError
from graph_slam.terrain.features import kernels, ramp_kernels
from graph_slam.terrain.features.config import FeatureConfig
from graph_slam.terrain.features.edges import edges_of
from graph_slam.terrain.features.kinds import boxes_of, chains_of
from graph_slam.terrain.features.model import EdgeLine, Ramp, TerrainFeatures, _Grid

_DEFAULT = FeatureConfig()


def features_of_view(view, config: FeatureConfig | None = None, source: str = "online"):
    """The features of a :class:`~graph_slam.terrain.grid.view.TerrainView` (online or re-fused)."""
    cfg = config or _DEFAULT
    s, shape = view.sums, view.shape
    h, var = view.height_m, view.variance_m2
    corr, noisy, known = kernels.view_cells(
        h, var, s.a.reshape(shape), s.b.reshape(shape), s.w.reshape(shape),
        cfg.max_noise_sigma_m,
    )  # fmt: skip
    cnt = np.asarray(view.count, dtype=np.float64)
    x0, y0 = (float(v) for v in view.origin_xy_m)
    g = _Grid(h, var, corr, x0, y0, view.cell_m, noisy, cnt, known)
    return _features(g, cfg, float(view.t_s), view.stride_index, source)


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
    return _features(g, cfg, float(t_s), stride_index, source)


def _features(g: _Grid, cfg: FeatureConfig, t_s: float, stride_index: int, source: str):
    out = TerrainFeatures(stride_index, t_s, source)
    if g.known.sum() < cfg.min_window_cells:
        return out
    level, sloped = _local_planes(g, cfg)
    labels, terraces, heights = _terraces(g, level, cfg)
    edges = edges_of(g, labels, heights, terraces, cfg)
    boxes, used = boxes_of(edges, terraces, cfg)
    rest = [e for k, e in enumerate(edges) if k not in used]
    stairs, curbs, parts = chains_of(rest, g, labels, terraces, cfg, heights)
    boxes += parts
    ramps = _ramps(g, sloped, labels, terraces, cfg)
    return TerrainFeatures(
        stride_index, t_s, source, tuple(stairs), tuple(ramps), tuple(curbs), tuple(boxes)
    )


@numba.njit(cache=True, nogil=True)
def _box(table, a0, a1, b0, b1):  # pragma: no cover - compiled
    """The sum over cells [a0, a1) × [b0, b1) of a summed-area table."""
    return table[a1, b1] - table[a0, b1] - table[a1, b0] + table[a0, b0]


@numba.njit(cache=True, nogil=True)
def _moment_tables(known):  # pragma: no cover - compiled
    """Summed-area tables of the known cells' count, a, b, a², ab and b² (integers: exact)."""
    nx, ny = known.shape
    t = np.zeros((6, nx + 1, ny + 1), np.int64)
    for a in range(nx):
        r = np.zeros(6, np.int64)
        for b in range(ny):
            if known[a, b]:
                r[0] += 1
                r[1] += a
                r[2] += b
                r[3] += a * a
                r[4] += a * b
                r[5] += b * b
            for m in range(6):
                t[m, a + 1, b + 1] = t[m, a, b + 1] + r[m]
    return t


@numba.njit(cache=True, nogil=True)
def _plane_kernel(h, known, half, min_cells, cell, level_max, ramp_min, ramp_max, rms_max):
    """Per known cell: the least-squares plane over its window's known cells (height per
    cell: slope over ``cell`` is its tan), and whether it is level (slope under
    ``level_max``) or sloped (between ``ramp_min`` and ``ramp_max``) with an RMS residual
    under ``rms_max``; neither where the window holds fewer than ``min_cells``. The window's
    cell offsets' moments are whole numbers, taken from summed-area tables (exact); the
    heights' sums run over the window in order (a window all known: without testing each
    cell)."""
    nx, ny = h.shape
    t = _moment_tables(known)
    level = np.zeros((nx, ny), dtype=np.bool_)
    sloped = np.zeros((nx, ny), dtype=np.bool_)
    for i in range(nx):
        a0, a1 = max(i - half, 0), min(i + half + 1, nx)
        for j in range(ny):
            if not known[i, j]:
                continue
            b0, b1 = max(j - half, 0), min(j + half + 1, ny)
            k = _box(t[0], a0, a1, b0, b1)
            n = float(k)
            if n < min_cells:
                continue
            sa, sb = _box(t[1], a0, a1, b0, b1), _box(t[2], a0, a1, b0, b1)
            sx, sy = float(sa - i * k), float(sb - j * k)
            sxx = float(_box(t[3], a0, a1, b0, b1) - 2 * i * sa + i * i * k)
            sxy = float(_box(t[4], a0, a1, b0, b1) - i * sb - j * sa + i * j * k)
            syy = float(_box(t[5], a0, a1, b0, b1) - 2 * j * sb + j * j * k)
            z0 = h[i, j]
            sz = sxz = syz = szz = 0.0
            if half == 2 and k == 25:  # the default window, all known: unrolled, no test
                for da in range(-2, 3):
                    x = float(da)
                    for db in range(-2, 3):
                        z = h[i + da, j + db] - z0
                        sz += z
                        sxz += x * z
                        syz += db * z
                        szz += z * z
            else:
                for a in range(a0, a1):
                    x = float(a - i)
                    for b in range(b0, b1):
                        if known[a, b]:
                            z = h[a, b] - z0
                            sz += z
                            sxz += x * z
                            syz += (b - j) * z
                            szz += z * z
            mx, my, mz = sx / n, sy / n, sz / n
            cxx, cxy, cyy = sxx / n - mx * mx, sxy / n - mx * my, syy / n - my * my
            cxz, cyz, czz = sxz / n - mx * mz, syz / n - my * mz, szz / n - mz * mz
            det = cxx * cyy - cxy * cxy
            if det <= 1e-9:
                continue
            gx = (cyy * cxz - cxy * cyz) / det
            gy = (cxx * cyz - cxy * cxz) / det
            slope = np.sqrt(gx * gx + gy * gy) / cell
            rms = np.sqrt(max(czz - gx * cxz - gy * cyz, 0.0))
            if rms < rms_max:
                level[i, j] = slope < level_max
                sloped[i, j] = slope >= ramp_min and slope <= ramp_max
    return level, sloped


def _local_planes(g: _Grid, cfg: FeatureConfig) -> tuple[np.ndarray, np.ndarray]:
    """Per cell: whether its local plane (over its window, enough known cells) is level, and
    whether it is sloped as a ramp's."""
    tan = [math.tan(math.radians(d)) for d in (cfg.level_max_deg, cfg.ramp_min_deg,
                                               cfg.ramp_max_deg)]  # fmt: skip
    return _plane_kernel(
        g.h, g.known, cfg.window_cells // 2, cfg.min_window_cells, g.cell, *tan, cfg.fit_rms_max_m
    )


def _terraces(g: _Grid, level: np.ndarray, cfg: FeatureConfig):
    """Components of level cells with ``min_terrace_cells``, and per component its height,
    σ parts, extent and ``x``, where along x its height lies (its cells' inverse-variance mean
    x: a tilt of the frame about y moves the height by the tilt times that x); and per label
    the terrace's height. Each terrace is grown by up to
    ``grow_cells`` cells (4-neighbours) into the known cells within ``grow_tol_m`` of its
    height: the cells by an edge are not level (their window holds the step) but those still
    on the surface are the terrace's, so that it ends at the edge (its height stays that of
    its level cells)."""
    labels, sizes, height, ind, corr, keep, ext, centre = kernels.terraces(
        level, g.known, g.h, g.var, g.corr, cfg.min_terrace_cells, cfg.grow_cells, cfg.grow_tol_m
    )
    out = {}
    for k in np.flatnonzero(keep).tolist():
        i0, i1, j0, j1 = ext[k - 1].tolist()
        out[k] = {
            "h": float(height[k]), "ind": float(ind[k]), "corr": float(corr[k]),
            "i": (i0, i1), "j": (j0, j1), "n": int(sizes[k]),
            "x": float(g.x0 + (centre[k] + 0.5) * g.cell),
        }  # fmt: skip
    return labels, out, height


def _ramps(g: _Grid, sloped, labels, terraces: dict, cfg: FeatureConfig) -> list[Ramp]:
    """One plane per component of sloped cells; its start line on the terrace it is entered
    from (the adjacent terrace nearest the heel)."""
    comp, ks, starts, ci, cj = ramp_kernels.big_components(sloped, cfg.min_ramp_cells)
    min_grad = math.tan(math.radians(cfg.ramp_min_deg))
    out = []
    for q, k in enumerate(ks):
        i, j = ci[starts[q] : starts[q + 1]], cj[starts[q] : starts[q + 1]]
        status, xm, ym, coef, cov, tilt, rms, x_lo, x_hi = ramp_kernels.ramp_plane(
            i, j, g.h, g.var, g.corr, g.x0, g.y0, g.cell, min_grad, cfg.min_ramp_length_m
        )
        if status < 2:
            continue  # cells along one line (no plane), or the flanks of an edge (no ramp)
        gx, gy = float(coef[1]), float(coef[2])
        grad = math.hypot(gx, gy)
        # a pose's tilt tilts the whole plane: the pose part of the cells' σ (correlated, it
        # does not average) changes along the slope by about that tilt's σ per metre (tilt)
        slope_sigma, yaw_sigma = ramp_kernels.slope_sigmas(gx, gy, cov, tilt)
        start = _ramp_start(g, comp, k, labels, terraces, coef, (xm, ym), cov)
        out.append(
            Ramp(
                slope_rad=math.atan(grad),
                slope_sigma_rad=float(slope_sigma),
                uphill_yaw_rad=math.atan2(gy, gx),
                uphill_yaw_sigma_rad=float(yaw_sigma),
                start=start,
                n_cells=int(i.size),
                rms_m=float(rms),
                x_range_m=(float(x_lo - g.cell / 2), float(x_hi + g.cell / 2)),
            )
        )
    return out


def _ramp_start(g: _Grid, comp, k, labels, terraces: dict, coef, centre, cov) -> EdgeLine | None:
    """The start line of ramp ``k`` of ``comp``: the plane's
    intersection with the terrace it is entered from (None: none seen before it)."""
    c, gx, gy = (float(v) for v in coef)
    if abs(gx) < 1e-6:
        return None
    xm, ym = centre
    # the labels within 4 cells (4-neighbour steps) of the ramp, their cells' mean x there
    found, mean_x, j_lo, j_hi, rows = ramp_kernels.ring_terraces(comp, k, labels, 4, g.x0, g.cell)
    # the terrace the ramp is entered from lies before it along x: a terrace met only beyond
    # it (the landing at its top, the ramp's start out of view) gives no start line
    near = [int(t) for t, mx in zip(found, mean_x, strict=True) if int(t) in terraces and mx < xm]
    if not near:
        return None
    t = min(near, key=lambda t: terraces[t]["i"][0])
    lo, hi = float(g.y_of(j_lo)), float(g.y_of(j_hi))
    yr = min(max(0.0, lo), hi)
    h0 = terraces[t]["h"]
    x = xm + (h0 - c - gy * (yr - ym)) / gx
    # σ of the line's position from the plane's offset and the terrace height
    var_c = float(cov[0, 0]) + terraces[t]["ind"] ** 2
    b = -gy / gx
    return EdgeLine(
        x_m=float(x), y_m=yr, yaw_rad=math.atan(-b), sigma_m=math.sqrt(var_c) / math.hypot(gx, gy),
        yaw_sigma_rad=float("nan"), y_range_m=(lo, hi), rows=int(rows),
    )  # fmt: skip

"""Step 3 of :mod:`graph_slam.terrain.features.model`: the edges across x between terraces
(each a dict: terraces ``a`` → ``b``, its ``line``, ``rise`` and ``rise_sigma``), from the rows
where two terraces meet (:func:`graph_slam.terrain.features.edge_kernels.transitions`) through a
robust line fit per terrace pair."""

from __future__ import annotations

import math

import numpy as np

from graph_slam.terrain.features import edge_kernels
from graph_slam.terrain.features.config import FeatureConfig
from graph_slam.terrain.features.model import EdgeLine, _Grid


def transitions(
    g: _Grid,
    labels: np.ndarray,
    height: np.ndarray,
    cfg: FeatureConfig,
    sparse_fraction: float | None = None,
):
    """Every pair of terraces met along a row (x) within the gap, rows in order: arrays of
    the labels ``a``, ``b``, the row's y, the edge's x and σ, and the occluded, counted
    (shadow part from the counts) and carried flags. ``height``: per label its terrace's
    height.

    The edge lies where the area between the two terraces says; the cells not seen between
    them (a shadow; beyond a drop, flying pixels) are the far surface's, and so are the cells
    past the last one mostly of the near surface before the first one not seen (flying pixels
    of the edge fill the shadow's first cells with heights in between: counted as fractions
    they put the edge up to a cell late); optionally, beyond a drop, the far surface's cells
    seen only from a few late viewpoints (``FeatureConfig.shadow_sparse_fraction``). Where a
    shadow begins inside the last cell seen:
    ``shadow_cell_seen``, or its points over the mean of the two cells before it
    (``FeatureConfig.shadow_from_counts``). Carried: both cells hold no point of this stride.
    ``sparse_fraction``: in place of ``cfg.shadow_sparse_fraction`` (:func:`sparse_spans`)."""
    if sparse_fraction is None:
        sparse_fraction = cfg.shadow_sparse_fraction
    has_count = g.count is not None
    count = g.count if has_count else np.zeros((1, 1))
    a, b, j, x, s, flags = edge_kernels.transitions(
        labels, height, g.h, g.var, g.noisy, count, has_count, cfg.max_gap_cells,
        cfg.min_rise_m, cfg.shadow_cell_seen, cfg.shadow_from_counts,
        float(cfg.shadow_count_min), sparse_fraction, g.x0, g.cell,
    )  # fmt: skip
    return a, b, g.y_of(j), x, s, flags


def sparse_spans(g: _Grid, labels, height: np.ndarray, cfg: FeatureConfig, rows) -> dict:
    """Per terrace pair (``a``, ``b``) beyond a drop: the span (m) between its edge's reading
    that takes the far cells seen only sparsely (``FeatureConfig.sparse_span_fraction`` of
    the near cells' count) as seen and the one that takes them as not seen, the rows' mean
    shift. ``rows``: :func:`transitions` with ``cfg`` (labels only pair the cells, so the
    second reading has the same rows)."""
    a, b, _, x = rows[0], rows[1], rows[2], rows[3]
    frac = cfg.sparse_span_fraction
    drop = height[b] < height[a]
    if g.count is None or frac <= cfg.shadow_sparse_fraction or not drop.any():
        return {}
    a2, b2, _, x2, _, _ = transitions(g, labels, height, cfg, sparse_fraction=frac)
    if a2.shape != a.shape or (a2 != a).any() or (b2 != b).any():
        return {}
    shift = x2 - x
    out = {}
    for la, lb in set(zip(a[drop].tolist(), b[drop].tolist(), strict=True)):
        sel = (a == la) & (b == lb)
        out[(la, lb)] = abs(float(shift[sel].mean()))
    return out


def fit_line(
    y: np.ndarray,
    x: np.ndarray,
    s: np.ndarray,
    occluded: bool,
    y_ref: float = 0.0,
    common_sigma_m: float = 0.0,
) -> EdgeLine:
    """x = x̄ + b (y - ȳ) through the rows (3σ outliers out), reported at ``y_ref`` clipped into
    the rows seen; ``common_sigma_m``: an error every row shares (it does not average out)."""
    fit = edge_kernels.fit_line(
        np.ascontiguousarray(y, np.float64), np.ascontiguousarray(x, np.float64),
        np.ascontiguousarray(s, np.float64),
    )  # fmt: skip
    return _line_of(fit, occluded, y_ref, common_sigma_m)


def _line_of(fit, occluded: bool, y_ref: float, common_sigma_m: float) -> EdgeLine:
    """The EdgeLine of a fit (:func:`graph_slam.terrain.features.edge_kernels.fit_line`)."""
    ym, xm, b, syy, var, n, lo, hi = (float(v) for v in fit)
    sb = math.sqrt(var / syy) if syy > 0 else math.inf
    yr = min(max(y_ref, lo), hi)
    sigma = math.sqrt(var / n + ((yr - ym) * sb) ** 2 + common_sigma_m**2)
    yaw = math.atan(-b)
    return EdgeLine(
        x_m=xm + b * (yr - ym), y_m=yr, yaw_rad=yaw, sigma_m=sigma * math.cos(yaw),
        yaw_sigma_rad=sb / (1 + b * b), y_range_m=(lo, hi), rows=int(n), occluded=occluded,
    )  # fmt: skip


def edges_of(g: _Grid, labels, height: np.ndarray, terraces: dict, cfg: FeatureConfig):
    """Per terrace pair met in at least ``min_edge_rows`` rows (pairs in the order first met):
    its edge line, rise and σ, sorted by the line's x. Where the shadow begins inside the
    last cell seen is the same guess in every row, or the counts' ratio (its error common to
    the rows too: the density's trend); an edge carried with the previous stride's cells
    moved with them; an edge seen face-on, where in its cell it lies (the face's points
    pull that cell to half the rise: ``edge_kernels.face_share``), common to the rows too.
    ``counted``: occluded, the shadow part from the counts; ``carried_m``, ``face_m``: the
    carried and face-on terms of its σ (0: none)."""
    a, b, y, x, s, flags = transitions(g, labels, height, cfg)
    if a.size == 0:
        return []
    spans = sparse_spans(g, labels, height, cfg, (a, b, y, x))
    pairs, fits = edge_kernels.edge_groups(a, b, y, x, s, flags, len(height), cfg.min_edge_rows)
    out = []
    for (la, lb, occluded, counted, carried), fit in zip(pairs, fits, strict=True):
        part_sigma = cfg.shadow_count_sigma if counted else cfg.shadow_cell_sigma
        common = g.cell * part_sigma if occluded else 0.0
        face_m = 0.0
        if not occluded and cfg.face_cell_sigma > 0 and g.count is not None:
            share = edge_kernels.face_share(
                g.count, a, b, la, lb, y, x, g.x0, g.y0, g.cell, float(cfg.shadow_count_min)
            )
            common = face_m = g.cell * cfg.face_cell_sigma * share
        carried_m = cfg.carried_edge_sigma_m if carried else 0.0
        common = math.hypot(common, carried_m)
        span = spans.get((int(la), int(lb)), 0.0)
        common = math.hypot(common, cfg.sparse_span_sigma * span)
        line = _line_of(fit, bool(occluded), 0.0, common)
        ta, tb = terraces[int(la)], terraces[int(lb)]
        tilt = cfg.stride_tilt_sigma_rad * abs(tb["x"] - ta["x"])
        out.append({
            "a": int(la), "b": int(lb), "line": line, "rise": tb["h"] - ta["h"],
            "counted": bool(occluded and counted), "carried_m": carried_m,
            "face_m": face_m,
            "rise_sigma": math.sqrt(ta["ind"] ** 2 + tb["ind"] ** 2
                                    + (ta["corr"] - tb["corr"]) ** 2 + tilt**2),
        })  # fmt: skip
    out.sort(key=lambda e: e["line"].x_m)
    return out

"""Step 4 of :mod:`graph_slam.terrain.features.model`: the edges of a grid (each a dict:
terraces ``a`` → ``b``, its ``line``, ``rise`` and ``rise_sigma``) sorted into boxes, stairs and
curbs."""

from __future__ import annotations

import math

import numpy as np

from graph_slam.terrain.features import edge_kernels
from graph_slam.terrain.features.config import FeatureConfig
from graph_slam.terrain.features.model import BoxFeature, Curb, EdgeLine, Stairs, Step, _Grid


def boxes_of(edges: list[dict], terraces: dict, cfg: FeatureConfig):
    """A terrace entered by a rise and left by a drop to the same level: a box."""
    boxes, used = [], set()
    for k, up in enumerate(edges):
        if up["rise"] <= 0:
            continue
        for m, down in enumerate(edges):
            if m in used or down["a"] != up["b"] or down["rise"] >= 0:
                continue
            base = (terraces[up["a"]]["h"], terraces[down["b"]]["h"])
            if abs(base[0] - base[1]) > cfg.box_same_level_m:
                continue
            top = terraces[up["b"]]
            floor_ind = math.hypot(terraces[up["a"]]["ind"], terraces[down["b"]]["ind"]) / 2
            floor_corr = (terraces[up["a"]]["corr"] + terraces[down["b"]]["corr"]) / 2
            # a tilt of the frame moves the top and the floor by it times where their heights
            # lie along x (the floor's, the mean of its two sides')
            floor_x = (terraces[up["a"]]["x"] + terraces[down["b"]]["x"]) / 2
            tilt = cfg.stride_tilt_sigma_rad * abs(top["x"] - floor_x)
            lead, trail = up["line"], down["line"]
            boxes.append(
                BoxFeature(
                    height_m=top["h"] - (base[0] + base[1]) / 2,
                    height_sigma_m=math.sqrt(
                        top["ind"] ** 2 + floor_ind**2 + (top["corr"] - floor_corr) ** 2 + tilt**2
                    ),
                    leading=lead,
                    depth_m=trail.x_at(lead.y_m) - lead.x_m,
                    depth_sigma_m=math.hypot(lead.sigma_m, trail.sigma_m),
                    floor_height_m=(base[0] + base[1]) / 2,
                )
            )
            used.update((k, m))
            used.update(_same_box(edges, up["b"], boxes[-1].floor_height_m, terraces, cfg))
            break
    return boxes, used


def _same_box(edges: list[dict], top: int, floor_m: float, terraces: dict, cfg: FeatureConfig):
    """The other edges between a box's top and its floor level (the floor around a box falls
    apart into several terraces where cells go unseen): parts of that box, not curbs."""
    for n, e in enumerate(edges):
        other = e["a"] if e["b"] == top else e["b"] if e["a"] == top else None
        if other is not None and abs(terraces[other]["h"] - floor_m) <= cfg.box_same_level_m:
            yield n


def _far_extent(g: _Grid, labels, terrace: int, line: EdgeLine, heights, cfg: FeatureConfig):
    """How far the terrace runs on beyond the edge (m, along x in the edge's rows); where that
    is short of a curb's upper surface, followed across cells not seen (up to
    ``max_gap_cells + 1``) into terraces at its height (within ``grow_tol_m``): beyond a drop
    the lower surface's first cells lie in the edge's shadow for the views from the top (the
    cells carried from the previous stride end before it and the new views begin after it)."""
    lo, hi = line.y_range_m
    x_far, y_mid = edge_kernels.far_end(labels, terrace, lo - 1e-9, hi + 1e-9, g.x0, g.y0, g.cell)
    if not math.isfinite(x_far):
        return 0.0
    run_on = float(x_far - line.x_at(float(y_mid)))
    if run_on < cfg.curb_min_depth_m:
        j0 = max(math.floor((lo - g.y0) / g.cell), 0)
        j1 = min(math.floor((hi - g.y0) / g.cell), g.h.shape[1] - 1)
        x_far = edge_kernels.far_end_bridged(
            labels, terrace, heights, g.known, j0, j1, cfg.max_gap_cells + 1, cfg.grow_tol_m,
            g.x0, g.cell,
        )  # fmt: skip
        run_on = max(run_on, float(x_far - line.x_at(float(y_mid))))
    return run_on


def _further_rise(g: _Grid, labels, edge: dict, terraces: dict, cfg: FeatureConfig) -> bool:
    """Whether the short terrace beyond a single edge is a tread: in at least
    ``min_edge_rows`` of the edge's rows, a known cell within ``max_gap_cells + 1`` past the
    terrace's far end lies a further ``min_rise_m`` on in the edge's direction (up beyond an
    up-step, down beyond a down-step). A box top ends in its shadow or a drop back to the floor."""
    b, line = edge["b"], edge["line"]
    sign = math.copysign(1.0, edge["rise"])
    lo, hi = line.y_range_m
    j0 = max(math.floor((lo - g.y0) / g.cell), 0)
    j1 = min(math.floor((hi - g.y0) / g.cell), g.h.shape[1] - 1)
    look = cfg.max_gap_cells + 1
    rows = edge_kernels.rows_rising_on(
        labels, b, g.h, j0, j1, look, sign, terraces[b]["h"], cfg.min_rise_m
    )
    return rows >= cfg.min_edge_rows


def _ends_unseen(g: _Grid, labels, edge: dict, cfg: FeatureConfig) -> bool:
    """Whether the terrace beyond a single edge runs into cells not seen (no known cell within
    ``max_gap_cells + 1`` past its far end, or the grid's end) in at least half of the edge's
    rows where it is seen: its far side is in the shadow or out of view."""
    b, (lo, hi) = edge["b"], edge["line"].y_range_m
    j0 = max(math.floor((lo - g.y0) / g.cell), 0)
    j1 = min(math.floor((hi - g.y0) / g.cell), g.h.shape[1] - 1)
    look = cfg.max_gap_cells + 1
    rows = unseen = 0
    for j in range(j0, j1 + 1):
        ii = np.flatnonzero(labels[:, j] == b)
        if ii.size == 0:
            continue
        rows += 1
        unseen += not g.known[ii[-1] + 1 : ii[-1] + 1 + look, j].any()
    return rows > 0 and 2 * unseen >= rows


def _part_box(e: dict, terraces: dict, depth_seen_m: float) -> BoxFeature:
    """A box seen in part (``BoxFeature.far_seen`` False): its leading edge and height, the
    part of its top seen."""
    return BoxFeature(
        height_m=e["rise"],
        height_sigma_m=e["rise_sigma"],
        leading=e["line"],
        depth_m=depth_seen_m,
        depth_sigma_m=float("nan"),
        floor_height_m=terraces[e["a"]]["h"],
        far_seen=False,
    )


def chains_of(edges: list[dict], g: _Grid, labels, terraces: dict, cfg: FeatureConfig, heights):
    """Edges linked through shared terraces with the same sign of rise: stairs or a curb; a
    single rise whose short top runs into cells not seen: a box seen in part. ``heights``: per
    label its terrace's height."""
    starts = {e["a"]: e for e in edges}
    ends = {e["b"] for e in edges}
    stairs, curbs, parts, seen = [], [], [], set()
    for e in edges:
        if id(e) in seen:
            continue
        if e["a"] in ends and any(
            x["b"] == e["a"] and np.sign(x["rise"]) == np.sign(e["rise"]) for x in edges
        ):
            continue  # not the chain's first edge
        chain = [e]
        while (
            (nxt := starts.get(chain[-1]["b"])) is not None
            and np.sign(nxt["rise"]) == np.sign(e["rise"])
            and id(nxt) not in seen
            and nxt not in chain
        ):
            chain.append(nxt)
        seen.update(id(c) for c in chain)
        if len(chain) == 1:
            run_on = _far_extent(g, labels, e["b"], e["line"], heights, cfg)
            if run_on >= cfg.curb_min_depth_m:
                curbs.append(Curb(e["rise"], e["rise_sigma"], e["line"], terraces[e["a"]]["h"]))
                continue
            if not _further_rise(g, labels, e, terraces, cfg):
                # one edge and a short top: not a flight; a box seen in part when its top
                # runs into cells not seen
                if e["rise"] > 0 and _ends_unseen(g, labels, e, cfg):
                    parts.append(_part_box(e, terraces, run_on))
                continue
        steps = []
        for k, c in enumerate(chain):
            tread, tread_sigma = float("nan"), float("nan")
            if k + 1 < len(chain):
                both = c.get("counted", False) and chain[k + 1].get("counted", False)
                rho = cfg.shadow_count_common if both else 0.0
                tread, tread_sigma = _tread(
                    c["line"], chain[k + 1]["line"], rho, _common_m2(c, chain[k + 1], g.cell)
                )
            steps.append(
                Step(
                    rise_m=c["rise"],
                    rise_sigma_m=c["rise_sigma"],
                    nosing=c["line"],
                    tread_m=tread,
                    tread_sigma_m=tread_sigma,
                    lower_height_m=min(terraces[c["a"]]["h"], terraces[c["b"]]["h"]),
                    upper_height_m=max(terraces[c["a"]]["h"], terraces[c["b"]]["h"]),
                )
            )
        stairs.append(Stairs(tuple(steps)))
    return stairs, curbs, parts


def _common_m2(here: dict, nxt: dict, cell_m: float) -> float:
    """The covariance (m²) of two nosings' errors through what they share: the carry's shift
    (two edges carried by one relative stride pose move alike: the product of their carried
    terms) and, both seen face-on, where each lies in its cell (:func:`_face_correlation`)."""
    cov = here.get("carried_m", 0.0) * nxt.get("carried_m", 0.0)
    fa, fb = here.get("face_m", 0.0), nxt.get("face_m", 0.0)
    if fa > 0 and fb > 0:
        la, lb = here["line"], nxt["line"]
        gap = abs(lb.x_at(la.y_m) - la.x_m) / cell_m
        rest = max(la.sigma_m**2 - fa**2, 0.0) + max(lb.sigma_m**2 - fb**2, 0.0)
        cov += fa * fb * _face_correlation(gap, math.sqrt(rest) / cell_m)
    return cov


def _face_correlation(gap_cells: float, sigma_cells: float) -> float:
    """The correlation of two face-on edges' face terms, ``gap_cells`` apart (measured, with σ
    ``sigma_cells``). Each is off by r (1/2 - f) of a cell, f where it lies in its cell
    (uniform); the second lies at f + δ (mod 1), δ the gap's fractional part, so the two
    correlate 1 - 6 h(δ), h(δ) = δ (1 - δ) (the variance of their difference over r² is
    h(δ)): fully at a whole number of cells (the same place in every cell: it cancels in the
    tread), -1/2 at half a cell. δ is known to the gap's σ: h averaged over a normal δ, from
    its Fourier series h = 1/6 - Σ cos(2πkδ) / (πk)², each term damped by exp(-2(πkσ)²)."""
    delta = gap_cells - math.floor(gap_cells)
    if sigma_cells < 0.02:  # the series' 64 terms would be cut short; blurring under 0.02
        return 1.0 - 6.0 * delta * (1.0 - delta)
    h = 1.0 / 6.0
    for k in range(1, 65):  # the terms past 64 are damped by under exp(-32)
        damp = math.exp(-2.0 * (math.pi * k * sigma_cells) ** 2)
        h -= math.cos(2.0 * math.pi * k * delta) * damp / (math.pi * k) ** 2
    return 1.0 - 6.0 * h


def _tread(
    here: EdgeLine, nxt: EdgeLine, rho: float = 0.0, common_m2: float = 0.0
) -> tuple[float, float]:
    """The tread from one nosing to the next along the first's normal and its σ, taken where
    both were seen, nearest the first's point (its y clipped into the overlap of their y
    ranges; its own y when they do not overlap): each line's σ there is its σ at its point
    and its yaw σ over the distance from it. Taken at the first's point, a next nosing seen
    in 4 rows at the grid's side was extrapolated half a metre by its poorly known yaw: 157 mm
    off with σ 12 mm on the simulated stairs down. ``rho``: the correlation of the two
    nosings' errors (their common part cancels in the difference); ``common_m2``: a further
    covariance of the two (m², the variance of an error both share: the carry's shift of two
    carried nosings)."""
    lo, hi = max(here.y_range_m[0], nxt.y_range_m[0]), min(here.y_range_m[1], nxt.y_range_m[1])
    y = min(max(here.y_m, lo), hi) if lo <= hi else here.y_m
    tread = (nxt.x_at(y) - here.x_at(y)) * math.cos(here.yaw_rad)
    sa, sb = _sigma_at(here, y), _sigma_at(nxt, y)
    var = sa * sa + sb * sb - 2.0 * (rho * sa * sb + common_m2)
    return tread, math.sqrt(max(var, 0.0))


def _sigma_at(line: EdgeLine, y_m: float) -> float:
    """σ of a line's position along x at ``y_m``: its σ at its point and its yaw σ over the
    lever ``|y - y_m| / cos²(yaw)`` (the derivative of ``x_at`` by the yaw)."""
    lever = abs(y_m - line.y_m) / math.cos(line.yaw_rad) ** 2
    return math.hypot(line.sigma_m, line.yaw_sigma_rad * lever)

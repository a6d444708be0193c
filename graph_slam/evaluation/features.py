"""Terrain features against the scene's truth: stairs, ramps, curbs and boxes (stride frame).

:func:`feature_truth_from_scene` turns a scene's objects into the features a perfect grid
would give (a :class:`~graph_slam.terrain.features.model.TerrainFeatures` with σ 0) in a stride's
frame: ``box`` objects are boxes; the ``step`` objects of a flight (``NAME.stepK``: step K a
box of height K·rise, its near face the K-th nosing) are stairs; a ``ramp`` (a wedge rising
along its x) is a ramp whose start line is its low edge; ``curb`` objects (a block of the
given height running on across the walk; a scene's kind may add them) are curbs. A scene
with walkable surfaces (flights down, ramps down, platforms and curbs by role) gives its truth
from those instead (:mod:`graph_slam.evaluation.surface_features`). It is the one place a
scene's geometry becomes feature truth: new scene kinds plug in here.

:func:`score_features` matches each measured feature to the truth (a nosing or an edge to the
nearest true one within ``match_m`` along x, in its y range; a ramp to the true ramp it
overlaps; a box to the true box whose footprint holds its leading edge's point) and gives the
errors and the errors over σ; :func:`summarise_scores` reduces them to n, RMSE and the std of
error/σ per quantity.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from graph_slam.terrain.features.model import (
    BoxFeature,
    Curb,
    EdgeLine,
    Ramp,
    Stairs,
    Step,
    TerrainFeatures,
)

QUANTITIES = {
    "steps": ("rise_m", "nosing_m", "tread_m"),
    "ramps": ("slope_rad", "start_m"),
    "curbs": ("height_m", "edge_m"),
    "boxes": ("height_m", "leading_m", "depth_m"),
}


def _edge(x: float, y: float, yaw: float, y_range: tuple[float, float]) -> EdgeLine:
    return EdgeLine(x, y, yaw, 0.0, 0.0, y_range, 0, False)


def _in_stride(stride_T_world: np.ndarray, world_T_object: np.ndarray):
    """Object centre (x, y, z) and yaw in the stride frame."""
    t = stride_T_world @ world_T_object
    return t[:3, 3], math.atan2(t[1, 0], t[0, 0])


def _near_face(centre, yaw: float, depth: float, width: float):
    """The object's near face (its −x side): point at the face's middle, its y range."""
    c, s = math.cos(yaw), math.sin(yaw)
    x, y = centre[0] - c * depth / 2, centre[1] - s * depth / 2
    return x, y, (y - width / 2, y + width / 2)


def feature_truth_from_scene(scene, world_T_stride: np.ndarray) -> TerrainFeatures:
    """The scene's features in the stride frame (see the module docstring); from its walkable
    surfaces when it has them (graph_slam.evaluation.surface_features)."""
    from graph_slam.evaluation.surface_features import features_from_surfaces, scene_surfaces

    surfaces = scene_surfaces(scene)
    if surfaces is not None:
        return features_from_surfaces(surfaces, world_T_stride)
    stride_T_world = np.linalg.inv(np.asarray(world_T_stride, dtype=np.float64))
    floor_z = float(stride_T_world[2, 3])  # the world floor (z = 0) in the stride frame
    boxes, ramps, curbs, flights = [], [], [], {}
    for obj in scene.objects:
        size = np.asarray(obj.size_m, dtype=np.float64)
        centre, yaw = _in_stride(stride_T_world, obj.world_T_object)
        x, y, yr = _near_face(centre, yaw, size[0], size[1])
        if obj.kind == "box":
            boxes.append(BoxFeature(size[2], 0.0, _edge(x, y, yaw, yr), size[0], 0.0, floor_z))
        elif obj.kind == "step":
            flights.setdefault(obj.name.split(".step")[0], []).append((x, y, yaw, yr, size))
        elif obj.kind == "ramp":
            ramps.append(
                Ramp(
                    math.atan2(size[2], size[0]),
                    0.0,
                    yaw,
                    0.0,
                    _edge(x, y, yaw, yr),
                    0,
                    0.0,
                    (x, x + size[0] * math.cos(yaw)),
                )
            )
        elif obj.kind == "curb":
            curbs.append(Curb(size[2], 0.0, _edge(x, y, yaw, yr), floor_z))
    stairs = []
    for steps in flights.values():
        steps.sort(key=lambda s: s[0])
        out = []
        for k, (x, y, yaw, yr, size) in enumerate(steps):
            below = floor_z + (steps[k - 1][4][2] if k else 0.0)
            rise = floor_z + size[2] - below
            tread = steps[k + 1][0] - x if k + 1 < len(steps) else float("nan")
            out.append(Step(rise, 0.0, _edge(x, y, yaw, yr), tread, 0.0, below, below + rise))
        stairs.append(Stairs(tuple(out)))
    return TerrainFeatures(source="truth", stairs=tuple(stairs), ramps=tuple(ramps),
                           curbs=tuple(curbs), boxes=tuple(boxes))  # fmt: skip


def _nearest_edge(line: EdgeLine, candidates, match_m: float):
    """The candidate (edge, payload) nearest ``line`` along x at its y, within ``match_m``."""
    best, dist = None, match_m
    for edge, payload in candidates:
        lo, hi = edge.y_range_m
        if not lo - 0.02 <= line.y_m <= hi + 0.02:
            continue
        d = abs(edge.x_at(line.y_m) - line.x_m)
        if d <= dist:
            best, dist = (edge, payload), d
    return best


def _err(value: float, truth: float, sigma: float) -> tuple[float, float]:
    e = value - truth
    return e, (e / sigma if sigma > 0 and math.isfinite(sigma) else float("nan"))


def score_features(
    measured: TerrainFeatures, truth: TerrainFeatures, match_m: float = 0.05
) -> dict[str, list[dict]]:
    """Per kind, one row per measured feature matched to the truth: per quantity its error
    and error/σ (``{quantity: (error, normalised)}``), and ``x_m`` (where along the walk)."""
    out: dict[str, list[dict]] = {k: [] for k in QUANTITIES}
    true_steps = [(s.nosing, s) for st in truth.stairs for s in st.steps]
    for st in measured.stairs:
        for step in st.steps:
            hit = _nearest_edge(step.nosing, true_steps, match_m)
            if hit is None:
                continue
            edge, t = hit
            row = {
                "x_m": step.nosing.x_m,
                "rise_m": _err(step.rise_m, t.rise_m, step.rise_sigma_m),
                "nosing_m": _err(step.nosing.x_m, edge.x_at(step.nosing.y_m), step.nosing.sigma_m),
            }
            if math.isfinite(step.tread_m) and math.isfinite(t.tread_m):
                row["tread_m"] = _err(step.tread_m, t.tread_m, step.tread_sigma_m)
            out["steps"].append(row)
    for c in measured.curbs:
        hit = _nearest_edge(c.edge, [(t.edge, t) for t in truth.curbs], match_m)
        if hit is not None:
            edge, t = hit
            out["curbs"].append({
                "x_m": c.edge.x_m,
                "height_m": _err(c.height_m, t.height_m, c.height_sigma_m),
                "edge_m": _err(c.edge.x_m, edge.x_at(c.edge.y_m), c.edge.sigma_m),
            })  # fmt: skip
    for r in measured.ramps:
        true = [t for t in truth.ramps if t.near_x_m < r.far_x_m and r.near_x_m < t.far_x_m]
        if not true:
            continue
        t = true[0]
        row = {"x_m": r.near_x_m, "slope_rad": _err(r.slope_rad, t.slope_rad, r.slope_sigma_rad)}
        if r.start is not None and t.start is not None:
            row["start_m"] = _err(r.start.x_m, t.start.x_at(r.start.y_m), r.start.sigma_m)
        out["ramps"].append(row)
    for b in measured.boxes:
        hit = _nearest_edge(b.leading, [(t.leading, t) for t in truth.boxes], match_m)
        if hit is not None:
            edge, t = hit
            row = {
                "x_m": b.leading.x_m,
                "height_m": _err(b.height_m, t.height_m, b.height_sigma_m),
                "leading_m": _err(b.leading.x_m, edge.x_at(b.leading.y_m), b.leading.sigma_m),
            }
            if b.far_seen:  # a box seen in part has no depth, only the part of its top seen
                row["depth_m"] = _err(b.depth_m, t.depth_m, b.depth_sigma_m)
            out["boxes"].append(row)
    return out


def summarise_scores(scores: Sequence[dict[str, list[dict]]]) -> dict[str, dict]:
    """Per kind and quantity over many grids: n, RMSE, mean error (bias) and the std of the
    errors over σ (1 when the σ are right)."""
    out: dict[str, dict] = {}
    for kind, quantities in QUANTITIES.items():
        rows = [r for s in scores for r in s.get(kind, [])]
        out[kind] = {"matched": len(rows)}
        for q in quantities:
            pairs = np.array([r[q] for r in rows if q in r], dtype=np.float64).reshape(-1, 2)
            e, z = pairs[:, 0], pairs[:, 1][np.isfinite(pairs[:, 1])]
            out[kind][q] = {
                "n": int(e.size),
                "rmse": float(np.sqrt(np.mean(e**2))) if e.size else None,
                "bias": float(np.mean(e)) if e.size else None,
                "std_error_over_sigma": float(np.std(z, ddof=1)) if z.size > 1 else None,
            }
    return out


def scene_height_at(scene, world_T_stride: np.ndarray, xy_m: np.ndarray) -> np.ndarray:
    """The scene's surface height (stride z) at stride-frame (x, y): the floor, boxes and
    steps (their tops), ramps (their wedge, up or down when the scene's surfaces are known)."""
    from graph_slam.evaluation.surface_features import scene_surfaces

    stride_T_world = np.linalg.inv(np.asarray(world_T_stride, dtype=np.float64))
    world_T_stride = np.asarray(world_T_stride, dtype=np.float64)
    xy = np.asarray(xy_m, dtype=np.float64).reshape(-1, 2)
    world = np.column_stack([xy, np.zeros(len(xy)), np.ones(len(xy))]) @ world_T_stride.T
    surfaces = scene_surfaces(scene)
    if surfaces is not None:
        up = np.column_stack([world[:, :2], surfaces.height_at(world[:, 0], world[:, 1]),
                              np.ones(len(xy))])  # fmt: skip
        return (up @ stride_T_world.T)[:, 2]
    h = np.zeros(len(xy))
    for obj in scene.objects:
        size = np.asarray(obj.size_m, dtype=np.float64)
        local = world @ np.linalg.inv(obj.world_T_object).T
        inside = (np.abs(local[:, 0]) <= size[0] / 2) & (np.abs(local[:, 1]) <= size[1] / 2)
        if obj.kind == "ramp":
            top = (local[:, 0] + size[0] / 2) / size[0] * size[2]
        else:
            top = np.full(len(xy), size[2])
        h = np.where(inside, np.maximum(h, top), h)
    up = np.column_stack([world[:, 0], world[:, 1], h, np.ones(len(xy))])
    return (up @ stride_T_world.T)[:, 2]


DEADLINE_TOLERANCE = {"step": 0.01, "curb": 0.01, "box": 0.01, "ramp": math.radians(1.0)}
"""How close a feature's value (rise, height; a ramp's slope) must be to the final one to count
as known; its edge must also be within ``DEADLINE_EDGE_M`` of the final edge."""
DEADLINE_EDGE_M = 0.02
DEADLINE_REACH_M = 0.2
"""How far beyond the rows it was seen in an online edge line may be followed to the final
edge's reported point."""


def feature_marks(features: TerrainFeatures) -> list[tuple[str, float, float, float]]:
    """(kind, edge x, edge y, value) of every feature: each step's nosing and rise, each
    curb's edge and height, each ramp's start and slope, each box's leading edge and height."""
    out = [("step", s.nosing.x_m, s.nosing.y_m, s.rise_m) for st in features.stairs
           for s in st.steps]  # fmt: skip
    out += [("curb", c.edge.x_m, c.edge.y_m, c.height_m) for c in features.curbs]
    out += [("ramp", r.near_x_m, 0.0 if r.start is None else r.start.y_m, r.slope_rad)
            for r in features.ramps]  # fmt: skip
    out += [("box", b.leading.x_m, b.leading.y_m, b.height_m) for b in features.boxes]
    return out


def _mark_lines(features: TerrainFeatures) -> list:
    """The edge line of each :func:`feature_marks` entry (None: a ramp without a start line),
    in the same order."""
    out = [s.nosing for st in features.stairs for s in st.steps]
    out += [c.edge for c in features.curbs]
    out += [r.start for r in features.ramps]
    out += [b.leading for b in features.boxes]
    return out


def _same_edge(line, x: float, y: float, final_line, tol_m: float) -> bool:
    """Whether an online edge line lies within ``tol_m`` of the final mark (x, y): along x at
    that y, with y within ``DEADLINE_REACH_M`` of the line's rows. Its reported point (the
    foot's line when seen there, else the nearest end of the part seen) may lie elsewhere on
    the same edge."""
    if line is None or final_line is None:
        return False
    lo, hi = line.y_range_m
    reach = DEADLINE_REACH_M
    return lo - reach <= y <= hi + reach and abs(line.x_at(y) - x) <= tol_m


def feature_deadlines(t_s: Sequence[float], online: Sequence, final: TerrainFeatures,
                      toe_off_s: float | None) -> list[dict]:  # fmt: skip
    """Per feature of the stride's final grid: the first time an online grid (``online[k]``
    at ``t_s[k]``, None: not searched) had the same kind with its edge within
    ``DEADLINE_EDGE_M`` of the final edge where that one is reported (:func:`_same_edge`; a
    ramp without a start line by its nearest point, 5 cm more) and its value within
    ``DEADLINE_TOLERANCE``; ``lead_s`` = toe-off − that time."""
    out = []
    finals = _mark_lines(final)
    for (kind, x, y, value), fline in zip(feature_marks(final), finals, strict=True):
        known = float("nan")
        for t, feats in zip(t_s, online, strict=True):
            if feats is None:
                continue
            marks = zip(feature_marks(feats), _mark_lines(feats), strict=True)
            if any(k == kind and abs(v - value) <= DEADLINE_TOLERANCE[k]
                   and (_same_edge(line, x, y, fline, DEADLINE_EDGE_M) or (
                       (line is None or fline is None) and abs(xx - x) <= DEADLINE_EDGE_M
                       and math.hypot(xx - x, yy - y) <= DEADLINE_EDGE_M + 0.05))
                   for (k, xx, yy, v), line in marks):  # fmt: skip
                known = float(t)
                break
        lead = (toe_off_s - known) if toe_off_s is not None and math.isfinite(known) else math.nan
        out.append({"kind": kind, "edge_x_m": x, "value": value, "known_t_s": known, "lead_s": lead,
                    "edge_y_range_m": None if fline is None else fline.y_range_m})  # fmt: skip
    return out


def summarise_feature_deadlines(rows: Sequence[dict]) -> dict:
    """n, known, known before toe-off, known ≥ 0.5 s before it, median and least lead; under
    ``swing`` the same for the rows marked ``in_swing`` (the features the swing must clear)."""
    out = _deadline_counts(rows)
    out["swing"] = _deadline_counts([r for r in rows if r.get("in_swing")])
    return out


def _deadline_counts(rows: Sequence[dict]) -> dict:
    lead = np.array([r["lead_s"] for r in rows], dtype=np.float64)
    known = np.isfinite(lead)
    return {
        "n": len(rows),
        "n_known": int(known.sum()),
        "n_before_toe_off": int((lead[known] > 0).sum()),
        "n_at_least_0_5_s": int((lead[known] >= 0.5).sum()),
        "lead_s_median": float(np.median(lead[known])) if known.any() else None,
        "lead_s_min": float(np.min(lead[known])) if known.any() else None,
        "by_kind": {k: int(sum(r["kind"] == k for r in rows)) for k in DEADLINE_TOLERANCE},
    }

"""The coming swing's clearance, predicted during stance (stride frame, metres).

:func:`reference_swing` builds a reference toe path for the terrain type the features report
ahead, from the toe's position now over one stride length (``ClearanceConfig.stride_length_m``;
stairs up: to the tread it lands on);
:func:`predict_clearance` measures it against the current grid and features and raises the
warning when its **edge** clearance (:func:`~graph_slam.terrain.features.clearance.edge_clearance`)
is below ``warn_below_m`` (2 cm). The reference per terrain type
(:func:`terrain_type`, the first that applies along the walking line):

* ``stairs_up`` — step over step (:func:`stairs_up_landing`): a lift of ``lift_m`` over a base
  line that rises by mid-swing to the tread ``stairs_steps_per_swing`` nosings ahead, where the
  swing lands, its toe short of that tread's riser; ``curb`` — the base line up to the curb's
  top by mid-swing (a curb nearer than that: by its edge); ``stairs_down`` — the base line
  drops to the next tread from mid-swing (the toe clears the nosing of the tread it leaves
  first);
* ``step_over`` — a box whose leading edge lies within the swing: the base line rises to the
  box's top over ``step_over_run_m`` before its leading edge and comes back down over as much
  past its trailing edge (or lands on the top when the box runs past the landing), as a leg
  stepping over it raises its foot; the same lift over it. A box right in front of the toe
  leaves the base line no room to rise and the warning is raised;
* ``ramp`` — the lift over a base line from the ground under the toe to the ground at landing;
  ``level`` — the same over level floor (no edge: no warning however low).

The lift follows ``lift_m · √sin(π s)`` over the swing's fraction ``s`` (a plateau: the toe stays
up mid-swing).
"""

from __future__ import annotations

import functools
import math

import numpy as np

from graph_slam.terrain.features.clearance import (
    Clearance,
    ClearanceConfig,
    _grid_heights,
    clearance_along,
    edge_clearance,
    finite_or,
)
from graph_slam.terrain.features.model import BoxFeature, TerrainFeatures

_DEFAULT = ClearanceConfig()


def _on_path(line, y_m: float, margin_m: float = 0.05) -> bool:
    return line.y_range_m[0] - margin_m <= y_m <= line.y_range_m[1] + margin_m


def box_ahead(
    features: TerrainFeatures, x_from_m: float, x_to_m: float, y_m: float = 0.0
) -> BoxFeature | None:
    """The nearest box whose leading edge lies between the two x on the line y = ``y_m``."""
    found = [
        b for b in features.boxes
        if x_from_m <= b.leading.x_at(y_m) <= x_to_m and _on_path(b.leading, y_m)
    ]  # fmt: skip
    return min(found, key=lambda b: b.leading.x_at(y_m)) if found else None


def terrain_type(
    features: TerrainFeatures, x_from_m: float, x_to_m: float, y_m: float = 0.0
) -> tuple[str, float]:
    """The reference swing's terrain type between two x along the line y = ``y_m`` (a
    feature beside that line does not count), and the rise it lifts over (a box: its
    height)."""
    for st in features.stairs:
        for step in st.steps:
            if x_from_m <= step.nosing.x_m <= x_to_m and _on_path(step.nosing, y_m):
                return ("stairs_up" if step.rise_m > 0 else "stairs_down"), step.rise_m
    for c in features.curbs:
        if x_from_m <= c.edge.x_m <= x_to_m and _on_path(c.edge, y_m):
            return "curb", c.height_m
    box = box_ahead(features, x_from_m, x_to_m, y_m)
    if box is not None:
        return "step_over", box.height_m
    for r in features.ramps:
        on = r.start is None or _on_path(r.start, y_m)
        if on and r.far_x_m >= x_from_m and r.near_x_m <= x_to_m:
            return "ramp", 0.0
    return "level", 0.0


def _smoothstep(u: np.ndarray) -> np.ndarray:
    u = np.clip(u, 0.0, 1.0)
    return u * u * (3 - 2 * u)


def step_over_base(x: np.ndarray, box: BoxFeature, y_m: float, run_m: float) -> np.ndarray:
    """The step-over base line's height over the box's floor, 0 to the box's height: up over
    ``run_m`` before its leading edge (from the first x when that is nearer), level over the
    top, down over ``run_m`` past its trailing edge (a box seen in part: its top runs on)."""
    x = np.asarray(x, dtype=np.float64)
    lead = box.leading.x_at(y_m)
    trail = lead + box.depth_m if box.far_seen else math.inf
    start = max(lead - run_m, float(x[0]))
    up = np.where(x >= lead, 1.0, _smoothstep((x - start) / max(lead - start, 1e-6)))
    down = np.where(x <= trail, 1.0, 1.0 - _smoothstep((x - trail) / run_m))
    return box.height_m * np.minimum(up, down)


def reference_swing(
    view, features: TerrainFeatures, toe_xy_m=(0.2, 0.0), config: ClearanceConfig | None = None
) -> tuple[np.ndarray, str]:
    """The reference toe path (N×3) of the coming swing from ``toe_xy_m``, and its type."""
    cfg = config or _DEFAULT
    x0, y0 = float(toe_xy_m[0]), float(toe_xy_m[1])
    s, lift = _fractions(cfg.samples, cfg.lift_m)
    kind, rise = terrain_type(features, x0, x0 + cfg.stride_length_m, y0)
    length, level = cfg.stride_length_m, math.nan
    if kind == "stairs_up":
        length, rise, level = stairs_up_landing(features, x0, y0, cfg)
    x = x0 + s * length
    xy = np.column_stack([x, np.full_like(x, y0)])
    ground, _ = _grid_heights(view, xy[[0, -1]], cfg.toe_radius_m)
    z0 = finite_or(ground[0])
    if kind == "step_over":
        box = box_ahead(features, x0, x0 + cfg.stride_length_m, y0)
        over = box.floor_height_m + step_over_base(x, box, y0, cfg.step_over_run_m)
        return np.column_stack([xy, np.maximum(z0, over) + lift]), kind
    z1 = z0 + rise if kind != "ramp" else finite_or(ground[1], nan=z0)
    z1 = level if math.isfinite(level) else z1
    # up to the landing level by mid-swing when stepping up; down from mid-swing when stepping
    # down (the toe clears the nosing of the tread it leaves first: lowered over the whole
    # swing it passed that nosing a centimetre up); over the whole swing otherwise
    # (a curb up nearer than mid-swing: by its edge, as a foot stepping up is raised before it)
    reach = 0.5 if not (kind == "curb" and rise > 0) else _curb_reach(features, x0, y0, cfg)
    u = np.minimum(s / reach, 1.0) if rise > 0 else np.clip(2 * s - 1, 0.0, 1.0) if rise < 0 else s
    z = z0 + (z1 - z0) * u * u * (3 - 2 * u) + lift
    return np.column_stack([xy, z]), kind


def stairs_up_landing(
    features: TerrainFeatures, x0_m: float, y_m: float = 0.0, config: ClearanceConfig | None = None
) -> tuple[float, float, float]:
    """The stairs-up reference swing's length from the toe at ``x0_m``, the rise it climbs
    and the height of the tread it lands on (the last climbed step's upper surface; NaN when
    not measured):
    step over step, onto the tread ``stairs_steps_per_swing`` nosings ahead (those within the
    stride length), its toe ``stairs_toe_gap_m`` short of that tread's riser (the next nosing,
    or the last climbed one's tread depth on) and never past the stride length. A foot lands
    on a tread: a swing run on through the riser beyond it reads as a collision."""
    cfg = config or _DEFAULT
    reach = x0_m + cfg.stride_length_m
    ahead = sorted(
        (
            (step.nosing.x_at(y_m), step)
            for st in features.stairs for step in st.steps
            if step.rise_m > 0 and _on_path(step.nosing, y_m) and step.nosing.x_at(y_m) >= x0_m
        ),
        key=lambda a: a[0],
    )  # fmt: skip
    climbed = [a for a in ahead if a[0] <= reach][: cfg.stairs_steps_per_swing]
    if not climbed:
        return cfg.stride_length_m, 0.0, math.nan
    last_x, last = climbed[-1]
    beyond = [x for x, _ in ahead if x > last_x]
    riser = beyond[0] if beyond else last_x + finite_or(last.tread_m, nan=math.inf)
    end = min(reach, riser - cfg.stairs_toe_gap_m)
    rise = float(sum(step.rise_m for _, step in climbed))
    return max(end, last_x) - x0_m, rise, float(last.upper_height_m)


@functools.lru_cache(maxsize=8)
def _fractions(samples: int, lift_m: float) -> tuple[np.ndarray, np.ndarray]:
    """The swing's fractions (``samples`` of them, 0 to 1) and the lift at each,
    ``lift_m · √sin(π s)`` (a plateau: the toe stays up mid-swing); read-only."""
    s = np.linspace(0.0, 1.0, samples)
    lift = lift_m * np.sqrt(np.sin(np.pi * s))
    s.flags.writeable = lift.flags.writeable = False
    return s, lift


def _mid_swing(cfg: ClearanceConfig, n: int) -> np.ndarray:
    """The indices of ``n`` swing samples in ``cfg.mid_swing`` (read-only)."""
    return _mid_indices(n, tuple(cfg.mid_swing))


@functools.lru_cache(maxsize=8)
def _mid_indices(n: int, mid_swing: tuple[float, float]) -> np.ndarray:
    s = np.linspace(0.0, 1.0, n)
    out = np.flatnonzero((s >= mid_swing[0]) & (s <= mid_swing[1]))
    out.flags.writeable = False
    return out


def _curb_reach(features: TerrainFeatures, x0: float, y0: float, cfg: ClearanceConfig) -> float:
    """The swing's fraction by which the base line is up a curb ahead: mid-swing, or the
    curb's edge when that comes first (at least 0.05 of the swing)."""
    edges = [
        c.edge.x_at(y0) for c in features.curbs
        if x0 <= c.edge.x_at(y0) <= x0 + cfg.stride_length_m and _on_path(c.edge, y0)
    ]  # fmt: skip
    if not edges:
        return 0.5
    return float(np.clip((min(edges) - x0) / cfg.stride_length_m, 0.05, 0.5))


def predict_clearance(
    view,
    features: TerrainFeatures | None = None,
    toe_xy_m=None,
    config: ClearanceConfig | None = None,
) -> Clearance:
    """The coming swing's clearance on its reference path over the current terrain, with the
    warning flag (see the module docstring)."""
    cfg = config or _DEFAULT
    feats = view.features if features is None else features
    toe = (view.toe_x_m, 0.0) if toe_xy_m is None else toe_xy_m
    path, kind = reference_swing(view, feats, toe, cfg)
    mid = _mid_swing(cfg, len(path))
    c = clearance_along(view, feats, path[mid], cfg, terrain=kind)
    edge = edge_clearance(feats, path[mid], cfg)
    edge_m = float("nan") if edge is None else edge.min_m
    warn = bool(math.isfinite(edge_m) and edge_m < cfg.warn_below_m)
    sample = int(mid[c.sample]) if c.sample >= 0 else -1
    return Clearance(c.min_m, c.sigma_m, c.x_m, c.y_m, sample, c.edge, kind, warn, edge_m)

"""Feature truth from a scene's walkable surfaces (graph_slam.sim.surface), in a stride frame.

:func:`scene_surfaces` finds the :class:`~graph_slam.sim.surface.Surfaces` of a scene: its own,
or, for a session's :class:`~graph_slam.session.records.SceneTruth`, those of the scene file of
that name when that file still builds the session's objects (same names, kinds, poses, sizes).
:func:`features_from_surfaces` turns :meth:`Surfaces.features` into the features a perfect
grid would give (σ 0): a flight up or down (signed rises, each nosing's tread to the next, NaN
for the last), a ramp up or down (slope, uphill direction, start line), a box to step over or
onto, and a platform's or curb's faces where the surface height jumps (curbs, signed along the
stride's x), leaving out the faces that are a flight's nosing.
"""

from __future__ import annotations

import math
from functools import lru_cache

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

_PROBE_M = 0.01  # either side of a platform's face, to read the height jump across it
_MIN_JUMP_M = 0.01  # a face with a smaller jump is flush with what lies beyond


@lru_cache(maxsize=8)
def _scene_by_name(name: str):
    from graph_slam.errors import GraphSlamError
    from graph_slam.sim.scene import load_scene

    try:
        return load_scene(name)
    except (GraphSlamError, OSError, ValueError):
        return None


def _same_objects(a, b) -> bool:
    if len(a) != len(b):
        return False
    return all(
        x.name == y.name and x.kind == y.kind
        and np.allclose(x.world_T_object, y.world_T_object, atol=1e-9)
        and np.allclose(x.size_m, y.size_m, atol=1e-9)
        for x, y in zip(a, b, strict=True)
    )  # fmt: skip


def scene_surfaces(scene):
    """The scene's Surfaces, or None when they cannot be had for exactly these objects."""
    surfaces = getattr(scene, "surfaces", None)
    if surfaces is not None:
        return surfaces
    name = getattr(scene, "name", None)
    loaded = _scene_by_name(name) if isinstance(name, str) and name else None
    if loaded is None or not _same_objects(loaded.truth_objects, tuple(scene.objects)):
        return None
    return loaded.surfaces


def _to_stride(stride_T_world: np.ndarray, p) -> np.ndarray:
    return (stride_T_world @ np.array([p[0], p[1], p[2], 1.0]))[:3]


def _line(stride_T_world: np.ndarray, ends) -> EdgeLine:
    """An edge through two world points, in the stride frame (point at its middle)."""
    a, b = (_to_stride(stride_T_world, p) for p in ends)
    d = b - a
    yaw = math.atan2(-d[0], d[1]) if d[1] >= 0 else math.atan2(d[0], -d[1])
    mid = (a + b) / 2
    lo, hi = sorted((float(a[1]), float(b[1])))
    return EdgeLine(float(mid[0]), float(mid[1]), yaw, 0.0, 0.0, (lo, hi), 0, False)


def _wrap(angle: float) -> float:
    return math.atan2(math.sin(angle), math.cos(angle))


def _flight(stride_T_world: np.ndarray, f) -> Stairs:
    sign = 1.0 if f.direction != "down" else -1.0
    steps = []
    for k, s in enumerate(f.steps):
        upper = float(_to_stride(stride_T_world, s.nosing_m[0])[2])
        tread = s.tread_m if k + 1 < len(f.steps) else float("nan")
        steps.append(Step(sign * s.rise_m, 0.0, _line(stride_T_world, s.nosing_m), tread, 0.0,
                          upper - s.rise_m, upper))  # fmt: skip
    return Stairs(tuple(steps))


def _ramp(stride_T_world: np.ndarray, f) -> Ramp:
    start, end = _line(stride_T_world, f.start_line_m), _line(stride_T_world, f.end_line_m)
    up_yaw = math.atan2(stride_T_world[1, 0], stride_T_world[0, 0])
    up_yaw = _wrap(up_yaw + (math.pi if f.direction == "down" else 0.0))
    x_range = tuple(sorted((start.x_m, end.x_m)))
    return Ramp(math.radians(f.slope_deg), 0.0, up_yaw, 0.0, start, 0, 0.0, x_range)


def _faces(surfaces, stride_T_world, world_T_stride, f, nosings) -> list[Curb]:
    """A platform's or curb's near and far faces where the height jumps across them."""
    c, s = math.cos(math.radians(f.yaw_deg)), math.sin(math.radians(f.yaw_deg))
    hx, hy, h = f.size_m[0] / 2, f.size_m[1] / 2, f.size_m[2]
    forward = world_T_stride[:3, 0]
    out = []
    for u in (-hx, hx):
        ends = [(f.center_m[0] + c * u - s * v, f.center_m[1] + s * u + c * v, h)
                for v in (-hy, hy)]  # fmt: skip
        mid = np.mean(np.array(ends), axis=0)
        if any(abs(mid[0] - x) < 1e-6 and y0 <= mid[1] <= y1 for x, y0, y1 in nosings):
            continue
        before = float(surfaces.height_at(*(mid[:2] - _PROBE_M * forward[:2])))
        after = float(surfaces.height_at(*(mid[:2] + _PROBE_M * forward[:2])))
        if abs(after - before) < _MIN_JUMP_M:
            continue
        near = float(_to_stride(stride_T_world, (mid[0], mid[1], before))[2])
        out.append(Curb(after - before, 0.0, _line(stride_T_world, ends), near))
    return out


def features_from_surfaces(surfaces, world_T_stride: np.ndarray) -> TerrainFeatures:
    """The surfaces' features in the stride frame (see the module docstring)."""
    world_T_stride = np.asarray(world_T_stride, dtype=np.float64)
    stride_T_world = np.linalg.inv(world_T_stride)
    floor_z = float(stride_T_world[2, 3])
    truths = surfaces.features()
    stairs = [_flight(stride_T_world, f) for f in truths if f.kind == "stairs"]
    ramps = [_ramp(stride_T_world, f) for f in truths if f.kind == "ramp"]
    nosings = [(s.nosing_m[0][0], min(s.nosing_m[0][1], s.nosing_m[1][1]),
                max(s.nosing_m[0][1], s.nosing_m[1][1]))
               for f in truths if f.kind == "stairs" for s in f.steps]  # fmt: skip
    curbs, boxes = [], []
    for f in truths:
        if f.kind != "box":
            continue
        if f.role in ("platform", "curb"):
            curbs += _faces(surfaces, stride_T_world, world_T_stride, f, nosings)
        else:
            boxes.append(BoxFeature(f.height_m, 0.0, _line(stride_T_world, f.edge_m),
                                    f.size_m[0], 0.0, floor_z))  # fmt: skip
    return TerrainFeatures(source="truth", stairs=tuple(stairs), ramps=tuple(ramps),
                           curbs=tuple(curbs), boxes=tuple(boxes))  # fmt: skip

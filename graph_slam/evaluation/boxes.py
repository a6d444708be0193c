"""Obstacle dimensions against the scene's ground truth (thesis Table 4.1).

Each stride's map gives a measurement of every box it saw **whole**. :func:`assess_stride`
assigns the extracted obstacles to the scene's boxes (an obstacle belongs to the box whose
footprint, grown by a margin, holds its centre) and gives every box in view one outcome:

* ``measured``: exactly one obstacle, seen whole (``Obstacle.complete``);
* ``skipped`` with a reason: the mapping's (``edge_of_map``, ``adjacent``, ``top_incomplete``,
  ``floor_not_seen``; :data:`graph_slam.terrain.SKIP_REASONS`) or ``split`` (the box came out
  as several obstacles);
* ``missed``: no obstacle, although the box stands wholly inside the mapped area.

Boxes outside the map are not counted; obstacles in no box's footprint are counted as
``unmatched``. :func:`obstacle_accuracy` reduces the measured boxes to mean, standard deviation
(sample, ddof=1; NaN for one measurement) and RMSE against the true size, per dimension.
Copies of a box in a repeated course (``Box1#2``) count as ``Box1``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from graph_slam.errors import EvaluationError
from graph_slam.session.records import SceneTruth
from graph_slam.terrain.maps.obstacles import Obstacle, ObstacleMap

DIMENSIONS = ("depth", "width", "height")
"""Order of ``size_m`` (thesis Table 3.1): depth along x (walking direction), width y, height z."""


@dataclass(frozen=True)
class DimensionStats:
    n: int
    truth_m: float
    mean_m: float
    std_m: float
    rmse_m: float

    def to_dict(self) -> dict[str, float | int]:
        return asdict(self)


def base_name(name: str) -> str:
    """``Box1#2`` -> ``Box1`` (a repeated course's copies are the same box)."""
    return name.split("#", 1)[0]


SPLIT = "split"
"""Skip reason of a box that came out as several obstacles."""
OUTCOMES = ("measured", "skipped", "missed")


@dataclass(frozen=True, eq=False)
class TrueBox:
    """A scene box in a stride frame: centre (x, y), size (depth, width, height), yaw of its
    depth axis from stride x."""

    name: str
    center_xy_m: np.ndarray
    size_m: np.ndarray
    yaw_rad: float = 0.0

    def local_xy_m(self, xy_m: np.ndarray) -> np.ndarray:
        """Points (N×2) in the box's own axes (depth, width), origin at its centre."""
        c, s = np.cos(self.yaw_rad), np.sin(self.yaw_rad)
        d = np.asarray(xy_m, dtype=np.float64).reshape(-1, 2) - self.center_xy_m
        return d @ np.array([[c, -s], [s, c]])

    def contains(self, xy_m: np.ndarray, margin_m: float = 0.0) -> np.ndarray:
        """Whether points lie on the footprint grown by ``margin_m``."""
        local = np.abs(self.local_xy_m(xy_m))
        half = np.asarray(self.size_m[:2]) / 2 + margin_m
        return (local <= half).all(axis=1)

    def outline_xy_m(self, margin_m: float = 0.0, step_m: float = 0.01) -> np.ndarray:
        """Points along the footprint's outline grown by ``margin_m`` (N×2, stride frame)."""
        hd, hw = np.asarray(self.size_m[:2]) / 2 + margin_m
        u = np.linspace(-hd, hd, max(2, int(2 * hd / step_m) + 1))
        v = np.linspace(-hw, hw, max(2, int(2 * hw / step_m) + 1))
        local = np.concatenate(
            [
                np.column_stack([u, np.full_like(u, -hw)]),
                np.column_stack([u, np.full_like(u, hw)]),
                np.column_stack([np.full_like(v, -hd), v]),
                np.column_stack([np.full_like(v, hd), v]),
            ]
        )
        c, s = np.cos(self.yaw_rad), np.sin(self.yaw_rad)
        return local @ np.array([[c, s], [-s, c]]) + self.center_xy_m


def truth_boxes_in_stride(scene: SceneTruth, world_T_stride: np.ndarray) -> list[TrueBox]:
    """Every box of the scene in the stride frame (centre, size, yaw)."""
    stride_T_world = np.linalg.inv(np.asarray(world_T_stride, dtype=np.float64))
    out = []
    for obj in scene.objects:
        if obj.kind != "box":
            continue
        stride_T_object = stride_T_world @ obj.world_T_object
        x_axis = stride_T_object[:3, 0]
        out.append(
            TrueBox(
                name=obj.name,
                center_xy_m=stride_T_object[:2, 3].copy(),
                size_m=np.asarray(obj.size_m, dtype=np.float64),
                yaw_rad=float(np.arctan2(x_axis[1], x_axis[0])),
            )
        )
    return out


@dataclass(frozen=True, eq=False)
class BoxOutcome:
    """What one stride's map made of one scene box."""

    box: str
    """The scene's name, copy suffix included (``Box1#2``)."""
    status: str
    """``measured``, ``skipped`` or ``missed``."""
    reason: str | None = None
    """Why ``skipped``: a mapping skip reason or ``split``."""
    detail: str = ""
    obstacle: Obstacle | None = None
    """The obstacle measured (for ``split``, the one with most points)."""

    def to_dict(self) -> dict[str, Any]:
        o = self.obstacle
        return {
            "box": self.box,
            "status": self.status,
            "reason": self.reason,
            "detail": self.detail,
            "size_m": None if o is None else [float(x) for x in o.size_m],
            "leading_edge_x_m": None if o is None else o.leading_edge_x_m,
            "yaw_rad": None if o is None else o.yaw_rad,
        }


@dataclass(frozen=True, eq=False)
class StrideObstacles:
    """Every box outcome of one stride's map, and the obstacles that matched no box."""

    outcomes: tuple[BoxOutcome, ...] = ()
    unmatched: int = 0
    error: str | None = None
    """Why the map has no obstacles at all (no floor found), else None."""

    def measured(self) -> dict[str, Obstacle]:
        return {o.box: o.obstacle for o in self.outcomes if o.status == "measured"}

    def counts(self) -> dict[str, Any]:
        return count_outcomes([self])

    def to_dict(self) -> dict[str, Any]:
        counts = self.counts()
        del counts["by_box"]  # the boxes are listed below
        return {
            **counts,
            "error": self.error,
            "boxes": [o.to_dict() for o in self.outcomes],
        }


def assign_obstacles(
    obstacles: Sequence[Obstacle], truth: Sequence[TrueBox], margin_m: float = 0.05
) -> tuple[dict[str, list[Obstacle]], list[Obstacle]]:
    """Each obstacle to the box whose footprint grown by ``margin_m`` holds its centre (the
    nearest centre where footprints overlap); returns per box its obstacles, and the rest."""
    assigned: dict[str, list[Obstacle]] = {}
    rest = []
    for obstacle in obstacles:
        holders = [b for b in truth if b.contains(obstacle.center_xy_m, margin_m)[0]]
        if not holders:
            rest.append(obstacle)
            continue
        box = min(
            holders, key=lambda b: float(np.linalg.norm(b.center_xy_m - obstacle.center_xy_m))
        )
        assigned.setdefault(box.name, []).append(obstacle)
    return assigned, rest


def assess_stride(
    obstacle_map: ObstacleMap | None,
    truth: Sequence[TrueBox],
    margin_m: float = 0.05,
    error: str | None = None,
) -> StrideObstacles:
    """One outcome per scene box that the stride's map covers (see the module docstring).

    ``obstacle_map`` None (no floor found; ``error`` says why): no outcome is given.
    """
    if obstacle_map is None:
        return StrideObstacles(error=error or "no obstacle map")
    assigned, rest = assign_obstacles(obstacle_map.obstacles, truth, margin_m)
    coverage = obstacle_map.coverage
    outcomes = []
    for box in truth:
        pieces = assigned.get(box.name, [])
        if len(pieces) > 1:
            largest = max(pieces, key=lambda o: o.point_count)
            outcomes.append(
                BoxOutcome(box.name, "skipped", SPLIT, f"seen as {len(pieces)} obstacles", largest)
            )
        elif pieces:
            (o,) = pieces
            if o.complete:
                outcomes.append(BoxOutcome(box.name, "measured", obstacle=o))
            else:
                outcomes.append(BoxOutcome(box.name, "skipped", o.skip_reason, o.skip_detail, o))
        elif coverage is not None and not coverage.is_outside(box.outline_xy_m(margin_m)).any():
            outcomes.append(
                BoxOutcome(box.name, "missed", None, "inside the mapped area, no obstacle found")
            )
    return StrideObstacles(tuple(outcomes), unmatched=len(rest))


def count_outcomes(strides: Sequence[StrideObstacles]) -> dict[str, Any]:
    """Totals over strides: ``measured``, ``skipped`` per reason, ``missed``, ``unmatched``,
    ``no_map`` (strides without an obstacle map) and ``by_box`` (per base box name)."""
    total: dict[str, Any] = {
        "measured": 0,
        "skipped": {},
        "missed": 0,
        "unmatched": 0,
        "no_map": 0,
        "by_box": {},
    }
    for stride in strides:
        total["unmatched"] += stride.unmatched
        total["no_map"] += stride.error is not None
        for o in stride.outcomes:
            box = total["by_box"].setdefault(
                base_name(o.box), {"measured": 0, "skipped": {}, "missed": 0}
            )
            for where in (total, box):
                if o.status == "skipped":
                    where["skipped"][o.reason] = where["skipped"].get(o.reason, 0) + 1
                else:
                    where[o.status] += 1
    total["by_box"] = dict(sorted(total["by_box"].items()))
    return total


def obstacle_accuracy(
    measured_size_m: Mapping[str, Sequence[np.ndarray]],
    truth_size_m: Mapping[str, np.ndarray],
) -> dict[str, dict[str, DimensionStats]]:
    """Per box and dimension: mean, std and RMSE of the measurements against the truth.

    Args:
        measured_size_m: box name -> list of measured (depth, width, height), metres.
        truth_size_m: box name -> true (depth, width, height), metres.
    """
    result: dict[str, dict[str, DimensionStats]] = {}
    for name, sizes in measured_size_m.items():
        if name not in truth_size_m:
            raise EvaluationError(f"obstacle_accuracy: no ground truth for box {name!r}")
        m = np.asarray(sizes, dtype=np.float64).reshape(-1, 3)
        if m.shape[0] == 0:
            continue
        truth = np.asarray(truth_size_m[name], dtype=np.float64).reshape(3)
        std = m.std(axis=0, ddof=1) if m.shape[0] > 1 else np.full(3, np.nan)
        rmse = np.sqrt(np.mean((m - truth) ** 2, axis=0))
        result[name] = {
            dim: DimensionStats(
                n=int(m.shape[0]),
                truth_m=float(truth[d]),
                mean_m=float(m[:, d].mean()),
                std_m=float(std[d]),
                rmse_m=float(rmse[d]),
            )
            for d, dim in enumerate(DIMENSIONS)
        }
    return result


def collect_measurements(strides: Sequence[StrideObstacles]) -> dict[str, list[np.ndarray]]:
    """The measured boxes of every stride as ``{base box name: [size_m, ...]}``."""
    out: dict[str, list[np.ndarray]] = {}
    for stride in strides:
        for name, obstacle in stride.measured().items():
            out.setdefault(base_name(name), []).append(obstacle.size_m)
    return out

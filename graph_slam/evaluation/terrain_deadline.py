"""Ready before toe-off: when did the online map know each obstacle of the stride?

For one stride, the *final* map (the stride's grid re-fused from the smoothed poses) gives
every obstacle it measures whole. The online map at frame ``t`` *knows* such an obstacle when
one of its obstacles (matched by centre within ``match_radius_m``) has its height within
``height_tol_m`` (1 cm) and its leading edge within ``edge_tol_m`` (2 cm) of the final values.
:func:`obstacle_deadlines` gives, per final obstacle, the first frame time at which it is
known and that time relative to toe-off (``lead_s = toe_off_s - known_t_s``: positive =
known before the swing must be planned). Obstacles are anything with ``leading_edge_x_m``,
``height_m`` and ``center_xy_m`` (a :class:`graph_slam.terrain.grid.grid_obstacles.GridObstacle`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from graph_slam.errors import EvaluationError


@dataclass(frozen=True)
class ObstacleDeadline:
    """One obstacle of a stride's final map and when the online map first knew it."""

    stride_index: int
    obstacle_index: int
    """Its index among the final map's whole obstacles (nearest first)."""
    final_leading_edge_x_m: float
    final_height_m: float
    known_t_s: float
    """First frame time at which the online map knew it (NaN: never in the stride)."""
    toe_off_s: float
    """The stride's toe-off (NaN: none)."""

    @property
    def known(self) -> bool:
        return math.isfinite(self.known_t_s)

    @property
    def lead_s(self) -> float:
        """``toe_off_s - known_t_s``: how long before toe-off it was known (NaN: never)."""
        return self.toe_off_s - self.known_t_s

    def to_dict(self) -> dict[str, Any]:
        return {**asdict(self), "lead_s": self.lead_s}


def _matches(online, final, match_radius_m, height_tol_m, edge_tol_m) -> bool:
    near = [
        o
        for o in online
        if np.linalg.norm(np.asarray(o.center_xy_m) - np.asarray(final.center_xy_m))
        <= match_radius_m
    ]
    return any(
        abs(o.height_m - final.height_m) <= height_tol_m
        and abs(o.leading_edge_x_m - final.leading_edge_x_m) <= edge_tol_m
        for o in near
    )


def obstacle_deadlines(
    frame_t_s: Sequence[float],
    frame_obstacles: Sequence[Sequence],
    final_obstacles: Sequence,
    toe_off_s: float | None,
    *,
    stride_index: int = 0,
    height_tol_m: float = 0.01,
    edge_tol_m: float = 0.02,
    match_radius_m: float = 0.15,
) -> list[ObstacleDeadline]:
    """Per whole obstacle of the final map, the first frame at which the online map knew it
    (see the module docstring). ``frame_t_s`` increasing; ``frame_obstacles[k]``: the online
    map's obstacles after frame ``k``."""
    t = np.asarray(frame_t_s, dtype=np.float64)
    if len(frame_obstacles) != t.size:
        raise EvaluationError(
            f"obstacle_deadlines: {len(frame_obstacles)} obstacle lists for {t.size} frames"
        )
    if t.size > 1 and not (np.diff(t) > 0).all():
        raise EvaluationError("obstacle_deadlines: frame times must increase")
    toe = float("nan") if toe_off_s is None else float(toe_off_s)
    out = []
    for k, final in enumerate(final_obstacles):
        known = float("nan")
        for tt, online in zip(t, frame_obstacles, strict=True):
            if _matches(online, final, match_radius_m, height_tol_m, edge_tol_m):
                known = float(tt)
                break
        out.append(
            ObstacleDeadline(
                stride_index, k, float(final.leading_edge_x_m), float(final.height_m), known, toe
            )
        )
    return out


@dataclass(frozen=True, eq=False)
class StrideDeadlines:
    """One scored stride's obstacles (those its final map measures whole) and when the online
    map knew each; ``known_pct``: that moment in % of the gait cycle (NaN: never)."""

    index: int
    speed: str
    number: int
    toe_off_pct: float
    deadlines: list[ObstacleDeadline]
    known_pct: list[float]

    def to_dict(self) -> dict[str, Any]:
        return {
            "index": self.index,
            "speed": self.speed,
            "number": self.number,
            "toe_off_pct": self.toe_off_pct,
            "obstacles": [
                {**d.to_dict(), "known_pct": p}
                for d, p in zip(self.deadlines, self.known_pct, strict=True)
            ],
        }


def summarise_deadlines(deadlines: Sequence[ObstacleDeadline]) -> dict[str, Any]:
    """Counts and the lead before toe-off: ``n`` obstacles, ``n_known`` (ever in the stride),
    ``n_before_toe_off``, ``fraction_before_toe_off`` (of ``n``; NaN when none), median and
    minimum ``lead_s`` over the known ones with a toe-off."""
    n = len(deadlines)
    known = [d for d in deadlines if d.known]
    leads = np.array([d.lead_s for d in known if math.isfinite(d.toe_off_s)])
    before = int((leads >= 0).sum())
    return {
        "n": n,
        "n_known": len(known),
        "n_before_toe_off": before,
        "fraction_before_toe_off": before / n if n else float("nan"),
        "lead_s_median": float(np.median(leads)) if leads.size else float("nan"),
        "lead_s_min": float(leads.min()) if leads.size else float("nan"),
    }


def deadline_summary(strides: Sequence[StrideDeadlines]) -> dict[str, Any]:
    """One variant's deadlines over its strides: every obstacle together (``all``) and per
    walking speed (``by_speed``), :func:`summarise_deadlines` each, plus the strides."""
    speeds = sorted({s.speed for s in strides})
    return {
        "all": summarise_deadlines([d for s in strides for d in s.deadlines]),
        "by_speed": {
            sp: summarise_deadlines([d for s in strides if s.speed == sp for d in s.deadlines])
            for sp in speeds
        },
        "strides": [s.to_dict() for s in strides],
    }

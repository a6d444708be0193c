"""What the online terrain map knew, frame by frame, recorded while a variant runs.

``compare`` hands a :class:`TerrainTrace` to ``run_session`` (its ``on_frame``) for every
variant. Per frame it keeps the time, the stride and, at most every ``interval_s``, the whole
obstacles of the frame's elevation grid (``FrameOutput.terrain``; the pipelines' results do
not keep the grids): what the deadline (:mod:`graph_slam.evaluation.terrain_deadline`)
needs. Every ``grid_step``-th frame, when asked, it also keeps a small snapshot of the grid
(heights and σ as float32, its boxes) for the rerun recording. The whole boxes are the ones
``TerrainView.obstacle_map`` gives a controller, searched without measuring the boxes seen
in part (``grid_obstacles(complete_only=True)``: 10–30 ms a search on this 2-core machine,
most of it the floor fit).

:func:`stride_deadlines` turns one variant's trace into the deadline of each scored stride.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from graph_slam.evaluation.terrain_deadline import StrideDeadlines, obstacle_deadlines
from graph_slam.strides.reference import gait_cycle_percent


@dataclass(frozen=True, eq=False)
class GridSnapshot:
    """One frame's elevation grid, reduced to what a view draws (stride frame, metres)."""

    stride_index: int
    t_s: float
    origin_xy_m: np.ndarray
    cell_m: float
    height_m: np.ndarray
    """(nx, ny) float32, NaN where unknown."""
    sigma_m: np.ndarray
    obstacles: tuple
    """The grid's boxes (:class:`~graph_slam.terrain.grid.grid_obstacles.GridObstacle`)."""
    floor_T_stride: np.ndarray | None = None


@dataclass
class TerrainTrace:
    """Per frame, the online grid's whole obstacles; every ``grid_step``-th frame a snapshot
    (``grid_step`` 0: none). Call it with each ``FrameOutput``. ``every_frame`` False: only
    the snapshots (a recording without the deadline: no per-frame box search)."""

    grid_step: int = 0
    every_frame: bool = True
    interval_s: float = 0.0
    """Search a frame's whole boxes only when this long has passed since the last searched
    frame of its stride (0: every frame); the others record None (not searched)."""
    whole_boxes: Callable[[Any], tuple] | None = None
    """A view's whole boxes (None: :func:`complete_boxes`)."""
    t_s: list[float] = field(default_factory=list)
    stride_index: list[int] = field(default_factory=list)
    obstacles: list[tuple | None] = field(default_factory=list)
    """The grid's complete obstacles after each frame (empty: no grid, no floor, none; None:
    not searched, ``interval_s``)."""
    _last: tuple[int, float] = field(default=(-(10**9), -math.inf), init=False, repr=False)
    snapshots: dict[int, GridSnapshot] = field(default_factory=dict)
    features: list = field(default_factory=list)
    """The grid's terrain features (:class:`~graph_slam.terrain.features.model.TerrainFeatures`)
    at the frames whose boxes were searched (None elsewhere): the per-feature deadline."""
    predictions: list = field(default_factory=list)
    """At the searched frames in stance, the coming swing's predicted clearance
    (:class:`~graph_slam.terrain.features.clearance.Clearance`; None elsewhere): the warnings."""

    def __call__(self, out) -> None:
        view = out.terrain
        snap = bool(view is not None and self.grid_step and out.frame_index % self.grid_step == 0)
        self.t_s.append(float(out.t_s))
        self.stride_index.append(int(out.stride_index))
        if snap:
            omap = view.obstacle_map  # every box, for the recording
            self.obstacles.append(() if omap is None else omap.complete)
            self.snapshots[int(out.frame_index)] = GridSnapshot(
                view.stride_index,
                float(out.t_s),
                np.asarray(view.origin_xy_m, float),
                float(view.cell_m),
                view.height_m.astype(np.float32),
                view.sigma_m.astype(np.float32),
                () if omap is None else omap.obstacles,
                None if omap is None else omap.floor.floor_T_stride(),
            )
        elif view is not None and self.every_frame and self._due(out):
            self.obstacles.append((self.whole_boxes or complete_boxes)(view))
        else:
            self.obstacles.append(() if view is None else None)
        searched = view is not None and self.obstacles[-1] is not None and self.every_frame
        feats = getattr(view, "features", None) if searched else None
        self.features.append(feats)
        prediction = None
        if feats is not None and getattr(out, "foot_loaded", False):
            from graph_slam.terrain.features.prediction import predict_clearance

            prediction = predict_clearance(view, feats)
        self.predictions.append(prediction)
        if self.obstacles[-1] is not None:
            self._last = (int(out.stride_index), float(out.t_s))

    def _due(self, out) -> bool:
        stride, t = self._last
        return int(out.stride_index) != stride or float(out.t_s) - t >= self.interval_s - 1e-9


def complete_boxes(view) -> tuple:
    """The view's whole boxes (those of ``view.obstacle_map.complete``, without measuring the
    others: ``grid_obstacles(complete_only=True)``)."""
    from graph_slam.errors import MappingError
    from graph_slam.terrain.grid.grid_obstacles import grid_obstacles

    try:
        return grid_obstacles(view, complete_only=True).obstacles
    except MappingError:  # no floor: no box
        return ()


def stride_deadlines(
    trace: TerrainTrace, stride, ref, index: int, speed: str, number: int
) -> StrideDeadlines:
    """The deadline of one scored stride: ``stride`` the variant's
    :class:`~graph_slam.pipelines.StrideOutput` (its ``smoothed_grid`` is the final map: the
    graph's re-fused from the smoothed poses, the baseline's online grid at its last frame),
    ``ref`` its :class:`~graph_slam.strides.reference.StrideReference` (frames, toe-off, the
    foot strikes that bound the gait cycle). Frames the trace did not search are left out: the
    time known is that of the first searched frame that knew the obstacle."""
    idx = [int(i) for i in ref.frame_indices if trace.obstacles[int(i)] is not None]
    grid = None if stride is None else stride.smoothed_grid
    omap = None if grid is None else grid.obstacle_map
    final = () if omap is None else omap.complete
    deadlines = obstacle_deadlines(
        [trace.t_s[i] for i in idx],
        [trace.obstacles[i] for i in idx],
        final,
        ref.toe_off_s,
        stride_index=index,
    )
    known = np.array([d.known_t_s for d in deadlines], dtype=float)
    pct = gait_cycle_percent(known, ref.t_strike_s, ref.t_next_strike_s) if known.size else known
    return StrideDeadlines(
        index,
        speed,
        number,
        ref.toe_off_pct,
        deadlines,
        [float(p) if math.isfinite(p) else math.nan for p in np.atleast_1d(pct)],
    )


def log_grids(logger, trace: TerrainTrace, frame_indices, stride: int, t0_s: float,
              world_T_stride) -> int:  # fmt: skip
    """Log the trace's grid snapshots of the given frames on the ``stride`` timeline (session
    time shifted by ``t0_s``) under the stride's transform; how many were logged."""
    n = 0
    for i in frame_indices:
        snap = trace.snapshots.get(int(i))
        if snap is None:
            continue
        logger.set_time(stride, t0_s + snap.t_s)
        logger.log_stride(world_T_stride)
        logger.log_grid(snap)
        n += 1
    return n

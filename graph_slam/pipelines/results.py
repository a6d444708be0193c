"""What every pipeline returns, whatever its variant: per-frame poses and statuses, per stride."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np


@dataclass(frozen=True, eq=False)
class FrameOutput:
    """One frame as the pipeline saw it online (causal).

    ``stride_T_camera`` is ``None`` when the pipeline has no pose for the frame (the baseline
    after it stopped registering); ``status`` then says why (``not_registered: <reason>``).
    """

    frame_index: int
    stride_index: int
    t_s: float
    stride_T_camera: np.ndarray | None
    world_T_camera: np.ndarray | None
    status: str
    """``reset`` (stride's first frame), ``registered``, ``estimated`` (graph), or
    ``not_registered: <reason>``."""
    foot_loaded: bool
    frontend_s: float
    backend_s: float
    fitness: float = float("nan")
    flags: tuple[str, ...] = ()

    @property
    def has_pose(self) -> bool:
        return self.stride_T_camera is not None


@dataclass(eq=False)
class StrideOutput:
    """One stride: its frames, smoothed poses (graph variants) and the map (baseline)."""

    index: int
    start: str
    world_T_stride: np.ndarray
    frame_indices: list[int]
    smoothed_stride_T_camera: np.ndarray
    """len(frame_indices)×4×4; NaN where the pipeline has no pose."""
    n_registered: int
    flags: tuple[str, ...] = ()
    map_points_m: np.ndarray | None = None
    """Baseline: the fused global map in the stride frame (N×3)."""
    map_colors: np.ndarray | None = None
    stop_reason: str | None = None


@dataclass(eq=False)
class PipelineResults:
    """Everything one ``run_session`` produced."""

    variant: str
    frames: list[FrameOutput] = field(default_factory=list)
    strides: list[StrideOutput] = field(default_factory=list)
    covariances: np.ndarray | None = None
    """N×6×6 online marginal covariances (camera local, rotation first), on request."""
    backend: Any = None
    """The back end's own :class:`graph_slam.backend.Results` (graph variants)."""
    config: dict[str, Any] = field(default_factory=dict)
    counts: dict[str, int] = field(default_factory=dict)

    @property
    def t_s(self) -> np.ndarray:
        return np.array([f.t_s for f in self.frames])

    @property
    def stride_index(self) -> np.ndarray:
        return np.array([f.stride_index for f in self.frames], dtype=int)

    @property
    def statuses(self) -> list[str]:
        return [f.status for f in self.frames]

    @property
    def has_pose(self) -> np.ndarray:
        return np.array([f.has_pose for f in self.frames], dtype=bool)

    def _stack(self, name: str) -> np.ndarray:
        out = np.full((len(self.frames), 4, 4), np.nan)
        for i, f in enumerate(self.frames):
            value = getattr(f, name)
            if value is not None:
                out[i] = value
        return out

    @property
    def online_stride_T_camera(self) -> np.ndarray:
        """N×4×4, NaN where there is no pose."""
        return self._stack("stride_T_camera")

    @property
    def online_world_T_camera(self) -> np.ndarray:
        return self._stack("world_T_camera")

    def _smoothed(self, world: bool) -> np.ndarray:
        out = np.full((len(self.frames), 4, 4), np.nan)
        for s in self.strides:
            poses = s.smoothed_stride_T_camera
            out[s.frame_indices] = s.world_T_stride @ poses if world else poses
        return out

    @property
    def smoothed_stride_T_camera(self) -> np.ndarray:
        """N×4×4 (the baseline has no smoother: its online poses)."""
        return self._smoothed(False)

    @property
    def smoothed_world_T_camera(self) -> np.ndarray:
        return self._smoothed(True)

    def timings_ms(self) -> dict[str, float]:
        """Median and 95th percentile of the per-frame processing time (front + back end)."""
        total = np.array([f.frontend_s + f.backend_s for f in self.frames]) * 1e3
        if total.size == 0:
            return {"median": float("nan"), "p95": float("nan")}
        return {"median": float(np.median(total)), "p95": float(np.percentile(total, 95))}

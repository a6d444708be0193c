"""What every pipeline returns, whatever its variant: per-frame poses and statuses, per stride."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from graph_slam.backend.results import release_oldest
from graph_slam.variants import Variant

if TYPE_CHECKING:
    from graph_slam.backend.results import FrameEstimate, Results, StrideSummary
    from graph_slam.terrain.grid.view import TerrainView
    from graph_slam.terrain.maps.builder import StrideTerrain


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
    """``reset`` (stride's first frame), ``registered``, ``partial: <k> DoF`` (baseline: a
    registration taken although it held only k directions), ``estimated`` (graph), or
    ``not_registered: <reason>``."""
    foot_loaded: bool
    frontend_s: float
    backend_s: float
    fitness: float = float("nan")
    flags: tuple[str, ...] = ()
    terrain_s: float = 0.0
    """Time spent keeping the frame's map cloud (the stride's maps are fused at its close)."""
    stages_s: dict[str, float] = field(default_factory=dict)
    """Per-stage wall time of this frame (s): ``cloud`` (depth → cloud), ``preprocess``
    (voxel grid, normals: the next frame's target), ``registration``, ``floor`` (stride
    start, without the smoothing), ``graph`` (gate, factors, iSAM2 update, estimate),
    ``terrain``, ``stride_close`` (the smoothing and the maps of a stride that closed at this
    frame). ``frontend_s`` and ``backend_s`` are the older two-way split of the same time."""
    estimate: FrameEstimate | None = None
    """The back end's own record of the frame (graph variants)."""
    registered_to: int | None = None
    """The frame this one was registered against (graph variants: the stride's keyframe,
    :mod:`graph_slam.pipelines.keyframe`); None when no registration was tried."""
    terrain: TerrainView | None = None
    """The stride's elevation grid after this frame (stride frame; docs/terrain.md): on the
    output ``add_frame`` returns only (``PipelineResults.frames`` keep None: memory)."""

    @property
    def covariance(self) -> np.ndarray | None:
        """6×6 marginal covariance of ``stride_T_camera`` (camera local, rotation first); None
        for the baseline (no estimator covariance) and with ``backend.covariances`` off."""
        return None if self.estimate is None else self.estimate.covariance

    @property
    def has_pose(self) -> bool:
        return self.stride_T_camera is not None


@dataclass(eq=False)
class BaselineStride:
    """The thesis baseline's own record of a stride (it has no back end): what
    :class:`StrideOutput` reads, as the graph variants' :class:`StrideSummary` holds it."""

    index: int
    start: str
    world_T_stride: np.ndarray
    frame_indices: list[int]
    smoothed_stride_T_camera: np.ndarray
    """Its online poses (the baseline has no smoother); NaN where it has no pose."""
    flags: tuple[str, ...]
    n_registered: int


@dataclass(eq=False)
class StrideOutput:
    """One stride: the pipeline's record of it, read through (the back end's
    :class:`StrideSummary` for the graph variants, updated in place when a deferred or
    settling smoothing finishes; :class:`BaselineStride` for the baseline), its terrain maps
    and grids."""

    summary: StrideSummary | BaselineStride
    """The stride's own record (graph variants: the back end's)."""
    terrain: StrideTerrain | None = None
    """The stride's terrain maps from its online and smoothed poses (``terrain.enabled``)."""
    online_grid: TerrainView | None = None
    """The per-frame elevation grid as it stood at the stride's last frame."""
    smoothed_grid: TerrainView | None = None
    """The stride's final grid: re-fused from the smoothed poses; the online grid when no
    clouds were kept for it (``terrain.online.keep_clouds: false``) and for the baseline."""
    stop_reason: str | None = None
    """Baseline: why registration stopped in this stride (None: it did not)."""
    grid_frames: tuple[int, int] = (0, 0)
    """Frames fused into the online grid and frames held back by its settling gate
    (``terrain.online.max_pose_sigma_m``, :mod:`graph_slam.terrain.grid.live`)."""

    @property
    def index(self) -> int:
        return self.summary.index

    @property
    def start(self) -> str:
        return self.summary.start

    @property
    def world_T_stride(self) -> np.ndarray:
        return self.summary.world_T_stride

    @property
    def frame_indices(self) -> list[int]:
        return self.summary.frame_indices

    @property
    def smoothed_stride_T_camera(self) -> np.ndarray:
        """len(frame_indices)×4×4; NaN where the pipeline has no pose."""
        return self.summary.smoothed_stride_T_camera

    @property
    def grid_stride_T_camera(self) -> np.ndarray:
        """The poses that placed the final grid (``smoothed_grid``): the online ones when it
        is the online grid (no clouds kept: the real-time preset), else the smoothed ones. A
        toe path measured against that grid is placed by the same poses, so that their common
        error cancels in the clearance (docs/terrain.md, "Toe clearance")."""
        online = getattr(self.summary, "online_stride_T_camera", None)
        grid = self.smoothed_grid
        if online is not None and grid is not None and grid is self.online_grid:
            return np.asarray(online)
        return self.summary.smoothed_stride_T_camera

    @property
    def flags(self) -> tuple[str, ...]:
        return self.summary.flags

    @property
    def n_registered(self) -> int:
        """Frames with a registration taken (graph variants: accepted by the gate)."""
        return self.summary.n_registered


@dataclass(eq=False)
class PipelineResults:
    """Everything one ``run_session`` produced."""

    variant: Variant
    frames: list[FrameOutput] = field(default_factory=list)
    strides: list[StrideOutput] = field(default_factory=list)
    covariances: np.ndarray | None = None
    """N×6×6 online marginal covariances (camera local, rotation first), on request."""
    backend: Results | None = None
    """The back end's own :class:`graph_slam.backend.Results` (graph variants)."""
    config: dict[str, Any] = field(default_factory=dict)
    counts: dict[str, int] = field(default_factory=dict)
    frames_released: int = 0
    """Frames no longer in ``frames`` (``keep_frames``): ``frames[i]`` is frame
    ``frames_released + i``."""
    with_pose_released: int = 0

    @property
    def n_frames(self) -> int:
        """Frames processed, kept or released."""
        return self.frames_released + len(self.frames)

    @property
    def n_with_pose(self) -> int:
        return self.with_pose_released + int(sum(f.has_pose for f in self.frames))

    def release_frames(self, keep: int | None) -> None:
        """Keep about the ``keep`` latest frame records (None: all; ``PipelineConfig.
        keep_frames``): a controller's memory stays flat over hours."""
        released = release_oldest(self.frames, keep)
        self.frames_released += len(released)
        self.with_pose_released += sum(f.has_pose for f in released)

    @property
    def t_s(self) -> np.ndarray:
        return np.array([f.t_s for f in self.frames])

    def release_grids(self, keep: int | None) -> None:
        """Drop the elevation grids of all but the ``keep`` latest strides (None: keep all;
        ``terrain.online.keep_stride_grids``): a long run's memory stays flat."""
        if keep is None:
            return
        for stride in self.strides[: max(0, len(self.strides) - keep)]:
            stride.online_grid = stride.smoothed_grid = None

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

    def poses(self, kind: str) -> np.ndarray:
        """``stride_T_camera`` of every frame, ``kind`` ``online`` or ``smoothed``."""
        return self.online_stride_T_camera if kind == "online" else self.smoothed_stride_T_camera

    def timings_ms(self) -> dict[str, float]:
        """Median and 95th percentile of the per-frame processing time (front + back end)."""
        total = np.array([f.frontend_s + f.backend_s + f.terrain_s for f in self.frames]) * 1e3
        if total.size == 0:
            return {"median": float("nan"), "p95": float("nan")}
        return {"median": float(np.median(total)), "p95": float(np.percentile(total, 95))}

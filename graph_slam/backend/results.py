"""Result containers of the back end: per-frame estimates, per-stride summaries, all of a run."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from graph_slam.backend.gating import GateDecision


@dataclass(frozen=True, eq=False)
class FrameEstimate:
    """The online (causal) estimate of one frame, right after its iSAM2 update."""

    frame_index: int
    stride_index: int
    k: int
    """Index of the frame within its stride (0 = the stride's first state)."""
    t_s: float
    stride_T_camera: np.ndarray
    world_T_camera: np.ndarray
    flags: tuple[str, ...]
    """e.g. ``imu_gap``, ``icp_rejected``, ``factor_dropped:icp``, ``first_stride``."""
    gate: GateDecision | None
    kinematic_factor: bool
    imu_factor: bool
    update_s: float
    covariance: np.ndarray | None = None
    """6×6 marginal covariance of ``stride_T_camera`` (camera local, rotation first)."""
    stride_start: bool = False
    """True for a stride's first state (``k == 0``: the anchor, no ICP across the strike)."""


@dataclass(eq=False)
class StrideSummary:
    """One stride: its frame, smoothed poses, flags and counts."""

    index: int
    t_start_s: float
    t_end_s: float
    start: str
    """How the stride started: ``first_stride``, ``foot_strike`` (flag ``no_anchor`` when the
    strike had no kinematic anchor) or ``missed_foot_strike``."""
    world_T_stride: np.ndarray
    frame_indices: list[int]
    t_s: np.ndarray
    online_stride_T_camera: np.ndarray
    smoothed_stride_T_camera: np.ndarray
    smoothed_covariances: np.ndarray | None
    flags: tuple[str, ...]
    n_icp_accepted: int
    n_icp_rejected: int
    n_kinematic: int
    n_imu_gaps: int
    dropped_factors: list[str]
    smoothing_s: float
    velocity_end_m_s: np.ndarray
    bias_end: np.ndarray
    """Accelerometer (m/s²) then gyro (rad/s) bias at the stride's last frame."""

    @property
    def smoothed_world_T_camera(self) -> np.ndarray:
        return self.world_T_stride @ self.smoothed_stride_T_camera

    @property
    def n_registered(self) -> int:
        """Frames whose registration the gate accepted (``StrideOutput.n_registered``)."""
        return self.n_icp_accepted

    @property
    def flagged(self) -> bool:
        return bool(self.flags)


def release_oldest(frames: list, keep: int | None) -> list:
    """Remove from ``frames`` all but the ``keep`` latest when it holds twice as many (the
    removal amortised over ``keep`` frames); the removed ones, oldest first (None: none)."""
    if keep is None or len(frames) <= 2 * keep:
        return []
    released = frames[: len(frames) - keep]
    del frames[: len(frames) - keep]
    return released


@dataclass(eq=False)
class Results:
    """Everything a run produced, frame by frame and stride by stride."""

    frames: list[FrameEstimate] = field(default_factory=list)
    strides: list[StrideSummary] = field(default_factory=list)
    imu_counts: dict[str, int] = field(default_factory=dict)
    frames_released: int = 0
    """Frames no longer in ``frames`` (``release_frames``): ``frames[i]`` is frame
    ``frames_released + i``."""

    @property
    def n_frames(self) -> int:
        """Frames added, kept or released."""
        return self.frames_released + len(self.frames)

    def release_frames(self, keep: int | None) -> None:
        """Keep about the ``keep`` latest frames' records (None: all; ``keep_frames``)."""
        self.frames_released += len(release_oldest(self.frames, keep))

    @property
    def t_s(self) -> np.ndarray:
        return np.array([f.t_s for f in self.frames])

    @property
    def online_world_T_camera(self) -> np.ndarray:
        return np.array([f.world_T_camera for f in self.frames]).reshape(-1, 4, 4)

    @property
    def online_stride_T_camera(self) -> np.ndarray:
        return np.array([f.stride_T_camera for f in self.frames]).reshape(-1, 4, 4)

    def _smoothed(self, world: bool) -> np.ndarray:
        out = np.full((len(self.frames), 4, 4), np.nan)
        for s in self.strides:
            poses = s.smoothed_world_T_camera if world else s.smoothed_stride_T_camera
            out[s.frame_indices] = poses
        return out

    @property
    def smoothed_world_T_camera(self) -> np.ndarray:
        """N×4×4, NaN for frames of a stride not yet closed."""
        return self._smoothed(True)

    @property
    def smoothed_stride_T_camera(self) -> np.ndarray:
        return self._smoothed(False)

    @property
    def stride_index(self) -> np.ndarray:
        return np.array([f.stride_index for f in self.frames], dtype=int)

    @property
    def gate_reasons(self) -> list[str | None]:
        return [f.gate.reason if f.gate is not None else None for f in self.frames]

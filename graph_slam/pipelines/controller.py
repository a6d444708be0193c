"""What a prosthesis controller reads from the pipeline at every frame (causal).

:class:`ControllerTap` wraps any :class:`~graph_slam.pipelines.protocol.Pipeline` (it is one
itself) and, after each frame, reads the frame's output into a :class:`ControllerReadout`:

- **gait phase**: ``stance`` while the foot is loaded, ``swing`` after the toe-off, with the
  fraction of the predicted stance elapsed; ``none`` before the first foot strike;
- **obstacle ahead**: the nearest box of ``FrameOutput.terrain`` whose leading edge lies ahead
  of the toe (:meth:`graph_slam.terrain.grid.view.TerrainView.obstacles_ahead`): its distance
  from the toe and its height, with σ (stride frame, metres), and whether it is seen whole;
- **time left to toe-off**: the stance duration predicted from the strides seen so far (the
  mean of the last ``history`` stances, each from its foot strike to the first frame seen
  unloaded) minus the time since this stride's foot strike; NaN before one stance was seen
  and after the toe-off.

Nothing is read ahead: the tap sees only the calls the pipeline sees, in their order.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from graph_slam.pipelines.results import FrameOutput, PipelineResults


@dataclass(frozen=True)
class ControllerReadout:
    """One frame as a controller sees it (see the module docstring)."""

    frame_index: int
    t_s: float
    stride_index: int
    phase: str
    obstacle_distance_m: float = float("nan")
    obstacle_distance_sigma_m: float = float("nan")
    obstacle_height_m: float = float("nan")
    obstacle_height_sigma_m: float = float("nan")
    toe_off_in_s: float = float("nan")
    has_pose: bool = False
    obstacle_whole: bool = False
    """The box is seen whole (else its dimensions are those of the part seen)."""
    feature: str = ""
    """The nearest stair, curb or ramp ahead in words
    (:meth:`graph_slam.terrain.features.model.TerrainFeatures.summary`)."""
    clearance_m: float = float("nan")
    """Stance: the coming swing's predicted toe clearance
    (:func:`graph_slam.terrain.features.prediction.predict_clearance`)."""
    clearance_warning: bool = False

    def line(self) -> str:
        """A fixed-width line: time, stride, phase, obstacle ahead, time left to toe-off."""
        if math.isfinite(self.obstacle_distance_m):
            part = "" if self.obstacle_whole else " (part seen)"
            obstacle = (
                f"box {self.obstacle_distance_m * 100:5.1f}±{self.obstacle_distance_sigma_m * 100:.1f}"
                f" cm ahead, {self.obstacle_height_m * 100:4.1f}±"
                f"{self.obstacle_height_sigma_m * 100:.1f} cm high{part}"
            )
        else:
            obstacle = "no box ahead"
        toe = (
            f"toe-off in {self.toe_off_in_s * 1e3:4.0f} ms"
            if math.isfinite(self.toe_off_in_s)
            else "toe-off in    ? ms"
        )
        pose = "" if self.has_pose else "  (no pose)"
        extra = f"  {self.feature}" if self.feature else ""
        if math.isfinite(self.clearance_m):
            warn = "  WARNING: low clearance" if self.clearance_warning else ""
            extra += f"  clearance {self.clearance_m * 100:.1f} cm{warn}"
        return (
            f"t={self.t_s:7.3f} s  stride {self.stride_index:2d}  {self.phase:<12} {toe}  "
            f"{obstacle}{extra}{pose}"
        )


class ControllerTap:
    """A pipeline that forwards every call and keeps the controller's readout of each frame."""

    def __init__(self, pipeline, history: int = 3) -> None:
        self.pipeline = pipeline
        self.variant = pipeline.variant
        self.history = history
        self.readouts: list[ControllerReadout] = []
        self._strike_s: float | None = None
        self._loaded = False
        self._stances_s: list[float] = []

    def add_imu(self, t_s, gyro_rad_s, accel_m_s2) -> None:
        self.pipeline.add_imu(t_s, gyro_rad_s, accel_m_s2)

    def add_joints(self, t_s, knee_rad, ankle_rad) -> None:
        self.pipeline.add_joints(t_s, knee_rad, ankle_rad)

    def foot_strike(self, t_s: float) -> None:
        self.pipeline.foot_strike(t_s)
        self._strike_s = float(t_s)

    def add_frame(self, frame, foot_loaded: bool) -> FrameOutput:
        out = self.pipeline.add_frame(frame, foot_loaded)
        if self._loaded and not foot_loaded and self._strike_s is not None:
            self._stances_s.append(float(frame.t_s) - self._strike_s)  # toe-off seen here
        self._loaded = bool(foot_loaded)
        self.readouts.append(self._readout(out, foot_loaded))
        return out

    def _readout(self, out: FrameOutput, loaded: bool) -> ControllerReadout:
        stance = np.mean(self._stances_s[-self.history :]) if self._stances_s else float("nan")
        if self._strike_s is None:
            phase, toe = "none", float("nan")
        elif loaded:
            since = out.t_s - self._strike_s
            toe = float(stance - since)
            phase = "stance" if not math.isfinite(stance) else f"stance {since / stance:4.0%}"
        else:
            phase, toe = "swing", float("nan")
        fields = {}
        ahead = () if out.terrain is None else out.terrain.obstacles_ahead()
        if ahead:
            o = ahead[0]
            fields = dict(
                obstacle_distance_m=o.distance_m,
                obstacle_distance_sigma_m=o.leading_edge_sigma_m,
                obstacle_height_m=o.height_m,
                obstacle_height_sigma_m=o.height_sigma_m,
                obstacle_whole=o.complete,
            )
        if out.terrain is not None:
            from graph_slam.terrain.features.prediction import predict_clearance

            fields["feature"] = out.terrain.features_ahead().summary(out.terrain.toe_x_m)
            if loaded:
                c = predict_clearance(out.terrain)
                fields["clearance_m"], fields["clearance_warning"] = c.min_m, c.warning
        return ControllerReadout(
            out.frame_index, out.t_s, out.stride_index, phase, toe_off_in_s=toe,
            has_pose=out.has_pose, **fields,
        )  # fmt: skip

    def finish(self) -> PipelineResults:
        return self.pipeline.finish()

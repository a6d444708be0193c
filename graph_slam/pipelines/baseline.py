"""The thesis pipeline (Shah 2021, Ch. 3.3-3.4), reproduced as the baseline (variant ``icp``).

At each foot strike the odometry is reset from the leg kinematics (encoders ->
``foot_T_camera``, the IMU's gravity for roll and pitch: :func:`kinematics.stride_frame.
stride_T_camera`) and the global map is reset to the current cloud placed at that pose. Every
later frame is registered to the global map by multi-scale (3 levels: 4, 2, 1 cm) colored ICP
(point-to-plane for depth-only sensors), with the latest odometry as the initial guess; the
result is the new odometry and the registered cloud is fused into the map. Fusion: the thesis
averages points matched by ICP; here every point falls into a voxel of a grid fixed in the
stride frame and each voxel keeps the running mean (:class:`graph_slam.frontend.LocalMap`):
points that correspond (within a voxel) are averaged, the grid does not move between frames.
When a registration's fitness drops below ``stop_fitness`` (0.3) registration stops for the
rest of the stride (the thesis halted there); every later frame is "not registered" with the
reason. A failed registration is never reported as a pose.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from graph_slam.errors import RegistrationError
from graph_slam.frontend import LocalMap, build_pyramid, register
from graph_slam.pipelines.config import PipelineConfig
from graph_slam.pipelines.protocol import PipelineBase, frame_cloud, sensor_registration
from graph_slam.pipelines.results import (
    BaselineStride,
    FrameOutput,
    PipelineResults,
    StrideOutput,
)
from graph_slam.pipelines.stages import StageTimer
from graph_slam.session.records import CameraIntrinsics, RgbdFrame
from graph_slam.strides.joints import JointBuffer
from graph_slam.strides.kinematics import imu_up_in_model
from graph_slam.variants import Variant

log = logging.getLogger(__name__)


@dataclass
class _OpenStride:
    """The baseline's state within one stride."""

    t0_s: float
    frames: list[int] = field(default_factory=list)
    poses: list[np.ndarray] = field(default_factory=list)
    n_registered: int = 0
    stop_reason: str | None = None
    """Why registration stopped (None: it goes on)."""
    odometry: np.ndarray | None = None
    """The last registered ``stride_T_camera`` (the next registration's initial guess)."""


class ThesisBaseline(PipelineBase):
    """Variant ``icp``: the thesis's reset-and-register pipeline (see the module docstring)."""

    def __init__(
        self,
        config: PipelineConfig,
        intrinsics: CameraIntrinsics,
        camera_T_imu: np.ndarray,
        leg_model,
        has_color: bool = True,
    ) -> None:
        # the baseline's stride frames are not linked (its world frame restarts at every
        # reset): no carry across the strike; no covariance (depth noise + fallback pose σ);
        # no smoothed poses, so no clouds kept for a re-fusion
        super().__init__(
            config, Variant.ICP, intrinsics, camera_T_imu, link_strides=False, refuse=False
        )
        self.registration = sensor_registration(config.baseline.registration, has_color)
        self._pixel_step = config.baseline.pixel_step_for(intrinsics.width_px)
        self.leg_model = leg_model
        self.has_color = has_color
        self.joints = JointBuffer(leg_model)
        self._map: LocalMap | None = None
        self._stride: _OpenStride | None = None
        self._pending_strike = False
        self._world_T_stride = np.eye(4)

    # ------------------------------------------------------------------ streams
    def add_imu(self, t_s, gyro_rad_s, accel_m_s2) -> None:
        """The IMU serves the reset's gravity (roll and pitch) only."""
        self.gravity.add_imu(t_s, gyro_rad_s, accel_m_s2)

    def add_joints(self, t_s, knee_rad, ankle_rad) -> None:
        """Encoder samples for the reset (checked and counted by :class:`JointBuffer`)."""
        self.joints.add(t_s, knee_rad, ankle_rad)

    def foot_strike(self, t_s: float) -> None:
        t_s = self.strike_clock.strike(t_s)
        self._close_stride()
        self.gravity.foot_strike(t_s)
        self._pending_strike = True

    # ------------------------------------------------------------------ reset
    def _reset_pose(self, t_s: float) -> tuple[np.ndarray | None, str]:
        """The thesis's odometry reset: ``stride_T_camera`` from encoders and IMU gravity."""
        from kinematics.errors import KinematicsError
        from kinematics.stride_frame import stride_T_camera

        if not self.joints.t_s.size:
            return None, "no joint encoders"
        q = self.joints.q_at(t_s)
        self.joints.drop_before(t_s - 1.0)  # only resets read the encoders
        if q is None:
            return None, "no encoder sample around the foot strike"
        up = None
        g = self.gravity.up_at(t_s, self.gravity.window_before(t_s))
        if g is not None:
            up = imu_up_in_model(self.leg_model, self.camera_T_imu, g)
        try:
            anchor = stride_T_camera(self.leg_model, q, up_in_imu=up)
        except KinematicsError as err:
            return None, f"kinematics: {err}"
        return anchor.stride_T_camera, "reset"

    # ------------------------------------------------------------------ frames
    def add_frame(self, frame: RgbdFrame, foot_loaded: bool) -> FrameOutput:
        self.strike_clock.frame(frame, self.intrinsics)
        index = self.results.n_frames
        timer = StageTimer()
        with timer("cloud"):
            cloud = frame_cloud(
                frame, self.intrinsics, self.cfg.cloud, self.has_color, self._pixel_step
            )
        with timer("registration"):  # reset or map pyramid + ICP + fusion
            pose, status, fitness = self._pose(index, frame.t_s, cloud)
        frontend_s = timer.total_s
        stride_index = len(self.results.strides) if self._stride is not None else -1
        view = None
        with timer("terrain"):
            if self._stride is not None:
                self.terrain.add_frame(index, frame)
                with timer("terrain_online"):
                    view = self.live_terrain.frame(index, frame, stride_index, pose, pose, None)
        out = FrameOutput(
            frame_index=index,
            stride_index=stride_index,
            t_s=float(frame.t_s),
            stride_T_camera=pose,
            world_T_camera=None if pose is None else self._world_T_stride @ pose,
            status=status,
            foot_loaded=foot_loaded,
            frontend_s=frontend_s,
            backend_s=0.0,
            fitness=fitness,
            terrain_s=timer.get("terrain"),
            stages_s=timer.stages_s,
            terrain=view,
        )
        return self._record(out)

    def _pose(self, index: int, t_s: float, cloud) -> tuple[np.ndarray | None, str, float]:
        """The frame's pose (the reset at a new stride, else its registration to the map),
        its status and fitness; the frame joins the open stride."""
        pose: np.ndarray | None = None
        fitness = float("nan")
        if self._pending_strike:
            self._pending_strike = False
            self._start_stride(t_s)
            pose, status = self._reset_pose(t_s)
            if pose is None:
                self._stride.stop_reason = f"no odometry reset ({status})"
                status = f"not_registered: {self._stride.stop_reason}"
            else:
                self._map.insert(cloud, pose)
                self._stride.odometry = pose
        elif self._stride is None:
            status = "not_registered: before the first foot strike"
        elif self._stride.stop_reason is not None:
            status = f"not_registered: stopped ({self._stride.stop_reason})"
        else:
            pose, status, fitness = self._register(cloud)
        if pose is not None:
            self._stride.n_registered += 1
        if self._stride is not None:
            self._stride.frames.append(index)
            self._stride.poses.append(np.full((4, 4), np.nan) if pose is None else pose)
        self.gravity.drop_before(t_s - self.gravity.keep_s)
        return pose, status, fitness

    def _register(self, cloud) -> tuple[np.ndarray | None, str, float]:
        bc = self.cfg.baseline
        s = self._stride
        target = build_pyramid(self._map.cloud(), self.registration)
        try:
            r = register(cloud, target, self.registration, s.odometry)
        except RegistrationError as err:
            fitness = float("nan") if err.fitness is None else float(err.fitness)
            reason = f"{err.reason.value}: {err.detail}"
            if bc.stop_on_any_failure or (np.isfinite(fitness) and fitness < bc.stop_fitness):
                s.stop_reason = reason
            return None, f"not_registered: {reason}", fitness
        if r.fitness < bc.stop_fitness:
            s.stop_reason = f"low_fitness: fitness {r.fitness:.3f} < {bc.stop_fitness}"
            return None, f"not_registered: {s.stop_reason}", r.fitness
        s.odometry = r.target_T_source
        self._map.insert(cloud, r.target_T_source)
        # the thesis takes the pose either way; the reports count a registration that held
        # fewer than six directions (the degeneracy test, docs/frontend.md) as partial
        dof = r.degeneracy.dof
        return r.target_T_source, "registered" if dof == 6 else f"partial: {dof} DoF", r.fitness

    # ------------------------------------------------------------------ strides
    def _start_stride(self, t_s: float) -> None:
        self._map = LocalMap(self.cfg.baseline.map_voxel_m, with_colors=self.has_color)
        self._stride = _OpenStride(t0_s=t_s)

    def _close_stride(self) -> None:
        s = self._stride
        if s is None:
            return
        index = len(self.results.strides)
        poses = np.array(s.poses).reshape(-1, 4, 4)
        grid = self.live_terrain.close(index)
        self.results.strides.append(
            StrideOutput(
                BaselineStride(
                    index=index,
                    start="foot_strike",
                    world_T_stride=self._world_T_stride.copy(),
                    frame_indices=list(s.frames),
                    smoothed_stride_T_camera=poses,
                    flags=("registration_stopped",) if s.stop_reason else (),
                    n_registered=s.n_registered,
                ),
                terrain=self.terrain.close_stride(index, s.frames, poses, None),
                online_grid=grid,
                smoothed_grid=grid,  # the baseline's smoothed poses are its online ones
                stop_reason=s.stop_reason,
            )
        )
        self.results.release_grids(self.live_terrain.cfg.keep_stride_grids)
        self._stride = None
        self._map = None

    def finish(self) -> PipelineResults:
        self._close_stride()
        n, reg = self.results.n_frames, self.results.n_with_pose
        self.results.counts = {
            "frames": n,
            "with_pose": reg,
            "without_pose": n - reg,
            **{f"joints_{k}": v for k, v in self.joints.counts.items()},
            **self.strike_clock.counts(),
        }
        return self.results

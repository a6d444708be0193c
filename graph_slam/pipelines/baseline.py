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
import time

import numpy as np

from graph_slam.errors import RegistrationError
from graph_slam.frontend import LocalMap, build_pyramid, register
from graph_slam.pipelines.config import PipelineConfig
from graph_slam.pipelines.protocol import frame_cloud, sensor_registration
from graph_slam.pipelines.results import FrameOutput, PipelineResults, StrideOutput
from graph_slam.session.records import CameraIntrinsics, RgbdFrame
from graph_slam.strides.kinematics import imu_up_in_model
from graph_slam.strides.streams import gravity_up

log = logging.getLogger(__name__)


class ThesisBaseline:
    """Variant ``icp``: the thesis's reset-and-register pipeline (see the module docstring)."""

    variant = "icp"

    def __init__(
        self,
        config: PipelineConfig,
        intrinsics: CameraIntrinsics,
        camera_T_imu: np.ndarray,
        leg_model,
        has_color: bool = True,
    ) -> None:
        self.cfg = config
        bc = config.baseline
        reg = sensor_registration(bc.registration, has_color)
        self.registration = reg
        self.intrinsics = intrinsics
        self.camera_T_imu = np.asarray(camera_T_imu, float)
        self.leg_model = leg_model
        self.has_color = has_color
        self._imu: list[tuple[np.ndarray, np.ndarray]] = []
        self.streams = None  # inputs.Streams, set by run_session (gravity at resets)
        self._joints: list[np.ndarray] = []
        self.results = PipelineResults(variant="icp", config=config.model_dump(mode="json"))
        self._map: LocalMap | None = None
        self._stride: dict | None = None
        self._pending_strike = False
        self._world_T_stride = np.eye(4)

    # ------------------------------------------------------------------ streams
    def add_imu(self, t_s, gyro_rad_s, accel_m_s2) -> None:
        t = np.ravel(t_s)
        a = np.asarray(accel_m_s2, float).reshape(-1, 3)
        good = np.isfinite(t) & np.isfinite(a).all(axis=1)
        self._imu.append((t[good], a[good]))

    def add_joints(self, t_s, knee_rad, ankle_rad) -> None:
        block = np.column_stack([np.ravel(t_s), np.ravel(knee_rad), np.ravel(ankle_rad)])
        self._joints.append(block[np.isfinite(block).all(axis=1)])

    def foot_strike(self, t_s: float) -> None:
        self._close_stride()
        self._pending_strike = True

    # ------------------------------------------------------------------ reset
    def _reset_pose(self, t_s: float) -> tuple[np.ndarray | None, str]:
        """The thesis's odometry reset: ``stride_T_camera`` from encoders and IMU gravity."""
        from kinematics.errors import KinematicsError
        from kinematics.stride_frame import stride_T_camera

        if not self._joints:
            return None, "no joint encoders"
        j = np.concatenate(self._joints)
        if not j[0, 0] <= t_s <= j[-1, 0]:
            return None, "no encoder sample around the foot strike"
        q = np.array([np.interp(t_s, j[:, 0], j[:, 1]), np.interp(t_s, j[:, 0], j[:, 2])])
        up = None
        if self.streams is not None:
            w = self.streams.window_before(t_s, self.cfg.gravity_window_s)
            g = gravity_up(self.streams, t_s, w)
            if g is not None:
                up = imu_up_in_model(self.leg_model, self.camera_T_imu, g)
        try:
            anchor = stride_T_camera(self.leg_model, q, up_in_imu=up)
        except KinematicsError as err:
            return None, f"kinematics: {err}"
        return anchor.stride_T_camera, "reset"

    # ------------------------------------------------------------------ frames
    def add_frame(self, frame: RgbdFrame, foot_loaded: bool) -> FrameOutput:
        t0 = time.perf_counter()
        index = len(self.results.frames)
        cloud = frame_cloud(frame, self.intrinsics, self.cfg.cloud, self.has_color)
        pose: np.ndarray | None = None
        fitness = float("nan")
        if self._pending_strike:
            self._pending_strike = False
            self._start_stride(frame.t_s)
            pose, status = self._reset_pose(frame.t_s)
            if pose is None:
                self._stride["stop_reason"] = f"no odometry reset ({status})"
                status = f"not_registered: {self._stride['stop_reason']}"
            else:
                self._map.insert(cloud, pose)
                self._stride["odometry"] = pose
        elif self._stride is None:
            status = "not_registered: before the first foot strike"
        elif self._stride["stop_reason"] is not None:
            status = f"not_registered: stopped ({self._stride['stop_reason']})"
        else:
            pose, status, fitness = self._register(cloud)
        if pose is not None:
            self._stride["n_registered"] += 1
        if self._stride is not None:
            self._stride["frames"].append(index)
            self._stride["poses"].append(np.full((4, 4), np.nan) if pose is None else pose)
        out = FrameOutput(
            frame_index=index,
            stride_index=len(self.results.strides) if self._stride is not None else -1,
            t_s=float(frame.t_s),
            stride_T_camera=pose,
            world_T_camera=None if pose is None else self._world_T_stride @ pose,
            status=status,
            foot_loaded=foot_loaded,
            frontend_s=time.perf_counter() - t0,
            backend_s=0.0,
            fitness=fitness,
        )
        self.results.frames.append(out)
        return out

    def _register(self, cloud) -> tuple[np.ndarray | None, str, float]:
        bc = self.cfg.baseline
        s = self._stride
        target = build_pyramid(self._map.cloud(), self.registration)
        try:
            r = register(cloud, target, self.registration, s["odometry"])
        except RegistrationError as err:
            fitness = float("nan") if err.fitness is None else float(err.fitness)
            reason = f"{err.reason.value}: {err.detail}"
            if bc.stop_on_any_failure or (np.isfinite(fitness) and fitness < bc.stop_fitness):
                s["stop_reason"] = reason
            return None, f"not_registered: {reason}", fitness
        if r.fitness < bc.stop_fitness:
            s["stop_reason"] = f"low_fitness: fitness {r.fitness:.3f} < {bc.stop_fitness}"
            return None, f"not_registered: {s['stop_reason']}", r.fitness
        s["odometry"] = r.target_T_source
        self._map.insert(cloud, r.target_T_source)
        return r.target_T_source, "registered", r.fitness

    # ------------------------------------------------------------------ strides
    def _start_stride(self, t_s: float) -> None:
        self._map = LocalMap(self.cfg.baseline.map_voxel_m, with_colors=self.has_color)
        self._stride = {
            "t0": t_s,
            "frames": [],
            "poses": [],
            "n_registered": 0,
            "stop_reason": None,
            "odometry": None,
        }

    def _close_stride(self) -> None:
        s = self._stride
        if s is None:
            return
        points = colors = None
        if self.cfg.baseline.keep_maps and self._map is not None and len(self._map):
            c = self._map.cloud()
            points, colors = c.points_m, c.colors
        self.results.strides.append(
            StrideOutput(
                index=len(self.results.strides),
                start="foot_strike",
                world_T_stride=self._world_T_stride.copy(),
                frame_indices=list(s["frames"]),
                smoothed_stride_T_camera=np.array(s["poses"]).reshape(-1, 4, 4),
                n_registered=s["n_registered"],
                flags=("registration_stopped",) if s["stop_reason"] else (),
                map_points_m=points,
                map_colors=colors,
                stop_reason=s["stop_reason"],
            )
        )
        self._stride = None
        self._map = None

    def finish(self) -> PipelineResults:
        self._close_stride()
        n = len(self.results.frames)
        reg = int(sum(f.has_pose for f in self.results.frames))
        self.results.counts = {"frames": n, "with_pose": reg, "without_pose": n - reg}
        return self.results

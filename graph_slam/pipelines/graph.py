"""The factor-graph variants (``icp+imu``, ``imu+kin``, ``icp+imu+kin``): the front end's
registrations (each frame against the stride's keyframe, :mod:`graph_slam.pipelines.keyframe`)
become :class:`IcpMeasurement` s for :class:`StrideSLAM`, fed
together with the IMU, the encoders (through a :class:`kinematics.leg_model.LegModel`) and the
load cell's foot-loaded state."""

from __future__ import annotations

import dataclasses
import logging
import time

import gtsam
import numpy as np

from graph_slam.backend import StrideSLAM
from graph_slam.backend.measurements import IcpMeasurement
from graph_slam.errors import RegistrationError
from graph_slam.frontend import Cloud, build_pyramid, depth_to_cloud, register
from graph_slam.frontend.config import GicpConfig, ProjectiveConfig
from graph_slam.frontend.projective import prepare_depth, register_depth
from graph_slam.frontend.realtime import prepare_frame, register_prepared
from graph_slam.frontend.registration import RegistrationResult
from graph_slam.pipelines.config import PipelineConfig
from graph_slam.pipelines.keyframe import Keyframes
from graph_slam.pipelines.protocol import (
    frame_cloud,
    make_gravity,
    make_live_terrain,
    make_terrain,
    sensor_registration,
    with_camera_floor,
)
from graph_slam.pipelines.results import FrameOutput, PipelineResults, StrideOutput
from graph_slam.session.records import CameraIntrinsics, RgbdFrame
from graph_slam.strides.anchor import make_anchor

log = logging.getLogger(__name__)


def icp_measurement(result: RegistrationResult, source_index: int, target_index: int):
    """The back end's record of a front-end registration.

    The front end (``RegistrationResult``) reports its information in GTSAM's tangent space
    of ``BetweenFactor<Pose3>`` (right perturbation, source frame), as ``IcpMeasurement``
    wants, already zero along the directions the front end's degeneracy test found free;
    ``dof`` carries that test's count of constrained directions to the gate.
    """
    return IcpMeasurement(
        source_index=source_index,
        target_index=target_index,
        target_T_source=result.target_T_source,
        information=result.information,
        fitness=result.fitness,
        inlier_rmse_m=result.inlier_rmse_m,
        correspondences=result.correspondences,
        dof=result.degeneracy.dof,
    )


def failed_icp_measurement(err: RegistrationError, source_index: int, target_index: int):
    """A failed registration: recorded with its reason, never a zero-motion factor."""
    return IcpMeasurement(
        source_index=source_index,
        target_index=target_index,
        target_T_source=np.eye(4),
        information=np.zeros((6, 6)),
        fitness=float("nan") if err.fitness is None else float(err.fitness),
        inlier_rmse_m=float("nan"),
        correspondences=err.correspondences or 0,
        ok=False,
        reason=f"{err.reason.value}: {err.detail}",
    )


def _measured(register_now, source_index: int, target_index: int):
    """Run a registration and make it the back end's record (a failure keeps its reason and is
    never a zero-motion factor); returns ``(IcpMeasurement, fitness)``."""
    try:
        r = register_now()
    except RegistrationError as err:
        icp = failed_icp_measurement(err, source_index, target_index)
        return icp, icp.fitness
    return icp_measurement(r, source_index, target_index), r.fitness


class GraphPipeline:
    """Front end + :class:`StrideSLAM` + the up vector at foot strikes + the terrain maps."""

    def __init__(
        self,
        config: PipelineConfig,
        intrinsics: CameraIntrinsics,
        camera_T_imu: np.ndarray,
        leg_model,
        has_color: bool = True,
    ) -> None:
        self.cfg = config
        self.variant = config.variant
        self.intrinsics = intrinsics
        self.use_icp = config.backend.factors["icp"]
        self.registration = with_camera_floor(
            sensor_registration(config.graph.registration, has_color, config.graph.depth_only),
            config.graph.real_camera_floor,
        )
        self.has_color = has_color
        self.imu_guess = self._imu_guess_for(config)
        self.camera_T_imu = np.asarray(camera_T_imu, float)
        self.slam = StrideSLAM(config.backend, camera_T_imu=camera_T_imu, leg_model=leg_model)
        self.gravity = make_gravity(config)
        self.anchor = make_anchor(config, self.camera_T_imu, self.gravity)
        self.terrain = make_terrain(config, intrinsics)
        self.live_terrain = make_live_terrain(config, intrinsics)
        self.results = PipelineResults(variant=self.variant, config=config.model_dump(mode="json"))
        self.keys = Keyframes(config.graph.keyframe)
        self._prev: tuple[np.ndarray, float] | None = None  # online pose, t: the last frame
        self._prev2: tuple[np.ndarray, float] | None = None
        self._pending_strike: float | None = None

    @staticmethod
    def _imu_guess_for(config: PipelineConfig) -> bool:
        """``graph.imu_guess``; unset (None): on with the projective (realtime) registration,
        whose one scale and tight correspondence distance need the IMU's guess."""
        if config.graph.imu_guess is not None:
            return config.graph.imu_guess
        return isinstance(config.graph.registration, ProjectiveConfig)

    def add_imu(self, t_s, gyro_rad_s, accel_m_s2) -> None:
        self.slam.add_imu(t_s, gyro_rad_s, accel_m_s2)
        self.gravity.add_imu(t_s, gyro_rad_s, accel_m_s2)

    def add_joints(self, t_s, knee_rad, ankle_rad) -> None:
        self.slam.add_joints(t_s, knee_rad, ankle_rad)

    def foot_strike(self, t_s: float) -> None:
        """Note the strike; the stride is closed at the next frame (or at ``finish``), whose
        depth gives the floor for the new anchor's tilt (:meth:`_strike_with_up`)."""
        self._pending_strike = float(t_s)
        self.gravity.foot_strike(t_s)

    def _strike_with_up(self, t_frame_s: float, cloud, stages: dict):
        """Close the stride at the pending strike with the new anchor's up vector and contact
        slope (:class:`graph_slam.strides.anchor.StrideAnchor`: the IMU's up, fused with the
        plane in this frame's depth only where that plane is level). Returns the anchor."""
        t_strike, self._pending_strike = self._pending_strike, None
        anchor = self.anchor.at_strike(
            t_strike, t_frame_s, None if cloud is None else cloud.points_m
        )
        t_close = time.perf_counter()
        self.slam.foot_strike(
            t_strike,
            up_in_imu=anchor.up_in_imu,
            up_sigma_rad=anchor.sigma_rad,
            up_t_s=t_frame_s,
            contact_slope_rad=anchor.contact_slope_rad,
        )
        stages["stride_close"] = time.perf_counter() - t_close  # smoothing of the last stride
        return anchor

    def _guess(self, t_s: float) -> np.ndarray:
        """Initial ``prev_T_current``: the IMU's prediction (``graph.imu_guess``; by default
        with the projective preset), else constant velocity from the last two online poses,
        else identity."""
        if self.imu_guess:
            guess = self.slam.predict_relative(t_s)
            if guess is not None:
                return guess
        if self._prev2 is None or not self.cfg.graph.constant_velocity_guess:
            return np.eye(4)
        pose1, t1 = self._prev
        pose0, t0 = self._prev2
        xi = gtsam.Pose3.Logmap(gtsam.Pose3(np.linalg.inv(pose0) @ pose1))
        return gtsam.Pose3.Expmap(xi * (t_s - t1) / max(t1 - t0, 1e-6)).matrix()

    def _target(self, t_s: float):
        """``(keyframe index, its prepared target, keyframe_T_current guess)``, or None: a new
        stride (or nothing registered yet) has nothing to register against."""
        if self._prev is None or self._pending_strike is not None or self.keys.key is None:
            return None
        guess = self.keys.target_T_current(self._prev[0], self._guess(t_s))
        return self.keys.key.index, self.keys.key.target, guess

    def _register(self, frame: RgbdFrame, index: int, foot_loaded: bool, stages: dict):
        """The frame's cloud, its registration to the keyframe (same stride) and its
        pyramid (the next keyframe, perhaps). Returns ``(cloud, icp, pyramid, fitness)``; each
        step's time goes into ``stages``."""
        if not self.use_icp or not (self.cfg.graph.icp_in_swing or foot_loaded):
            return None, None, None, float("nan")
        if isinstance(self.registration, GicpConfig):
            return self._register_realtime(frame, index, stages)
        if isinstance(self.registration, ProjectiveConfig):
            return self._register_projective(frame, index, stages)
        t0 = time.perf_counter()
        cloud = frame_cloud(frame, self.intrinsics, self.cfg.cloud, self.has_color)
        t1 = time.perf_counter()
        stages["cloud"] = t1 - t0
        icp, fitness = None, float("nan")
        if (key := self._target(frame.t_s)) is not None:
            key_index, key_pyramid, guess = key
            icp, fitness = _measured(
                lambda: register(cloud, key_pyramid, self.registration, guess), index, key_index
            )
        t2 = time.perf_counter()
        stages["registration"] = t2 - t1
        try:
            pyramid = build_pyramid(cloud, self.registration)
        except RegistrationError:
            pyramid = None
        stages["preprocess"] = time.perf_counter() - t2
        return cloud, icp, pyramid, fitness

    def _register_realtime(self, frame: RgbdFrame, index: int, stages: dict):
        """:meth:`_register` with the real-time preset: the frame is prepared once (on the
        keyframe's grid through the guess) and is kept, as it is, as a possible next target."""
        cfg = self.registration
        t0 = time.perf_counter()
        step = cfg.pixel_step_for(self.intrinsics)
        cloud, _ = depth_to_cloud(frame, self.intrinsics, self.cfg.cloud, step)
        t1 = time.perf_counter()
        stages["cloud"] = t1 - t0
        icp, fitness = None, float("nan")
        key_index, target, guess = self._target(frame.t_s) or (None, None, None)
        grid_T_cloud = None if target is None else target.grid_T_cloud @ guess
        prepared = prepare_frame(cloud, cfg, grid_T_cloud)
        t2 = time.perf_counter()
        stages["preprocess"] = t2 - t1
        if target is not None:
            icp, fitness = _measured(
                lambda: register_prepared(prepared, target, cfg, guess), index, key_index
            )
        stages["registration"] = time.perf_counter() - t2
        return cloud, icp, prepared, fitness

    def _register_projective(self, frame: RgbdFrame, index: int, stages: dict):
        """:meth:`_register` with the projective preset: the frame is prepared once from its
        organised depth image (on the keyframe's grid through the guess) and kept, as it is,
        as a possible next target."""
        cfg = self.registration
        t0 = time.perf_counter()
        icp, fitness = None, float("nan")
        key_index, target, guess = self._target(frame.t_s) or (None, None, None)
        grid_T_cloud = None if target is None else target.grid_T_cloud @ guess
        prepared = prepare_depth(
            frame, self.intrinsics, cfg, self.cfg.cloud, grid_T_cloud, self.has_color
        )
        t1 = time.perf_counter()
        stages["cloud"] = prepared.timing_s["cloud"]
        stages["preprocess"] = t1 - t0 - stages["cloud"]
        if target is not None:
            icp, fitness = _measured(
                lambda: register_depth(prepared, target, cfg, guess), index, key_index
            )
        stages["registration"] = time.perf_counter() - t1
        return Cloud(prepared.pixel_points_m), icp, prepared, fitness

    def add_frame(self, frame: RgbdFrame, foot_loaded: bool) -> FrameOutput:
        """Register → (at a new stride) up vector and floor → graph update → keep the frame's
        map cloud; strides the back end closed get their terrain maps."""
        t0 = time.perf_counter()
        index = self.results.n_frames
        stages: dict[str, float] = {}
        cloud, icp, pyramid, fitness = self._register(frame, index, foot_loaded, stages)
        floor_flag: tuple[str, ...] = ()
        if self._pending_strike is not None:
            t_floor = time.perf_counter()
            anchor = self._strike_with_up(frame.t_s, cloud, stages)
            stages["floor"] = time.perf_counter() - t_floor - stages["stride_close"]
            floor_flag = anchor.flags
        t1 = time.perf_counter()
        est = self.slam.add_frame(frame.t_s, icp=icp, foot_loaded=foot_loaded)
        t2 = time.perf_counter()
        stages["graph"] = t2 - t1  # a missed strike's smoothing included
        self._remember(index, pyramid, est, frame.t_s)
        self._close_strides()  # those closed by this frame (a strike, or a missed one)
        if (keep := self.cfg.backend.max_deferred_strides) is not None:
            self._smooth_deferred(keep)  # the oldest queued strides, beyond the bound
        t3 = time.perf_counter()
        self.gravity.drop_before(frame.t_s - self.gravity.keep_s)
        self.terrain.add_frame(index, frame)
        t4 = time.perf_counter()
        view = self.live_terrain.frame(
            index, frame, est.stride_index, est.stride_T_camera, est.world_T_camera,
            est.covariance,
        )  # fmt: skip
        stages["terrain_online"] = time.perf_counter() - t4
        stages["terrain"] = time.perf_counter() - t3
        if t3 - t2 > 1e-4:  # the terrain maps of a stride that closed
            stages["stride_close"] = stages.get("stride_close", 0.0) + t3 - t2
        out = FrameOutput(
            frame_index=index,
            stride_index=est.stride_index,
            t_s=float(frame.t_s),
            stride_T_camera=est.stride_T_camera,
            world_T_camera=est.world_T_camera,
            status="reset" if est.stride_start else "estimated",
            foot_loaded=foot_loaded,
            frontend_s=t1 - t0,
            backend_s=t2 - t1,
            fitness=fitness,
            flags=est.flags
            + floor_flag
            + ((f"icp:{est.gate.reason}",) if est.gate is not None else ()),
            terrain_s=stages["terrain"],
            stages_s=stages,
            estimate=est,
            registered_to=None if icp is None else icp.target_index,
            terrain=view,
        )
        self.results.frames.append(dataclasses.replace(out, terrain=None))
        self.results.release_frames(self.cfg.keep_frames)
        self.slam.results.release_frames(self.cfg.keep_frames)
        return out

    def _remember(self, index: int, pyramid, est, t_s: float) -> None:
        """The keyframe (the next frame's registration target) and the constant-velocity
        history for the next frame."""
        self._prev2 = None if est.stride_start else self._prev
        self._prev = (est.stride_T_camera, t_s)
        accepted = est.gate is not None and est.gate.accepted
        self.keys.update(
            index, pyramid, est.stride_T_camera, t_s, keep=accepted and not est.stride_start
        )
        if pyramid is None:  # nothing to register the next frame against
            self._prev = None
            self._prev2 = None

    def _close_strides(self) -> None:
        """A :class:`StrideOutput` (with its terrain) for every stride the back end closed."""
        for s in self.slam.results.strides[len(self.results.strides) :]:
            deferred = "smoothing_deferred" in s.flags
            terrain = self.terrain.close_stride(
                s.index,
                s.frame_indices,
                s.online_stride_T_camera,
                s.smoothed_stride_T_camera,
                smoothed_later=deferred,
            )
            online_grid = self.live_terrain.close(s.index)
            smoothed_grid = None if deferred else self._final_grid(s, online_grid)
            self.results.strides.append(
                StrideOutput(
                    index=s.index,
                    start=s.start,
                    world_T_stride=s.world_T_stride,
                    frame_indices=list(s.frame_indices),
                    smoothed_stride_T_camera=s.smoothed_stride_T_camera,
                    n_registered=s.n_icp_accepted,
                    flags=s.flags,
                    terrain=terrain,
                    summary=s,
                    online_grid=online_grid,
                    smoothed_grid=smoothed_grid,
                )
            )
        self.results.release_grids(self.live_terrain.cfg.keep_stride_grids)

    def _final_grid(self, s, online_grid):
        """The stride's grid re-fused from its smoothed poses; without kept clouds
        (``terrain.online.keep_clouds: false``) its online grid at its last frame."""
        grid = self.live_terrain.refuse(
            s.index, s.frame_indices, s.smoothed_stride_T_camera, s.smoothed_covariances
        )
        if grid is None and not self.live_terrain.cfg.keep_clouds:
            return online_grid
        return grid

    def _smooth_deferred(self, keep: int = 0) -> None:
        """The batch smoothing of strides closed in real time (``backend.defer_smoothing``),
        oldest first until ``keep`` wait, and their maps from the smoothed poses."""
        for s in self.slam.smooth_deferred(keep):
            out = self.results.strides[s.index]
            out.smoothed_stride_T_camera = s.smoothed_stride_T_camera
            out.flags = s.flags
            if out.terrain is not None:
                out.terrain = self.terrain.fuse_smoothed(out.terrain, s.smoothed_stride_T_camera)
            out.smoothed_grid = self._final_grid(s, out.online_grid)

    def finish(self) -> PipelineResults:
        if self._pending_strike is not None:  # a strike after the last frame
            self.slam.foot_strike(self._pending_strike)
            self._pending_strike = None
        res = self.slam.finish()
        self._close_strides()
        self._smooth_deferred()
        self.results.backend = res
        if self.cfg.backend.covariances:
            self.results.covariances = np.array(
                [
                    f.covariance if f.covariance is not None else np.full((6, 6), np.nan)
                    for f in res.frames
                ]
            )
        self.results.counts = {
            "frames": self.results.n_frames,
            "with_pose": self.results.n_with_pose,
            "icp_accepted": int(sum(s.n_icp_accepted for s in res.strides)),
            "icp_rejected": int(sum(s.n_icp_rejected for s in res.strides)),
            **{f"imu_{k}": v for k, v in res.imu_counts.items()},
            **{f"joints_{k}": v for k, v in self.slam.leg.joints.counts.items()},
        }
        return self.results

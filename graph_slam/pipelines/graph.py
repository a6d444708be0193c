"""The factor-graph variants (``icp+imu``, ``imu+kin``, ``icp+imu+kin``): the front end's
registrations (each frame against the stride's keyframe, :mod:`graph_slam.pipelines.keyframe`)
become :class:`IcpMeasurement` s for :class:`StrideSLAM`, fed
together with the IMU, the encoders (through a :class:`kinematics.leg_model.LegModel`) and the
load cell's foot-loaded state.

The front end's registrations as the back end's measurements:
:mod:`graph_slam.pipelines.graph_frontend` (its names importable from here too)."""

from __future__ import annotations

import logging
import time

import gtsam
import numpy as np

from graph_slam.backend import StrideSLAM
from graph_slam.frontend.methods import OrganisedAhead
from graph_slam.pipelines.bridge import UnregisteredStride
from graph_slam.pipelines.config import PipelineConfig
from graph_slam.pipelines.graph_frontend import (  # noqa: F401 (re-exported)
    _graph_registration,
    _measured,
    failed_icp_measurement,
    icp_measurement,
    imu_guess_on,
)
from graph_slam.pipelines.keyframe import Keyframes
from graph_slam.pipelines.protocol import PipelineBase
from graph_slam.pipelines.results import FrameOutput, PipelineResults, StrideOutput
from graph_slam.pipelines.stages import StageTimer
from graph_slam.session.records import CameraIntrinsics, RgbdFrame
from graph_slam.strides.anchor import make_anchor

log = logging.getLogger(__name__)


class GraphPipeline(PipelineBase):
    """Front end + :class:`StrideSLAM` + the up vector at foot strikes + the terrain maps."""

    def __init__(
        self,
        config: PipelineConfig,
        intrinsics: CameraIntrinsics,
        camera_T_imu: np.ndarray,
        leg_model,
        has_color: bool = True,
    ) -> None:
        super().__init__(config, config.variant, intrinsics, camera_T_imu)
        self.registration = _graph_registration(config, intrinsics, has_color)
        self.has_color = has_color
        # A frame recorded without a colour image (colour slower than depth, or missing) is
        # registered with the depth-only settings, as is any frame whose keyframe has none.
        self.registration_depth_only = _graph_registration(config, intrinsics, False)
        self._uncoloured: set[int] = set()
        self._ahead = OrganisedAhead()  # frames organised before their turn (prepare_ahead)
        for registration in (self.registration, self.registration_depth_only):
            if hasattr(registration, "organise"):
                registration.ahead = self._ahead
        self.imu_guess = imu_guess_on(config, self.registration)
        self.slam = StrideSLAM(config.backend, camera_T_imu=camera_T_imu, leg_model=leg_model)
        self.anchor = make_anchor(
            config, self.camera_T_imu, self.gravity, self.slam.up_estimate,
            self.slam.velocity_change, self.slam.lateral_bias, self.slam.leg.heel_strike_up,
        )  # fmt: skip
        self.keys = Keyframes(config.graph.keyframe)
        self.unregistered = UnregisteredStride()
        self._prev: tuple[np.ndarray, float] | None = None  # online pose, t: the last frame
        self._prev2: tuple[np.ndarray, float] | None = None
        self._pending_strike: float | None = None

    def add_imu(self, t_s, gyro_rad_s, accel_m_s2) -> None:
        self.slam.add_imu(t_s, gyro_rad_s, accel_m_s2)
        self.gravity.add_imu(t_s, gyro_rad_s, accel_m_s2)

    def add_joints(self, t_s, knee_rad, ankle_rad) -> None:
        self.slam.add_joints(t_s, knee_rad, ankle_rad)

    def foot_strike(self, t_s: float) -> None:
        """Note the strike; the stride is closed at the next frame (or at ``finish``), whose
        depth gives the floor for the new anchor's tilt (:meth:`_strike_with_up`)."""
        self._pending_strike = self.strike_clock.strike(t_s)
        self.gravity.foot_strike(self._pending_strike)

    def _strike_with_up(self, t_frame_s: float, cloud, stages: dict):
        """Close the stride at the pending strike with the new anchor's up vector and contact
        slope (:class:`graph_slam.strides.anchor.StrideAnchor`: the IMU's up, fused with the
        plane in this frame's depth only where that plane is level). Returns the anchor."""
        t_strike, self._pending_strike = self._pending_strike, None
        anchor = self.anchor.at_strike(
            t_strike, t_frame_s, None if cloud is None else cloud.points_m,
            self._heel_in_camera(t_frame_s),
        )  # fmt: skip
        t_close = time.perf_counter()
        self.slam.foot_strike(
            t_strike,
            up_in_imu=anchor.up_in_imu,
            up_sigma_rad=anchor.sigma_rad,
            up_t_s=t_frame_s,
            contact_slope_rad=anchor.contact_slope_rad,
            up_assumed=anchor.assumed,
        )
        stages["stride_close"] = time.perf_counter() - t_close  # smoothing of the last stride
        return anchor

    def _heel_in_camera(self, t_s: float) -> np.ndarray | None:
        """The stance heel in the camera frame at ``t_s`` from the encoders (None: no leg
        model, no encoder sample there, or the model refuses the angles)."""
        from kinematics.errors import KinematicsError

        leg = self.slam.leg
        q = leg.q_at(t_s)
        if q is None:
            return None
        try:
            return np.linalg.inv(leg.model.foot_T_camera(q))[:3, 3]
        except KinematicsError:
            return None

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

    def _register(self, frame: RgbdFrame, index: int, foot_loaded: bool, timer: StageTimer):
        """The frame prepared once (on the keyframe's grid through the guess: its cloud, and
        the next keyframe perhaps) and registered to the keyframe (same stride), with the
        depth-only settings when the frame or its keyframe has no colour image. Returns
        ``(prepared, icp, fitness)``; stages ``cloud``, ``preprocess``, ``registration``."""
        if not self.cfg.backend.factors["icp"] or not (self.cfg.graph.icp_in_swing or foot_loaded):
            return None, None, float("nan")
        key = self._target(frame.t_s)
        registration = (
            self.registration
            if self._coloured(frame, index, None if key is None else key[0])
            else self.registration_depth_only
        )
        with timer("preprocess"):
            grid_T_cloud = None if key is None else key[1].grid_T_cloud @ key[2]
            prepared = registration.prepare(frame, grid_T_cloud)
        timer.add("cloud", prepared.timing_s["cloud"])
        timer.exclude("preprocess", "cloud")
        icp, fitness = None, float("nan")
        with timer("registration"):
            if key is not None:
                key_index, target, guess = key
                icp, fitness = _measured(
                    lambda: registration.register(prepared, target, guess), index, key_index
                )
        if registration is self.registration_depth_only and self._recolours(frame):
            with timer("preprocess"):  # its coloured cloud: the next (coloured) keyframe
                prepared = self.registration.prepare(frame, None)
            timer.exclude("preprocess", "cloud")
        return prepared, icp, fitness

    def prepare_ahead(self, frame: RgbdFrame) -> None:
        """The part of the frame's preparation that depends on the frame alone (organised
        points and normals), done now — on any thread, before its turn: the live loop does it
        as the frame is decoded — and taken by :meth:`add_frame` for the same frame (the same
        arrays: the result is the one it would compute). A frame of its kind registers with
        colour when it has a colour image (its keyframe without one: computed then)."""
        if not self.cfg.backend.factors["icp"]:
            return
        registration = (self.registration if frame.color_rgb is not None
                        else self.registration_depth_only)  # fmt: skip
        organise = getattr(registration, "organise", None)
        if organise is not None:
            self._ahead.put(organise(frame))

    def _recolours(self, frame: RgbdFrame) -> bool:
        """The frame has colour but its keyframe has none (``graph.recolour_keyframe``): it
        registers without colour, is prepared again with colour and becomes the keyframe, so
        the frames after it register with colour again."""
        return self.cfg.graph.recolour_keyframe and self.has_color and frame.color_rgb is not None

    def _coloured(self, frame: RgbdFrame, index: int, key_index: int | None) -> bool:
        """Whether frame ``index`` registers with colour: the session has colour, the frame
        has its colour image and so has its keyframe (``key_index``; None: no keyframe)."""
        if not self.has_color:
            return False
        if frame.color_rgb is None or key_index in self._uncoloured:
            if not self._recolours(frame):
                self._uncoloured.add(index)  # its cloud has no colour: a target without colour
            return False
        return True

    def _waits_for_colour(self, index: int, t_s: float) -> bool:
        """Frame ``index`` has no colour but the keyframe has: the keyframe is kept until a
        frame with colour replaces it, for at most twice the keyframe interval."""
        key = self.keys.key
        return (
            index in self._uncoloured
            and key is not None
            and key.index not in self._uncoloured
            and t_s - key.t_s < 2 * self.keys.config.interval_s
        )

    def add_frame(self, frame: RgbdFrame, foot_loaded: bool) -> FrameOutput:
        """Register → (at a new stride) up vector and floor → graph update → keep the frame's
        map cloud; strides the back end closed get their terrain maps."""
        self.strike_clock.frame(frame, self.intrinsics)
        index = self.results.n_frames
        timer = StageTimer()
        prepared, icp, fitness = self._register(frame, index, foot_loaded, timer)
        floor_flag: tuple[str, ...] = ()
        if self._pending_strike is not None:
            cloud = None if prepared is None else prepared.cloud
            with timer("floor"):
                anchor = self._strike_with_up(frame.t_s, cloud, timer.stages_s)
            timer.exclude("floor", "stride_close")
            floor_flag = anchor.flags
        frontend_s = timer.total_s
        with timer("graph"):  # a missed strike's smoothing included
            est = self.slam.add_frame(frame.t_s, icp=icp, foot_loaded=foot_loaded)
        self._remember(index, prepared, est, frame.t_s)
        with timer("stride_close") as lap:  # the maps of the strides this frame closed
            closed = self._close_strides()
            lap.keep = closed + self._smooth_deferred(self.cfg.backend.max_deferred_strides) > 0
        self.gravity.drop_before(frame.t_s - self.gravity.keep_s)
        with timer("terrain"):
            self.terrain.add_frame(index, frame)
            with timer("terrain_online"):
                view = self.live_terrain.frame(
                    index, frame, est.stride_index, est.stride_T_camera, est.world_T_camera,
                    est.covariance, self._gate_covariance(est),
                )  # fmt: skip
        icp_flag = (f"icp:{est.gate.reason}",) if est.gate is not None else ()
        icp_flag += self.unregistered.frame(
            frame.t_s, est.stride_start, est.gate is not None and est.gate.accepted
        )
        out = FrameOutput(
            frame_index=index,
            stride_index=est.stride_index,
            t_s=float(frame.t_s),
            stride_T_camera=est.stride_T_camera,
            world_T_camera=est.world_T_camera,
            status="reset" if est.stride_start else "estimated",
            foot_loaded=foot_loaded,
            frontend_s=frontend_s,
            backend_s=timer.get("graph"),
            fitness=fitness,
            flags=est.flags + floor_flag + icp_flag,
            terrain_s=timer.get("terrain"),
            stages_s=timer.stages_s,
            estimate=est,
            registered_to=None if icp is None else icp.target_index,
            terrain=view,
        )
        self.slam.results.release_frames(self.cfg.keep_frames)
        return self._record(out)

    def _gate_covariance(self, est) -> np.ndarray | None:
        """The pose covariance for the online grid's settling gate: the estimate's own, else
        (per-frame covariances off) the open stride's marginal, computed only while the gate
        still checks the stride's frames (:meth:`LiveTerrain.needs_gate`)."""
        if est.covariance is not None or not self.live_terrain.needs_gate(est.stride_index):
            return None
        return self.slam.pose_covariance(est.k)

    def _remember(self, index: int, prepared, est, t_s: float) -> None:
        """The keyframe (the next frame's registration target) and the constant-velocity
        history for the next frame."""
        self._prev2 = None if est.stride_start else self._prev
        self._prev = (est.stride_T_camera, t_s)
        accepted = est.gate is not None and est.gate.accepted
        target = prepared if prepared is not None and prepared.is_target else None
        keep = accepted and not est.stride_start
        key = self.keys.key
        if (
            self.cfg.graph.recolour_keyframe
            and key is not None
            and key.index in self._uncoloured
            and index not in self._uncoloured
        ):
            keep = False  # a coloured frame replaces a keyframe without colour
        if keep and target is not None and self._waits_for_colour(index, t_s):
            return  # the coloured keyframe stays the target (a colourless one would make
            # the frames after it register without colour too)
        self.keys.update(index, target, est.stride_T_camera, t_s, keep=keep)
        if self._uncoloured:  # only the keyframe's and later frames' colour is asked again
            oldest = index if self.keys.key is None else min(index, self.keys.key.index)
            self._uncoloured = {k for k in self._uncoloured if k >= oldest}
        if target is None:  # nothing to register the next frame against
            self._prev = None
            self._prev2 = None

    def _close_strides(self) -> int:
        """A :class:`StrideOutput` (with its terrain) for every stride the back end closed;
        returns how many."""
        closed = self.slam.results.strides[len(self.results.strides) :]
        for s in closed:
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
                StrideOutput(s, terrain, online_grid=online_grid, smoothed_grid=smoothed_grid,
                             grid_frames=self.live_terrain.counts(s.index))
            )  # fmt: skip
        self.results.release_grids(self.live_terrain.cfg.keep_stride_grids)
        return len(closed)

    def _final_grid(self, s, online_grid):
        """The stride's grid re-fused from its smoothed poses; without kept clouds
        (``terrain.online.keep_clouds: false``) its online grid at its last frame."""
        grid = self.live_terrain.refuse(
            s.index, s.frame_indices, s.smoothed_stride_T_camera, s.smoothed_covariances
        )
        if grid is None and not self.live_terrain.cfg.keep_clouds:
            return online_grid
        return grid

    def _smooth_deferred(self, keep: int | None) -> int:
        """The batch smoothing of strides closed in real time (``backend.defer_smoothing``),
        oldest first until ``keep`` wait (None: none now), and their maps from the smoothed
        poses (the stride's record, the back end's, holds them); returns how many."""
        if keep is None:
            return 0
        smoothed = self.slam.smooth_deferred(keep)
        for s in smoothed:
            out = self.results.strides[s.index]
            if out.terrain is not None:
                out.terrain = self.terrain.fuse_smoothed(out.terrain, s.smoothed_stride_T_camera)
            out.smoothed_grid = self._final_grid(s, out.online_grid)
        return len(smoothed)

    def finish(self) -> PipelineResults:
        if self._pending_strike is not None:  # a strike after the last frame
            self.slam.foot_strike(self._pending_strike)
            self._pending_strike = None
        res = self.slam.finish()
        self._close_strides()
        self._smooth_deferred(0)
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
            **self.strike_clock.counts(),
            "grid_frames_fused": int(sum(s.grid_frames[0] for s in self.results.strides)),
            "grid_frames_held": int(sum(s.grid_frames[1] for s in self.results.strides)),
        }
        return self.results

"""The streaming estimator: one factor graph per stride, re-solved at every frame.

    slam = StrideSLAM(BackendConfig(), camera_T_imu=calib.camera_T_imu)
    slam.add_imu(t_s, gyro_rad_s, accel_m_s2)          # any time, any chunk size
    est = slam.add_frame(t_s, icp=..., foot_loaded=..., kinematics=...)   # online pose
    summary = slam.foot_strike(t_s)                     # closes the stride: smoothed poses
    results = slam.finish()

Kinematic measurements (``KinematicMeasurement``: ``stride_T_camera`` from FK with its
covariance) are given per frame by the caller, or computed from ``add_joints`` samples when a
``kinematics.leg_model.LegModel`` is given (foot strike: :func:`kinematics.stride_frame.
stride_T_camera` with gravity from the IMU; stance: the struck foot's ``stride_T_foot`` held,
``foot_T_camera(q)`` from the encoders). The first frame of a stride takes the kinematic
measurement as its **anchor** (the prior that defines the stride frame) in every variant.
"""

from __future__ import annotations

import logging
import time

import gtsam
import numpy as np

from graph_slam.backend import factors
from graph_slam.backend.config import BackendConfig
from graph_slam.backend.gating import GateDecision, gate_icp
from graph_slam.backend.imu import ImuBuffer, ImuCheck
from graph_slam.backend.keys import B, V, X
from graph_slam.backend.measurements import IcpMeasurement, KinematicMeasurement
from graph_slam.backend.results import FrameEstimate, Results, StrideSummary
from graph_slam.backend.stride_graph import StrideGraph
from graph_slam.errors import EstimationError

log = logging.getLogger(__name__)


def gravity_aligned_rotation(up_in_imu: np.ndarray) -> np.ndarray:
    """``nav_R_imu`` with z along ``up_in_imu`` and zero yaw of the IMU's x axis (if possible)."""
    z = up_in_imu / np.linalg.norm(up_in_imu)  # nav z expressed in the IMU frame
    x_imu = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = x_imu - (x_imu @ z) * z
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return np.vstack([x, y, z])  # rows: nav axes in IMU coordinates -> nav_R_imu


def tilt_covariance(stride_T_camera: np.ndarray, cov: np.ndarray, sigma_rad: float) -> np.ndarray:
    """``cov`` (camera local, rotation first) with its tilt about the stride frame's x and y axes
    (through the stride origin) replaced by an independent σ ``sigma_rad``: with the stride
    frame's z from the IMU's up vector the camera's tilt error is that vector's error."""
    ad = factors.adjoint(stride_T_camera)  # right (camera) -> left (stride) coordinates
    left = ad @ cov @ ad.T
    left[:2, :] = 0.0
    left[:, :2] = 0.0
    left[0, 0] = left[1, 1] = sigma_rad**2
    inv = np.linalg.inv(ad)
    return inv @ left @ inv.T


def anchor_covariance(
    stride_T_camera: np.ndarray,
    encoder_cov: np.ndarray,
    up_sigma_rad: float,
    yaw_sigma_rad: float,
    position_sigma_m: float,
) -> np.ndarray:
    """The anchor's covariance (camera local, rotation first) when the up vector is known.

    The stride frame *is* the foot at the strike (origin at the heel, x along the foot) with z
    up: relative to it the camera is uncertain only by the encoders' FK error
    (``encoder_cov``), the up vector's tilt error (``up_sigma_rad``, about the stride x/y axes
    through the heel) and a small floor on yaw and position (``yaw_sigma_rad``,
    ``position_sigma_m``) that keeps the prior well conditioned. Where the foot landed in the
    world (the contact noise of the kinematics module) does not move the camera in this frame.
    Measured without this (the contact noise's 2° yaw and 1 cm in the anchor): the smoother
    turned whole strides by up to 1° of yaw to fit a carried-over velocity (24 mm at the stride's
    end, full-resolution normal-speed session).
    """
    ad = factors.adjoint(stride_T_camera)
    floor = np.diag(np.r_[0.0, 0.0, yaw_sigma_rad**2, np.full(3, position_sigma_m**2)])
    inv = np.linalg.inv(ad)
    cov = np.asarray(encoder_cov, float) + inv @ floor @ inv.T
    return tilt_covariance(stride_T_camera, cov, up_sigma_rad)


class StrideSLAM:
    """Per-stride factor-graph estimator (see the module docstring)."""

    def __init__(
        self,
        config: BackendConfig | None = None,
        camera_T_imu: np.ndarray | None = None,
        leg_model=None,
    ):
        self.cfg = config or BackendConfig()
        self.camera_T_imu = np.eye(4) if camera_T_imu is None else np.asarray(camera_T_imu, float)
        self.leg_model = leg_model
        self.imu = ImuBuffer(self.cfg.imu)
        self._joints: list[np.ndarray] = []
        self._graph: StrideGraph | None = None
        self._stride_start = "first_stride"
        self._pending_start: str | None = None
        self._world_T_stride = np.eye(4)
        self._stride_t0 = np.nan
        self._frame_to_k: dict[int, int] = {}
        self._frames_in_stride: list[FrameEstimate] = []
        self._stride_counts = {"icp_ok": 0, "icp_rej": 0, "kin": 0, "gap": 0}
        self._stride_T_foot: np.ndarray | None = None  # foot at strike ("foot_pose" stance)
        self._strike_up: tuple[float, np.ndarray] | None = None  # foot_strike(up_in_imu=...)
        self._heel_off = False  # contact_points stance: the heel has left the ground
        self._strike_up_sigma: float | None = None
        self._last_nav = None  # (t_s, NavEstimate, cov_pose, cov_vel, cov_bias) at stride end
        self._started_loaded = True  # the open stride's first frame had the foot loaded
        self.results = Results()
        self._frame_count = 0
        self._last_frame_t = -np.inf

    # ------------------------------------------------------------------ inputs
    def add_imu(self, t_s, gyro_rad_s, accel_m_s2) -> ImuCheck:
        """Add IMU samples (IMU frame); bad samples are rejected and counted, never used."""
        return self.imu.add(t_s, gyro_rad_s, accel_m_s2)

    def add_joints(self, t_s, knee_rad, ankle_rad) -> int:
        """Add encoder samples (used only with a leg model); returns how many were kept."""
        block = np.column_stack([np.ravel(t_s), np.ravel(knee_rad), np.ravel(ankle_rad)])
        good = np.isfinite(block).all(axis=1)
        last = self._joints[-1][-1, 0] if self._joints else -np.inf
        for i in np.flatnonzero(good):
            if block[i, 0] <= last:
                good[i] = False
            else:
                last = block[i, 0]
        if (~good).any():
            log.warning(
                "joints: %d of %d samples rejected (NaN or not increasing)",
                (~good).sum(),
                good.size,
            )
        if good.any():
            self._joints.append(block[good])
        return int(good.sum())

    def foot_strike(
        self,
        t_s: float,
        up_in_imu: np.ndarray | None = None,
        up_sigma_rad: float | None = None,
        up_t_s: float | None = None,
    ) -> StrideSummary | None:
        """A foot strike: close the current stride (smoothing); the next frame starts a new one.

        ``up_in_imu``: the up direction (e.g. a gravity estimate in m/s²) in the IMU frame at
        ``t_s``, for the new stride's anchor (roll and pitch of the stride frame). The back end
        rotates it to the first frame's time with the gyro. Default: the accelerometer mean over
        ``kinematics.gravity_window_s`` before the first frame — biased by the swing leg's
        deceleration (measured ~60° off on the simulator); pipelines pass a better estimate.
        ``up_sigma_rad``: the σ of that up vector's direction. Given, it replaces the anchor's
        roll/pitch uncertainty (the camera's tilt in the stride frame is the IMU's, whatever
        the foot contact); otherwise the kinematics' covariance (contact σ up to 5°) stays.
        ``up_t_s``: the time at which ``up_in_imu`` holds (default ``t_s``; e.g. the new
        stride's first frame when the up vector comes from the floor in its depth).
        """
        if up_sigma_rad is not None and not (np.isfinite(up_sigma_rad) and up_sigma_rad > 0):
            raise EstimationError(
                f"foot_strike: up_sigma_rad must be finite and > 0, got {up_sigma_rad!r}"
            )
        self._strike_up_sigma = None if up_in_imu is None else up_sigma_rad
        if up_in_imu is not None:
            up = np.asarray(up_in_imu, float)
            if up.shape != (3,) or not np.isfinite(up).all() or np.linalg.norm(up) < 1e-9:
                raise EstimationError(
                    f"foot_strike: up_in_imu must be a finite non-zero 3-vector, got {up_in_imu!r}"
                )
            self._strike_up = (float(t_s if up_t_s is None else up_t_s), up)
        else:
            self._strike_up = None
        summary = self._close_stride() if self._graph is not None else None
        self._pending_start = "foot_strike"
        return summary

    def finish(self) -> Results:
        """Close the open stride and return every result."""
        if self._graph is not None:
            self._close_stride()
        self.results.imu_counts = dict(self.imu.counts)
        return self.results

    # ------------------------------------------------------------------ kinematics
    def _q_at(self, t_s: float) -> np.ndarray | None:
        if not self._joints:
            return None
        j = np.concatenate(self._joints)
        if t_s < j[0, 0] or t_s > j[-1, 0]:
            return None
        return np.array([np.interp(t_s, j[:, 0], j[:, 1]), np.interp(t_s, j[:, 0], j[:, 2])])

    def _kinematics_from_joints(self, t_s: float, anchor: bool) -> KinematicMeasurement | None:
        if self.leg_model is None:
            return None
        q = self._q_at(t_s)
        if q is None:
            return None
        from kinematics.errors import KinematicsError
        from kinematics.stride_frame import stride_T_camera

        try:
            if anchor:
                up = self._up_at(t_s)
                a = stride_T_camera(self.leg_model, q, up_in_imu=self._imu_up_to_model(up))
                self._stride_T_foot = a.stride_T_foot
                cov = a.covariance
                if self._strike_up_sigma is not None and self._strike_up is not None:
                    from kinematics.stride_frame import DEFAULT_ENCODER_VAR_RAD2

                    pc = self.cfg.priors
                    cov = anchor_covariance(
                        a.stride_T_camera,
                        self.leg_model.camera_covariance(q, DEFAULT_ENCODER_VAR_RAD2),
                        self._strike_up_sigma,
                        pc.anchor_yaw_sigma_rad,
                        pc.anchor_position_sigma_m,
                    )
                return KinematicMeasurement(a.stride_T_camera, cov)
            if self._stride_T_foot is None:
                return None
            from kinematics.stride_frame import DEFAULT_ENCODER_VAR_RAD2

            cov = self.leg_model.camera_covariance(q, DEFAULT_ENCODER_VAR_RAD2, contact="foot_flat")
            return KinematicMeasurement(self._stride_T_foot @ self.leg_model.foot_T_camera(q), cov)
        except KinematicsError as err:
            log.warning("t=%.3f s: no kinematic measurement (%s)", t_s, err)
            return None

    def _up_at(self, t_s: float) -> np.ndarray | None:
        """Up in the IMU frame at ``t_s``: the caller's (``foot_strike(up_in_imu=...)``) rotated
        from the strike to ``t_s`` by the gyro, else the accelerometer mean before ``t_s``."""
        if self._strike_up is not None:
            t0, up = self._strike_up
            if t_s <= t0:
                return up
            seg = self.imu.integrate(t0, t_s, gtsam.imuBias.ConstantBias())
            if seg.ok:  # strike_R_now: up_now = strike_R_nowᵀ · up_strike
                return np.asarray(seg.pim.deltaRij().matrix()).T @ up
            log.warning("t=%.3f s: no IMU to carry the strike's up vector (%s)", t_s, seg.reason)
        w = self.cfg.kinematics.gravity_window_s
        return self.imu.mean_accel(t_s - w, t_s)

    def _predicted_cov(self, g: StrideGraph, k: int, seg, dt_s: float) -> np.ndarray | None:
        """Approximate covariance of the predicted ``X(k)`` (IMU local): the marginal of
        ``X(k-1)``, its velocity's marginal × dt² and the preintegration noise."""
        try:
            cov = g.marginal_covariance(X(k - 1)).copy()
            cov_v = g.marginal_covariance(V(k - 1))
        except RuntimeError as err:
            log.info("no marginal for the stance gate (%s)", err)
            return None
        rot = g.estimate.atPose3(X(k - 1)).rotation().matrix()
        cov[3:, 3:] += rot.T @ cov_v @ rot * dt_s**2
        if seg.ok:
            cov += np.asarray(seg.pim.preintMeasCov())[:6, :6]
        return cov

    def _contact_factors(
        self, t_s: float, k: int, pred: gtsam.Pose3, pred_cov: np.ndarray | None = None
    ):
        """Stance factors of the ``contact_points`` model (see ``KinematicFactorConfig``).

        Heel at the stride origin while the foot is not pitched toe-down (before heel-off),
        toe at its foot-flat position (level ground) while the foot is not pitched toe-up
        (from foot flat to toe-off). The foot pitch comes from the predicted IMU orientation
        and the encoders. A point farther than ``max_mahalanobis`` from the prediction (its σ
        combined with the prediction's covariance ``pred_cov`` when given) is not used
        (``kin_inconsistent``). Returns ``(tagged factors, flags)``."""
        from kinematics.errors import KinematicsError

        q = self._q_at(t_s)
        if self.leg_model is None or q is None:
            return [], ["no_kinematics"]
        kc = self.cfg.kinematics
        try:
            imu_T_foot = np.linalg.inv(self.leg_model.foot_T_imu(q))
            foot_p_toe = self.leg_model.frame_T_frame("heel", "toe", q)[:3, 3]
        except KinematicsError as err:
            log.warning("t=%.3f s: no kinematic measurement (%s)", t_s, err)
            return [], ["no_kinematics"]
        stride_R_foot = pred.rotation().matrix() @ imu_T_foot[:3, :3]
        x = stride_R_foot[:, 0]
        pitch = float(np.arctan2(x[2], np.hypot(x[0], x[1])))
        if pitch < -kc.contact_pitch_rad:
            self._heel_off = True
        points = []
        if not self._heel_off:
            points.append(("heel", imu_T_foot[:3, 3], np.zeros(3)))
        if pitch < kc.contact_pitch_rad:
            points.append(("toe", imu_T_foot[:3, :3] @ foot_p_toe + imu_T_foot[:3, 3], foot_p_toe))
        tagged, flags = [], []
        pose = pred.matrix()
        for name, imu_p, stride_p in points:
            err, h = factors.contact_point_residual(pose, imu_p, stride_p)
            cov = np.eye(3) * kc.contact_sigma_m**2
            if pred_cov is not None:
                cov = cov + h @ pred_cov @ h.T
            if np.sqrt(err @ np.linalg.solve(cov, err)) > kc.max_mahalanobis:
                flags.append(f"kin_inconsistent:{name}")
                continue
            tagged.append(
                (
                    "kin",
                    factors.contact_point_factor(
                        k, imu_p, stride_p, kc.contact_sigma_m, kc.robust_kernel, kc.robust_k
                    ),
                )
            )
        if not points:
            flags.append("no_contact")
        return tagged, flags

    def _imu_up_to_model(self, up_in_imu: np.ndarray | None) -> np.ndarray | None:
        """The session IMU's up vector in the leg model's ``imu`` frame (via the camera)."""
        if up_in_imu is None:
            return None
        m = self.leg_model
        model_camera_R_imu = (
            np.linalg.inv(m.thigh_T_frame("camera_optical")) @ m.thigh_T_frame("imu")
        )[:3, :3]
        return model_camera_R_imu.T @ self.camera_T_imu[:3, :3] @ up_in_imu

    # ------------------------------------------------------------------ frames
    def add_frame(
        self,
        t_s: float,
        icp: IcpMeasurement | None = None,
        foot_loaded: bool = False,
        kinematics: KinematicMeasurement | None = None,
    ) -> FrameEstimate:
        """Add one camera frame; returns its online estimate (iSAM2)."""
        if not np.isfinite(t_s) or t_s <= self._last_frame_t:
            raise EstimationError(
                f"add_frame: t_s={t_s!r} must be finite and after the previous frame "
                f"({self._last_frame_t!r})"
            )
        use = self.cfg.factors
        if (
            self._graph is not None
            and self._pending_start is None
            and t_s - self._stride_t0 > self.cfg.priors.max_stride_s
        ):
            log.warning(
                "t=%.3f s: stride longer than %.2f s: a missed foot strike",
                t_s,
                self.cfg.priors.max_stride_s,
            )
            self._close_stride()
            self._pending_start = "missed_foot_strike"
        index = self._frame_count
        t_start = time.perf_counter()
        flags: list[str] = []
        gate: GateDecision | None = None
        kin_used = imu_used = False
        if self._graph is None:
            if kinematics is None:
                kinematics = self._kinematics_from_joints(t_s, anchor=True)
            flags += self._start_stride(t_s, kinematics)
            self._started_loaded = bool(foot_loaded)
            k = 0
            if icp is not None:
                gate = GateDecision(False, "previous_stride (ICP across a foot strike not used)")
        else:
            g = self._graph
            k = g.n_states
            prev = g.nav(k - 1)
            t_prev = g.t_s[-1]
            tagged: list[tuple[str, object]] = []
            seg = self.imu.integrate(t_prev, t_s, prev.bias)
            nav_prev = gtsam.NavState(prev.stride_T_imu, prev.velocity_m_s)
            if seg.ok:
                pred = seg.pim.predict(nav_prev, prev.bias)
                tagged.append(("imu", factors.imu_factor(k - 1, k, seg.pim)))
            else:
                flags.append(seg.reason)
                self._stride_counts["gap"] += 1
                g.flags.add(seg.reason)
                dt = t_s - t_prev
                pred = gtsam.NavState(
                    prev.stride_T_imu.compose(
                        gtsam.Pose3(
                            gtsam.Rot3(),
                            prev.stride_T_imu.rotation().unrotate(prev.velocity_m_s) * dt,
                        )
                    ),
                    prev.velocity_m_s,
                )
            v_body = prev.stride_T_imu.rotation().unrotate(prev.velocity_m_s)
            imu_cfg = self.cfg.imu

            def bridge(k=k, dt=t_s - t_prev, v_body=v_body):
                return factors.gap_bridge_factors(
                    k - 1,
                    k,
                    dt,
                    v_body,
                    self.cfg.gap_bridge_rot_sigma_rad,
                    self.cfg.gap_bridge_trans_sigma_m,
                    imu_cfg.gravity_m_s2,
                    imu_cfg.accel_random_walk_m_s3_sqrt_hz,
                    imu_cfg.gyro_random_walk_rad_s2_sqrt_hz,
                )

            if not seg.ok:
                tagged.extend(("bridge", f) for f in bridge())
            if icp is not None and use["icp"]:
                gate, f = self._icp_factor(icp, index, k)
                if f is not None:
                    tagged.append(("icp", f))
            contact_model = (
                kinematics is None
                and self.leg_model is not None
                and self.cfg.kinematics.stance_model == "contact_points"
            )
            if foot_loaded and use["kin"] and contact_model:
                if self._stride_start in ("missed_foot_strike", "no_anchor"):
                    flags.append("kin_unanchored")
                else:
                    kin_tagged, kin_flags = self._contact_factors(
                        t_s, k, pred.pose(), self._predicted_cov(g, k, seg, t_s - t_prev)
                    )
                    tagged += kin_tagged
                    flags += kin_flags
                    if any(f.startswith("kin_inconsistent") for f in kin_flags):
                        g.flags.add("kin_inconsistent")
            elif foot_loaded and use["kin"]:
                if kinematics is None:
                    kinematics = self._kinematics_from_joints(t_s, anchor=False)
                if kinematics is not None and self._stride_start in (
                    "missed_foot_strike",
                    "no_anchor",
                ):
                    flags.append("kin_unanchored")  # the foothold of this stride is unknown
                    kinematics = None
                elif kinematics is not None:
                    d = self._kin_mahalanobis(kinematics, pred.pose())
                    if d > self.cfg.kinematics.max_mahalanobis:
                        log.info("frame %d: stance factor %.1f sigmas off: not added", index, d)
                        flags.append("kin_inconsistent")
                        g.flags.add("kin_inconsistent")
                        kinematics = None
                if kinematics is not None:
                    kc = self.cfg.kinematics
                    tagged.append(
                        (
                            "kin",
                            factors.kinematic_prior_factor(
                                k,
                                kinematics.stride_T_camera,
                                kinematics.covariance * kc.sigma_scale**2,
                                self.camera_T_imu,
                                kc.robust_kernel,
                                kc.robust_k,
                            ),
                        )
                    )
                elif not any(f.startswith("kin_") for f in flags):
                    flags.append("no_kinematics")
            values = gtsam.Values()
            values.insert(X(k), pred.pose())
            values.insert(V(k), pred.velocity())
            values.insert(B(k), prev.bias)
            kept, extra = g.add_state(t_s, tagged, values, bridge)
            flags += extra
            imu_used = "imu" in kept
            kin_used = "kin" in kept
            if "icp" in kept:
                self._stride_counts["icp_ok"] += 1
            elif gate is not None:
                self._stride_counts["icp_rej"] += 1
                flags.append("icp_rejected" if not gate.accepted else "icp_dropped")
            if kin_used:
                self._stride_counts["kin"] += 1
        g = self._graph
        self._frame_to_k[index] = k
        stride_T_imu = g.estimate.atPose3(X(k)).matrix()
        stride_T_camera = stride_T_imu @ np.linalg.inv(self.camera_T_imu)
        cov = None
        if self.cfg.covariances:
            cov = factors.imu_cov_to_camera(g.marginal_covariance(X(k)), self.camera_T_imu)
        est = FrameEstimate(
            frame_index=index,
            stride_index=len(self.results.strides),
            k=k,
            t_s=float(t_s),
            stride_T_camera=stride_T_camera,
            world_T_camera=self._world_T_stride @ stride_T_camera,
            flags=tuple(flags),
            gate=gate,
            kinematic_factor=kin_used,
            imu_factor=imu_used,
            update_s=time.perf_counter() - t_start,
            covariance=cov,
        )
        self.results.frames.append(est)
        self._frames_in_stride.append(est)
        self._frame_count += 1
        self._last_frame_t = t_s
        self.imu.drop_before(t_s - 1.0)
        return est

    def _kin_mahalanobis(self, kin: KinematicMeasurement, stride_T_imu_pred: gtsam.Pose3) -> float:
        """Distance (in sigmas of the measurement) of a stance measurement from the prediction."""
        pred_camera = gtsam.Pose3(stride_T_imu_pred.matrix() @ np.linalg.inv(self.camera_T_imu))
        e = gtsam.Pose3.Logmap(gtsam.Pose3(kin.stride_T_camera).between(pred_camera))
        cov = kin.covariance * self.cfg.kinematics.sigma_scale**2
        return float(np.sqrt(e @ np.linalg.solve(cov, e)))

    def _icp_factor(self, icp: IcpMeasurement, index: int, k: int):
        if icp.source_index != index:
            return GateDecision(
                False, f"source_index {icp.source_index} is not this frame ({index})"
            ), None
        if icp.target_index not in self._frame_to_k or icp.target_index >= index:
            return GateDecision(False, "target frame not in this stride"), None
        decision = gate_icp(icp, self.cfg.gate)
        if not decision.accepted:
            log.info("frame %d: ICP rejected (%s)", index, decision.reason)
            return decision, None
        gc = self.cfg.gate
        f = factors.icp_between_factor(
            self._frame_to_k[icp.target_index],
            k,
            icp.target_T_source,
            decision.sqrt_information,
            self.camera_T_imu,
            gc.robust_kernel,
            gc.robust_k,
        )
        return decision, f

    # ------------------------------------------------------------------ strides
    def _start_stride(self, t_s: float, anchor: KinematicMeasurement | None) -> list[str]:
        pc = self.cfg.priors
        reason = self._pending_start or "first_stride"
        if self._last_nav is None and reason != "first_stride":
            reason = "first_stride"
        flags = [reason] if reason != "foot_strike" else []
        g = StrideGraph(self.cfg.isam2_relinearize_threshold)
        tagged: list[tuple[str, object]] = []
        if self._last_nav is None:  # first stride of the session: gravity-aligned, weak priors
            if anchor is not None:
                pose, cov_pose = factors.camera_pose_to_imu(
                    anchor.stride_T_camera, anchor.covariance, self.camera_T_imu
                )
            else:
                up = self.imu.mean_accel(t_s - self.cfg.kinematics.gravity_window_s, t_s)
                rot = np.eye(3) if up is None else gravity_aligned_rotation(up)
                pose = gtsam.Pose3(gtsam.Rot3(rot), np.zeros(3))
                s = np.r_[
                    pc.first_roll_pitch_sigma_rad,
                    pc.first_roll_pitch_sigma_rad,
                    pc.first_yaw_sigma_rad,
                    np.full(3, pc.first_position_sigma_m),
                ]
                # roll/pitch sigmas are about the nav axes: rotate into the body (local) frame
                ad = np.zeros((6, 6))
                ad[:3, :3] = ad[3:, 3:] = rot.T
                cov_pose = ad @ np.diag(s**2) @ ad.T
                flags.append("no_anchor" if up is not None else "no_anchor_no_gravity")
            vel = np.zeros(3)
            cov_vel = np.eye(3) * pc.first_velocity_sigma_m_s**2
            bias = gtsam.imuBias.ConstantBias()
            cov_bias = np.diag(
                np.r_[
                    np.full(3, pc.first_accel_bias_sigma_m_s2**2),
                    np.full(3, pc.first_gyro_bias_sigma_rad_s**2),
                ]
            )
        else:
            t_last, nav, cov_x, cov_v, cov_b = self._last_nav
            seg = self.imu.integrate(t_last, t_s, nav.bias) if t_s > t_last else None
            if seg is not None and seg.ok:
                pred = seg.pim.predict(gtsam.NavState(nav.stride_T_imu, nav.velocity_m_s), nav.bias)
                pcov = np.asarray(seg.pim.preintMeasCov())
                cov_x = cov_x + pcov[:6, :6]
                cov_v = cov_v + pcov[6:9, 6:9]
            else:
                if seg is not None:
                    flags.append(seg.reason)
                dt = max(t_s - t_last, 0.0)
                pred = gtsam.NavState(
                    gtsam.Pose3(
                        nav.stride_T_imu.rotation(),
                        nav.stride_T_imu.translation() + nav.velocity_m_s * dt,
                    ),
                    nav.velocity_m_s,
                )
                cov_x = cov_x + np.diag(np.r_[np.full(3, 0.05**2), np.full(3, (2.0 * dt) ** 2)])
                cov_v = cov_v + np.eye(3) * (self.cfg.imu.gravity_m_s2 * dt) ** 2
            infl = pc.carry_inflation if reason == "foot_strike" else pc.missed_strike_inflation
            if self._stride_start == "first_stride" and not self._started_loaded:
                infl *= pc.first_carry_inflation  # out of a first stride begun in the air
            bias, cov_bias = nav.bias, cov_b * infl
            if anchor is not None and reason == "foot_strike":
                pose, cov_pose = factors.camera_pose_to_imu(
                    anchor.stride_T_camera, anchor.covariance, self.camera_T_imu
                )
                new_R_old = pose.rotation().matrix() @ pred.pose().rotation().matrix().T
                vel = new_R_old @ np.asarray(pred.velocity())
                cov_vel = new_R_old @ cov_v @ new_R_old.T * infl
                self._world_T_stride = (
                    self._world_T_stride @ pred.pose().matrix() @ np.linalg.inv(pose.matrix())
                )
            else:  # no new stride frame: continue in the previous one, inflated
                if reason == "foot_strike":
                    flags.append("no_anchor")
                    infl = pc.missed_strike_inflation
                pose, vel = pred.pose(), np.asarray(pred.velocity())
                cov_pose, cov_vel = cov_x * infl, cov_v * infl
                cov_bias = cov_b * infl
        tagged.append(("prior", factors.pose_prior(0, pose, cov_pose)))
        tagged.append(("prior", factors.velocity_prior(0, vel, cov_vel)))
        tagged.append(("prior", factors.bias_prior(0, bias, cov_bias)))
        values = gtsam.Values()
        values.insert(X(0), pose)
        values.insert(V(0), vel)
        values.insert(B(0), bias)
        g.add_state(t_s, tagged, values, None)
        g.flags.update(f for f in flags if f != "first_stride")
        self._graph = g
        self._stride_start = reason
        self._pending_start = None
        self._strike_up = None
        self._strike_up_sigma = None
        self._heel_off = False
        self._stride_t0 = t_s
        self._frame_to_k = {}
        self._frames_in_stride = []
        self._stride_counts = {"icp_ok": 0, "icp_rej": 0, "kin": 0, "gap": 0}
        return flags

    def _close_stride(self) -> StrideSummary:
        g = self._graph
        result, marginals, smoothing_s = g.smooth(self.cfg.smoothing)
        n = g.n_states
        inv_ext = np.linalg.inv(self.camera_T_imu)
        smoothed = np.array([result.atPose3(X(k)).matrix() @ inv_ext for k in range(n)])
        online = np.array([f.stride_T_camera for f in self._frames_in_stride])
        covs = None
        last = g.nav(n - 1, result)
        if marginals is not None:
            cov_x = np.asarray(marginals.marginalCovariance(X(n - 1)))
            cov_v = np.asarray(marginals.marginalCovariance(V(n - 1)))
            cov_b = np.asarray(marginals.marginalCovariance(B(n - 1)))
            if self.cfg.covariances:
                covs = np.array(
                    [
                        factors.imu_cov_to_camera(
                            np.asarray(marginals.marginalCovariance(X(k))), self.camera_T_imu
                        )
                        for k in range(n)
                    ]
                )
        else:
            cov_x = g.marginal_covariance(X(n - 1))
            cov_v = g.marginal_covariance(V(n - 1))
            cov_b = g.marginal_covariance(B(n - 1))
        self._last_nav = (g.t_s[-1], last, cov_x, cov_v, cov_b)
        c = self._stride_counts
        summary = StrideSummary(
            index=len(self.results.strides),
            t_start_s=g.t_s[0],
            t_end_s=g.t_s[-1],
            start=self._stride_start,
            world_T_stride=self._world_T_stride.copy(),
            frame_indices=[f.frame_index for f in self._frames_in_stride],
            t_s=np.array(g.t_s),
            online_stride_T_camera=online,
            smoothed_stride_T_camera=smoothed,
            smoothed_covariances=covs,
            flags=tuple(sorted(g.flags)),
            n_icp_accepted=c["icp_ok"],
            n_icp_rejected=c["icp_rej"],
            n_kinematic=c["kin"],
            n_imu_gaps=c["gap"],
            dropped_factors=list(g.dropped),
            smoothing_s=smoothing_s,
            velocity_end_m_s=last.velocity_m_s,
            bias_end=np.asarray(last.bias.vector()),
        )
        self.results.strides.append(summary)
        self._graph = None
        return summary

"""The streaming estimator: one factor graph per stride, re-solved at every frame.

    slam = StrideSLAM(BackendConfig(), camera_T_imu=calib.camera_T_imu, leg_model=model)
    slam.add_imu(t_s, gyro_rad_s, accel_m_s2)          # any time, any chunk size
    slam.add_joints(t_s, knee_rad, ankle_rad)           # encoders (with a leg model)
    est = slam.add_frame(t_s, icp=..., foot_loaded=..., kinematics=...)   # online pose
    summary = slam.foot_strike(t_s)                     # closes the stride: smoothed poses
    results = slam.finish()

A small facade: it wires components built by ``make_*`` factories, each with its own state
and tests (docs/backend.md, "Components"): the leg kinematics (encoders -> anchor and stance
measurements, :mod:`graph_slam.strides.kinematics`), the IMU prediction
(:mod:`.prediction`), the registration gate (:mod:`.gating`), the stance model
(:mod:`.stance`) and the chain of stride graphs (:mod:`.stride_chain`). The first frame of a
stride takes the kinematic measurement (the caller's, else the encoders') as its **anchor**.
"""

from __future__ import annotations

import logging
import time

import gtsam
import numpy as np

from graph_slam.backend import factors
from graph_slam.backend.config import BackendConfig
from graph_slam.backend.gating import GateDecision, make_registration_gate
from graph_slam.backend.imu import ImuCheck
from graph_slam.backend.keys import B, X
from graph_slam.backend.measurements import IcpMeasurement, KinematicMeasurement
from graph_slam.backend.prediction import StrikeUp, make_imu_predictor
from graph_slam.backend.results import FrameEstimate, Results, StrideSummary
from graph_slam.backend.stance import make_stance_model
from graph_slam.backend.stride_chain import make_stride_chain
from graph_slam.errors import EstimationError
from graph_slam.strides.kinematics import make_leg_kinematics
from graph_slam.strides.up_fusion import GraphUp

log = logging.getLogger(__name__)


class StrideSLAM:
    """Per-stride factor-graph estimator (see the module docstring). ``leg_model``: a
    :class:`kinematics.leg_model.LegModel` for kinematics from :meth:`add_joints`."""

    def __init__(
        self,
        config: BackendConfig | None = None,
        camera_T_imu: np.ndarray | None = None,
        leg_model=None,
    ):
        self.cfg = config or BackendConfig()
        self.camera_T_imu = np.eye(4) if camera_T_imu is None else np.asarray(camera_T_imu, float)
        pc = self.cfg.priors
        self.leg = make_leg_kinematics(
            leg_model, self.camera_T_imu, pc.anchor_yaw_sigma_rad, pc.anchor_position_sigma_m
        )
        self.imu = make_imu_predictor(self.cfg)
        self.registration = make_registration_gate(self.cfg, self.camera_T_imu)
        self.stance = make_stance_model(self.cfg, self.leg, self.camera_T_imu)
        self.strides = make_stride_chain(self.cfg, self.camera_T_imu, self.imu)
        self.results: Results = self.strides.results
        self._strike_up: StrikeUp | None = None
        self._contact_slope_rad = 0.0
        self._last_frame_t = -np.inf

    # ------------------------------------------------------------------ inputs
    def add_imu(self, t_s, gyro_rad_s, accel_m_s2) -> ImuCheck:
        """Add IMU samples (IMU frame); bad samples are rejected and counted, never used."""
        return self.imu.add(t_s, gyro_rad_s, accel_m_s2)

    def add_joints(self, t_s, knee_rad, ankle_rad) -> int:
        """Add encoder samples (used only with a leg model); returns how many were kept."""
        return self.leg.add_joints(t_s, knee_rad, ankle_rad)

    def foot_strike(
        self,
        t_s: float,
        up_in_imu: np.ndarray | None = None,
        up_sigma_rad: float | None = None,
        up_t_s: float | None = None,
        contact_slope_rad: float = 0.0,
        up_assumed: bool = False,
    ) -> StrideSummary | None:
        """A foot strike: close the current stride (smoothing); the next frame starts a new one.

        ``up_in_imu``: the up direction (e.g. gravity, m/s²) in the IMU frame at ``up_t_s``
        (default ``t_s``) for the new stride's anchor, carried to its first frame by the gyro;
        default: the accelerometer mean before that frame (biased by the swing leg's
        deceleration). ``up_sigma_rad``: that direction's σ; given, the anchor's covariance is
        :func:`graph_slam.strides.kinematics.anchor_covariance` (docs/backend.md).
        ``contact_slope_rad``: the ground's pitch along the heading under the new foot (+
        rising ahead; 0: level), where the stance contact factors put the toe.
        ``up_assumed``: the up vector rests on an assumption (a plane taken as level at a
        session's first strike): like one without σ, its stride's bias is not trusted by the
        next (``priors.loose_tilt_bias_*``).
        """
        self._strike_up = StrikeUp.checked(t_s, up_in_imu, up_sigma_rad, up_t_s, up_assumed)
        self._contact_slope_rad = (
            float(contact_slope_rad) if np.isfinite(contact_slope_rad) else 0.0
        )
        return self.strides.foot_strike()

    def finish(self) -> Results:
        """Close the open stride and return every result (deferred smoothings not run:
        :meth:`smooth_deferred`)."""
        self.strides.settle_pending(at_once=True)
        if self.strides.graph is not None:
            self.strides.close()
        self.strides.settle_pending(at_once=True)
        self.strides.refit_first()  # the first stride with the first strike's up vector
        self.results.imu_counts = dict(self.imu.counts)
        return self.results

    def _carried_to(self, t_s: float):
        """``(graph, its latest state, the IMU segment from it to t_s)`` of the open stride;
        None with no open stride, a pending strike, ``t_s`` not after its last state or an
        IMU gap."""
        g = self.strides.graph
        if g is None or self.strides.pending is not None or not t_s > g.t_s[-1]:
            return None
        last = g.nav(g.n_states - 1)
        seg = self.imu.buffer.integrate(g.t_s[-1], t_s, last.bias)
        return (g, last, seg) if seg.ok else None

    def predict_relative(self, t_s: float) -> np.ndarray | None:
        """``last_T_new``: the camera's motion from the open stride's latest state to ``t_s``,
        preintegrated from the current estimate (pose, velocity, bias) — an ICP initial guess
        good to millimetres. None at a stride's first frame or across an IMU gap."""
        carried = self._carried_to(t_s)
        if carried is None:
            return None
        _, last, seg = carried
        nav = seg.pim.predict(gtsam.NavState(last.stride_T_imu, last.velocity_m_s), last.bias)
        last_T_new_imu = np.linalg.inv(last.stride_T_imu.matrix()) @ nav.pose().matrix()
        imu_T_camera, _ = factors.fixed_transforms(self.camera_T_imu)
        return self.camera_T_imu @ last_T_new_imu @ imu_T_camera

    def up_estimate(self, t_s: float) -> GraphUp | None:
        """Up in the IMU frame at ``t_s`` from the open stride's online attitude (its latest
        state, carried by the gyro with the estimated bias), with that attitude's marginal
        covariance plus the carry's (causal: only what was added). None: no open stride, a
        pending strike, ``t_s`` not after its last state, an IMU gap, or no marginal."""
        carried = self._carried_to(t_s)
        if carried is None:
            return None
        g, last, seg = carried
        try:
            cov_last = g.marginal_covariance(X(g.n_states - 1))[:3, :3]
        except RuntimeError as err:
            log.info("t=%.3f s: no attitude marginal for the up vector (%s)", t_s, err)
            return None
        last_R_now = np.asarray(seg.pim.deltaRij().matrix())
        now_R_stride = (last.stride_T_imu.rotation().matrix() @ last_R_now).T
        cov = last_R_now.T @ cov_last @ last_R_now + np.asarray(seg.pim.preintMeasCov())[:3, :3]
        return GraphUp(float(t_s), now_R_stride[:, 2], cov, now_R_stride[:, 1])

    def pose_covariance(self, k: int) -> np.ndarray | None:
        """The open stride's state ``k``: the camera pose's marginal covariance (camera local,
        rotation first), as ``backend.covariances`` gives every frame. None: no open stride,
        no such state, or no marginal."""
        g = self.strides.graph
        if g is None or not 0 <= k < g.n_states:
            return None
        try:
            return factors.imu_cov_to_camera(g.marginal_covariance(X(k)), self.camera_T_imu)
        except RuntimeError as err:  # GTSAM's exceptions arrive as bare RuntimeError
            log.info("state %d: no pose marginal (%s)", k, err)
            return None

    def velocity_change(self, t_s: float) -> tuple[float, np.ndarray] | None:
        """``(t0_s, Δv)``: the open stride's first state's time and the IMU's velocity change
        from it to ``t_s`` (online estimate, carried by the IMU), in the IMU frame at ``t_s``
        (m/s): what the accelerometer's mean over ``[t0_s, t_s]`` holds besides gravity and
        its bias (:class:`graph_slam.strides.anchor.StrideAnchor`). None as
        :meth:`up_estimate`."""
        carried = self._carried_to(t_s)
        if carried is None:
            return None
        g, last, seg = carried
        now = seg.pim.predict(gtsam.NavState(last.stride_T_imu, last.velocity_m_s), last.bias)
        dv_stride = np.asarray(now.velocity()) - g.nav(0).velocity_m_s
        now_R_stride = now.pose().rotation().matrix().T
        return float(g.t_s[0]), now_R_stride @ dv_stride

    def lateral_bias(self, t_s: float) -> tuple[np.ndarray, float] | None:
        """The open stride's accelerometer bias across the sagittal plane (along the stride
        frame's y axis) at ``t_s``, as a vector in the IMU frame at ``t_s`` (m/s²), and its
        marginal σ: a lateral bias reads as a roll to the accelerometer's up
        (:class:`graph_slam.strides.anchor.StrideAnchor`). None as :meth:`up_estimate`."""
        carried = self._carried_to(t_s)
        if carried is None:
            return None
        g, last, seg = carried
        try:
            cov = g.marginal_covariance(B(g.n_states - 1))[:3, :3]
        except RuntimeError as err:
            log.info("t=%.3f s: no bias marginal for the lateral bias (%s)", t_s, err)
            return None
        now_R_stride = (last.stride_T_imu.rotation().matrix() @ seg.pim.deltaRij().matrix()).T
        lateral = now_R_stride[:, 1]
        b = np.asarray(last.bias.accelerometer())
        return float(b @ lateral) * lateral, float(np.sqrt(max(lateral @ cov @ lateral, 0.0)))

    def smooth_deferred(self, keep: int = 0) -> list[StrideSummary]:
        """Batch-smooth the strides closed with ``defer_smoothing`` (off the real-time path:
        at the end of a run, or when the host is idle), oldest first, until ``keep`` wait;
        returns the strides updated."""
        return self.strides.smooth_deferred(keep)

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
        self.strides.close_if_missed(t_s)
        t_start, index = time.perf_counter(), self.results.n_frames
        if self.strides.graph is None:
            return self._stride_start(index, t_s, t_start, icp, foot_loaded, kinematics)
        self.strides.settle_pending()  # end_state: next_frame
        g, use = self.strides.graph, self.cfg.factors
        pred = self.imu.predict(g, t_s)  # 1. IMU prediction (or a gap and its bridges)
        tagged, flags, gate = list(pred.tagged), list(pred.flags), None
        if icp is not None and use["icp"]:  # 2. registration factor
            gate, icp_factor = self.registration.factor(icp, index, pred.k)
            tagged += [] if icp_factor is None else [("icp", icp_factor)]
        if foot_loaded and use["kin"]:  # 3. stance factors
            anchored = self.strides.anchored
            kin, kin_flags = self.stance.factors(
                t_s, pred.k, pred.pose, pred.covariance, anchored, kinematics
            )
            tagged, flags = tagged + kin, flags + kin_flags
        kept, extra = g.add_state(t_s, tagged, pred.values(), pred.bridge)  # 4. add the state
        flags += extra
        flags += self.strides.count(pred, kept, gate, flags)
        return self._estimate(index, pred.k, t_s, flags, gate, kept, t_start)  # 5. estimate

    def _stride_start(self, index, t_s, t_start, icp, foot_loaded, kinematics) -> FrameEstimate:
        """A stride's first frame: its anchor and priors; no ICP across the strike."""
        anchor = kinematics if kinematics is not None else self._anchor(t_s)
        up = self._strike_up
        known = kinematics is not None or (
            up is not None and up.sigma_rad is not None and not up.assumed
        )
        flags = self.strides.start(t_s, anchor, foot_loaded, known)
        self.stance.start_stride(self._contact_slope_rad)
        self.registration.start_stride()
        self._strike_up = None
        gate = None
        if icp is not None:
            gate = GateDecision(False, "previous_stride (ICP across a foot strike not used)")
        return self._estimate(index, 0, t_s, flags, gate, [], t_start)

    def _anchor(self, t_s: float) -> KinematicMeasurement | None:
        """The encoders' anchor with the up vector at ``t_s`` (None without encoders)."""
        if self.leg.q_at(t_s) is None:
            return None
        sigma = None if self._strike_up is None else self._strike_up.sigma_rad
        return self.leg.anchor(t_s, self.imu.up_at(t_s, self._strike_up), sigma)

    def _estimate(self, index, k, t_s, flags, gate, kept, t_start) -> FrameEstimate:
        est = self.strides.estimate(index, k, t_s, flags, gate, kept, t_start)
        self.registration.add_frame(index, k)
        self.imu.drop_before(t_s - 1.0)
        self.leg.joints.drop_before(t_s - 1.0)  # memory stays flat on long recordings
        self._last_frame_t = t_s
        return est

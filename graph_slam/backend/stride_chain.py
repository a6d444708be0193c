"""The chain of stride graphs: how a stride starts (priors), ends (smoothing) and is recorded.

**Start** (:meth:`StrideChain.start`, at a stride's first frame). Why it starts is the pending
reason: ``foot_strike`` (announced), ``missed_foot_strike`` (the open stride ran past
``priors.max_stride_s``: :meth:`StrideChain.close_if_missed`) or ``first_stride`` (nothing
carried yet). The first state gets pose, velocity and bias priors:

* first stride of a session (:func:`first_stride_priors`): the anchor if any, else
  gravity-aligned from the accelerometer mean (roll/pitch σ ``first_roll_pitch_sigma_rad``,
  flag ``no_anchor``); weak velocity and bias priors;
* later strides (:func:`carried_priors`): the previous stride's smoothed end state propagated
  by the IMU (:meth:`~graph_slam.backend.prediction.ImuPredictor.carry`), covariances ×
  ``carry_inflation`` (× ``missed_strike_inflation`` after a missed strike; also ×
  ``first_carry_inflation`` out of a first stride begun with the foot unloaded). With an
  anchor at a foot strike the pose is the anchor, the velocity is rotated by
  ``new_R_old = R_anchor · R_predictedᵀ`` and ``world_T_stride`` chains by the prediction;
  without one (or after a missed strike) the new graph continues in the previous stride
  frame, covariances × ``missed_strike_inflation``.

**Close** (:meth:`StrideChain.close`): LM smoothing, marginals at the end state (carried to
the next stride), the :class:`~graph_slam.backend.results.StrideSummary`.

**Bookkeeping**: per-stride counts (ICP accepted/rejected, kinematic factors, IMU gaps), the
frame estimates (:meth:`StrideChain.estimate`).
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field

import gtsam
import numpy as np

from graph_slam.backend import factors
from graph_slam.backend.config import BackendConfig, PriorConfig
from graph_slam.backend.gating import GateDecision
from graph_slam.backend.keys import B, V, X
from graph_slam.backend.measurements import KinematicMeasurement
from graph_slam.backend.prediction import ImuPredictor, Prediction
from graph_slam.backend.results import FrameEstimate, Results, StrideSummary
from graph_slam.backend.stride_graph import NavEstimate, StrideGraph

log = logging.getLogger(__name__)

#: Strides whose foothold is unknown: no stance factors (``kin_unanchored``).
UNANCHORED = ("missed_foot_strike",)


def gravity_aligned_rotation(up_in_imu: np.ndarray) -> np.ndarray:
    """``nav_R_imu`` with z along ``up_in_imu`` and zero yaw of the IMU's x axis (if possible)."""
    z = up_in_imu / np.linalg.norm(up_in_imu)  # nav z expressed in the IMU frame
    x_imu = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = x_imu - (x_imu @ z) * z
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return np.vstack([x, y, z])  # rows: nav axes in IMU coordinates -> nav_R_imu


@dataclass(eq=False)
class StartPriors:
    """Priors of a stride's first state (IMU local covariances, rotation first)."""

    stride_T_imu: gtsam.Pose3
    cov_pose: np.ndarray
    velocity_m_s: np.ndarray
    cov_velocity: np.ndarray
    bias: gtsam.imuBias.ConstantBias
    cov_bias: np.ndarray
    flags: list[str] = field(default_factory=list)
    old_stride_T_imu: np.ndarray | None = None
    """The predicted IMU pose in the previous stride's frame when a new stride frame starts
    (``world_T_stride`` chains by it), else None."""


def first_stride_priors(
    pc: PriorConfig,
    camera_T_imu: np.ndarray,
    anchor: KinematicMeasurement | None,
    gravity_in_imu: np.ndarray | None,
) -> StartPriors:
    """The session's first state: the anchor, or gravity-aligned; weak velocity/bias priors."""
    flags = []
    if anchor is not None:
        pose, cov_pose = factors.camera_pose_to_imu(
            anchor.stride_T_camera, anchor.covariance, camera_T_imu
        )
    else:
        rot = np.eye(3) if gravity_in_imu is None else gravity_aligned_rotation(gravity_in_imu)
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
        flags.append("no_anchor" if gravity_in_imu is not None else "no_anchor_no_gravity")
    cov_bias = np.diag(
        np.r_[
            np.full(3, pc.first_accel_bias_sigma_m_s2**2),
            np.full(3, pc.first_gyro_bias_sigma_rad_s**2),
        ]
    )
    cov_vel = np.eye(3) * pc.first_velocity_sigma_m_s**2
    bias = gtsam.imuBias.ConstantBias()
    return StartPriors(pose, cov_pose, np.zeros(3), cov_vel, bias, cov_bias, flags)


def carried_priors(
    pc: PriorConfig,
    camera_T_imu: np.ndarray,
    reason: str,
    pred: gtsam.NavState,
    cov_x: np.ndarray,
    cov_v: np.ndarray,
    bias: gtsam.imuBias.ConstantBias,
    cov_b: np.ndarray,
    anchor: KinematicMeasurement | None,
    out_of_unloaded_first: bool = False,
) -> StartPriors:
    """The previous stride's end state ``pred`` (propagated to this frame, covariances incl.
    preintegration) as the new stride's priors; see the module docstring for the inflation."""
    infl = pc.carry_inflation if reason == "foot_strike" else pc.missed_strike_inflation
    if out_of_unloaded_first:
        infl *= pc.first_carry_inflation
    if anchor is not None and reason == "foot_strike":
        pose, cov_pose = factors.camera_pose_to_imu(
            anchor.stride_T_camera, anchor.covariance, camera_T_imu
        )
        new_R_old = pose.rotation().matrix() @ pred.pose().rotation().matrix().T
        vel = new_R_old @ np.asarray(pred.velocity())
        cov_vel = new_R_old @ cov_v @ new_R_old.T * infl
        old = pred.pose().matrix()
        return StartPriors(pose, cov_pose, vel, cov_vel, bias, cov_b * infl, [], old)
    flags = []  # no new stride frame: continue in the previous one, inflated
    if reason == "foot_strike":
        flags.append("no_anchor")
        infl = pc.missed_strike_inflation
    pose, vel = pred.pose(), np.asarray(pred.velocity())
    return StartPriors(pose, cov_x * infl, vel, cov_v * infl, bias, cov_b * infl, flags)


class StrideChain:
    """The open stride's graph and everything carried from one stride to the next."""

    def __init__(self, config: BackendConfig, camera_T_imu: np.ndarray, imu: ImuPredictor):
        self.cfg = config
        self.camera_T_imu = np.asarray(camera_T_imu, float)
        self.imu = imu
        self.results = Results()
        self.graph: StrideGraph | None = None
        self.start_reason = "first_stride"
        self.pending: str | None = None
        self.world_T_stride = np.eye(4)
        self._t0_s = np.nan
        self._frames: list[FrameEstimate] = []
        self._counts = {"icp_ok": 0, "icp_rej": 0, "kin": 0, "gap": 0}
        self._last_nav = None  # (t_s, NavEstimate, cov_pose, cov_vel, cov_bias) at stride end
        self._started_loaded = True  # the open stride's first frame had the foot loaded
        self.deferred: list[tuple[StrideSummary, StrideGraph]] = []
        """Closed strides whose batch smoothing waits (``defer_smoothing``)."""

    @property
    def anchored(self) -> bool:
        """False when the open stride's foothold is unknown (:data:`UNANCHORED`)."""
        return self.start_reason not in UNANCHORED

    def foot_strike(self) -> StrideSummary | None:
        """Close the open stride (if any); the next frame starts a new one."""
        summary = self.close() if self.graph is not None else None
        self.pending = "foot_strike"
        return summary

    def close_if_missed(self, t_s: float) -> None:
        """A stride longer than ``priors.max_stride_s``: a missed foot strike, closed here."""
        max_s = self.cfg.priors.max_stride_s
        if self.graph is not None and self.pending is None and t_s - self._t0_s > max_s:
            log.warning("t=%.3f s: stride longer than %.2f s: a missed foot strike", t_s, max_s)
            self.close()
            self.pending = "missed_foot_strike"

    def start(
        self, t_s: float, anchor: KinematicMeasurement | None, foot_loaded: bool
    ) -> list[str]:
        """A new stride graph at ``t_s`` with its first state's priors; returns frame flags."""
        reason = self.pending or "first_stride"
        if self._last_nav is None:
            reason = "first_stride"
        flags = [reason] if reason != "foot_strike" else []
        if self._last_nav is None:  # first stride of the session: gravity-aligned, weak priors
            priors = first_stride_priors(
                self.cfg.priors, self.camera_T_imu, anchor, self.imu.gravity(t_s)
            )
        else:
            t_last, nav, cov_x, cov_v, cov_b = self._last_nav
            pred, cov_x, cov_v, carry_flags = self.imu.carry(t_last, nav, cov_x, cov_v, t_s)
            flags += carry_flags
            unloaded_first = self.start_reason == "first_stride" and not self._started_loaded
            priors = carried_priors(
                self.cfg.priors,
                self.camera_T_imu,
                reason,
                pred,
                cov_x,
                cov_v,
                nav.bias,
                cov_b,
                anchor,
                unloaded_first,
            )
        flags += priors.flags
        if priors.old_stride_T_imu is not None:  # a new stride frame: chain it
            new_T_imu = priors.stride_T_imu.matrix()
            self.world_T_stride = (
                self.world_T_stride @ priors.old_stride_T_imu @ np.linalg.inv(new_T_imu)
            )
        self._new_graph(t_s, priors, flags)
        self.start_reason = reason
        self.pending = None
        self._started_loaded = bool(foot_loaded)
        return flags

    def _new_graph(self, t_s: float, p: StartPriors, flags: list[str]) -> None:
        cfg = self.cfg
        g = StrideGraph(
            cfg.isam2_relinearize_threshold,
            (cfg.isam2_velocity_relinearize_threshold, cfg.isam2_accel_bias_relinearize_threshold),
        )
        tagged = [
            ("prior", factors.pose_prior(0, p.stride_T_imu, p.cov_pose)),
            ("prior", factors.velocity_prior(0, p.velocity_m_s, p.cov_velocity)),
            ("prior", factors.bias_prior(0, p.bias, p.cov_bias)),
        ]
        values = gtsam.Values()
        values.insert(X(0), p.stride_T_imu)
        values.insert(V(0), p.velocity_m_s)
        values.insert(B(0), p.bias)
        g.add_state(t_s, tagged, values, None)
        g.flags.update(f for f in flags if f != "first_stride")
        self.graph = g
        self._t0_s = t_s
        self._frames = []
        self._counts = {"icp_ok": 0, "icp_rej": 0, "kin": 0, "gap": 0}

    def count(
        self, pred: Prediction, kept: list[str], gate: GateDecision | None, flags: list[str]
    ) -> list[str]:
        """Count a frame's factors (``kept`` tags) and flags into the stride's summary;
        returns the frame's ICP flag (``icp_rejected``/``icp_dropped``) if any."""
        g, c = self.graph, self._counts
        if not pred.segment.ok:
            c["gap"] += 1
            g.flags.add(pred.segment.reason)
        if any(f.startswith("kin_inconsistent") for f in flags):
            g.flags.add("kin_inconsistent")
        c["kin"] += "kin" in kept
        if "icp" in kept:
            c["icp_ok"] += 1
        elif gate is not None:
            c["icp_rej"] += 1
            return ["icp_rejected" if not gate.accepted else "icp_dropped"]
        return []

    def estimate(self, index, k, t_s, flags, gate, kept, t_start) -> FrameEstimate:
        """The frame's online estimate (state ``k`` of the open stride), recorded."""
        g = self.graph
        stride_T_camera = g.estimate.atPose3(X(k)).matrix() @ np.linalg.inv(self.camera_T_imu)
        cov = None
        if self.cfg.covariances:
            cov = factors.imu_cov_to_camera(g.marginal_covariance(X(k)), self.camera_T_imu)
        est = FrameEstimate(
            frame_index=index,
            stride_index=len(self.results.strides),
            k=k,
            t_s=float(t_s),
            stride_T_camera=stride_T_camera,
            world_T_camera=self.world_T_stride @ stride_T_camera,
            flags=tuple(flags),
            gate=None if gate is None else gate.record(),  # the factor holds the matrices
            kinematic_factor="kin" in kept,
            imu_factor="imu" in kept,
            update_s=time.perf_counter() - t_start,
            covariance=cov,
            stride_start=k == 0,
        )
        self.results.frames.append(est)
        self._frames.append(est)
        return est

    def close(self) -> StrideSummary:
        """Smooth the open stride, keep its end state for the next one, summarise it. With
        ``defer_smoothing`` the end state is iSAM2's and the smoothing is queued
        (:meth:`smooth_deferred`)."""
        g = self.graph
        defer = self.cfg.smoothing and self.cfg.defer_smoothing
        result, marginals, smoothing_s = g.smooth(self.cfg.smoothing and not defer)
        n = g.n_states
        last = g.nav(n - 1, result)
        marginal = g.marginal_covariance  # online iSAM2 when the smoothed one failed
        if marginals is not None:

            def marginal(key):
                return np.asarray(marginals.marginalCovariance(key))

        end = tuple(marginal(key(n - 1)) for key in (X, V, B))
        covs = None
        if marginals is not None and self.cfg.covariances:
            covs = np.array(
                [factors.imu_cov_to_camera(marginal(X(k)), self.camera_T_imu) for k in range(n)]
            )
        self._last_nav = (g.t_s[-1], last, *end)
        summary = self._summary(result, covs, smoothing_s, last)
        self.results.strides.append(summary)
        if defer:
            summary.flags = (*summary.flags, "smoothing_deferred")
            self.deferred.append((summary, g))
        self.graph = None
        return summary

    def smooth_deferred(self, keep: int = 0) -> list[StrideSummary]:
        """Run the queued smoothings, oldest first, until ``keep`` strides wait: each
        summary's smoothed poses (and covariances, when asked for) are replaced by the batch
        solution and its graph is released; returns the strides updated."""
        done = []
        inv_ext = np.linalg.inv(self.camera_T_imu)
        while len(self.deferred) > keep:
            summary, g = self.deferred.pop(0)
            result, marginals, smoothing_s = g.smooth(True, marginals=self.cfg.covariances)
            summary.smoothed_stride_T_camera = np.array(
                [result.atPose3(X(k)).matrix() @ inv_ext for k in range(g.n_states)]
            )
            if marginals is not None:
                summary.smoothed_covariances = np.array(
                    [
                        factors.imu_cov_to_camera(
                            np.asarray(marginals.marginalCovariance(X(k))), self.camera_T_imu
                        )
                        for k in range(g.n_states)
                    ]
                )
            summary.smoothing_s = smoothing_s
            summary.flags = tuple(sorted({*summary.flags, *g.flags} - {"smoothing_deferred"}))
            done.append(summary)
        return done

    def _summary(self, result, covs, smoothing_s: float, last: NavEstimate) -> StrideSummary:
        g, c = self.graph, self._counts
        inv_ext = np.linalg.inv(self.camera_T_imu)
        return StrideSummary(
            index=len(self.results.strides),
            t_start_s=g.t_s[0],
            t_end_s=g.t_s[-1],
            start=self.start_reason,
            world_T_stride=self.world_T_stride.copy(),
            frame_indices=[f.frame_index for f in self._frames],
            t_s=np.array(g.t_s),
            online_stride_T_camera=np.array([f.stride_T_camera for f in self._frames]),
            smoothed_stride_T_camera=np.array(
                [result.atPose3(X(k)).matrix() @ inv_ext for k in range(g.n_states)]
            ),
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


def make_stride_chain(
    config: BackendConfig, camera_T_imu: np.ndarray, imu: ImuPredictor
) -> StrideChain:
    """The stride start/close component of :class:`~graph_slam.backend.estimator.StrideSLAM`."""
    return StrideChain(config, camera_T_imu, imu)

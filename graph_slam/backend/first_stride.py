"""The session's first stride smoothed again once the first foot strike's anchor is known.

A recording usually starts mid-walk: its first stride (``first_stride``) begins at the first
frame, not at a foot strike. Its frame's up vector is the accelerometer mean over the short
window before that frame, taken while the leg swings: off by up to tens of degrees (the IMU's
up at a session's first strike was measured 13° off the floor plane). The first state's
anchor holds that tilt tightly, and the stride's IMU factors then integrate gravity along the
wrong axis (½·g·sin θ·t²: 0.1–0.2 m over 0.4 s at 13°); the smoothed poses before the first
strike were 56–150 mm off where the rest of the walk was within 5 mm.

The first foot strike brings a good up vector (the IMU's, fused with the floor plane:
:class:`graph_slam.strides.anchor.StrideAnchor`). Offline, that is enough to fix the first
stride (:class:`FirstStrideRefit`):

1. **at the first strike** (:meth:`FirstStrideRefit.strike`, causal): the new anchor's up
   vector is carried back by the gyro to the first stride's last state (the preintegration
   from that state to the new stride's first frame is kept), with the anchor's tilt σ;
2. **at the end of the run** (:meth:`FirstStrideRefit.apply`, the smoothed output only: the
   online poses stay as they were): the first stride's graph again, with its first state's
   tilt σ relaxed to ``priors.first_stride_refit_tilt_sigma_rad`` about the stride frame's
   x/y axes (yaw and position keep defining the frame) and an attitude factor
   (``AttitudeFactorPose3``) at its last state, batch-smoothed (LM); then again with a prior
   on its last velocity: the second stride's first velocity (from its own ICP and stance
   factors; the first stride's, in swing, is barely observable) carried back by the kept
   preintegration. The new poses are expressed in the first stride's frame as it was (the
   rigid motion that best maps them onto the earlier smoothed poses, :func:`frame_fit`), so
   its terrain maps and grids, fused at its close and not fused again, stay in their frame
   and the world frame stays where it was. The second stride's ``world_T_stride`` is
   chained again from the new end state and the later strides follow it rigidly. Only the
   smoothed output changes: the online world poses keep the chain they had (from the second
   stride on they differ from the smoothed ones by that rigid correction). Flag
   ``first_stride_refit`` (``first_stride_refit_failed`` when the smoothing failed: the
   earlier poses stay).

Off with ``priors.first_stride_refit: false``.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import gtsam
import numpy as np

from graph_slam.backend import noise
from graph_slam.backend.config import PriorConfig
from graph_slam.backend.keys import B, V, X
from graph_slam.backend.measurements import KinematicMeasurement
from graph_slam.backend.results import StrideSummary
from graph_slam.backend.stride_graph import NavEstimate, StrideGraph, _finite_state
from graph_slam.strides.kinematics import tilt_covariance

log = logging.getLogger(__name__)

UP = np.array([0.0, 0.0, 1.0])


@dataclass(frozen=True, eq=False)
class StrikeAttitude:
    """What the first foot strike tells the first stride: up at its last state and the IMU's
    motion from that state to the new stride's first frame."""

    up_in_imu: np.ndarray
    """Unit up vector at the first stride's last state, IMU frame."""
    sigma_rad: float
    """Its σ (the anchor's tilt σ)."""
    pim: gtsam.PreintegratedCombinedMeasurements
    """Last state -> the new stride's first frame."""
    stride_T_imu: np.ndarray
    """The new stride's first state (its anchor, IMU frame)."""


def anchor_tilt_sigma_rad(stride_T_camera: np.ndarray, cov: np.ndarray) -> float:
    """The anchor's tilt σ: its covariance's rotation about the stride frame's x and y axes
    (RMS of the two), ``cov`` camera local, rotation first."""
    from kinematics.conversions import adjoint_rot_first

    ad = adjoint_rot_first(stride_T_camera)
    left = ad @ np.asarray(cov, float) @ ad.T
    return float(np.sqrt(max(0.5 * (left[0, 0] + left[1, 1]), 0.0)))


def strike_attitude(
    anchor: KinematicMeasurement, camera_T_imu: np.ndarray, seg_pim
) -> StrikeAttitude:
    """:class:`StrikeAttitude` from the first strike's anchor and the preintegration from the
    first stride's last state to the anchor's frame (``seg_pim``)."""
    stride_T_imu = np.asarray(anchor.stride_T_camera, float) @ camera_T_imu
    up_now = stride_T_imu[:3, :3].T @ UP  # up in the IMU frame at the anchor
    last_R_now = np.asarray(seg_pim.deltaRij().matrix())
    up_last = last_R_now @ up_now
    sigma = anchor_tilt_sigma_rad(anchor.stride_T_camera, anchor.covariance)
    return StrikeAttitude(up_last / np.linalg.norm(up_last), sigma, seg_pim, stride_T_imu)


def relaxed_pose_prior(prior: gtsam.PriorFactorPose3, sigma_rad: float) -> gtsam.PriorFactorPose3:
    """``prior`` with its tilt about the stride frame's x/y axes given σ ``sigma_rad``."""
    mean = prior.prior()
    cov = np.asarray(prior.noiseModel().covariance(), float)
    cov = tilt_covariance(mean.matrix(), cov, sigma_rad)
    return gtsam.PriorFactorPose3(prior.keys()[0], mean, noise.covariance(cov))


class FirstStrideRefit:
    """Keeps the session's first stride (and the second, for its first velocity) until the end
    of the run, then smooths the first again (module docstring)."""

    def __init__(self, config: PriorConfig, camera_T_imu: np.ndarray):
        self.cfg = config
        self.camera_T_imu = np.asarray(camera_T_imu, float)
        self.graph: StrideGraph | None = None
        self.summary: StrideSummary | None = None
        self.attitude: StrikeAttitude | None = None
        self.next_graph: StrideGraph | None = None
        self.finished = False
        """The run has ended (:meth:`apply` was called)."""

    def keep(self, summary: StrideSummary, graph: StrideGraph) -> None:
        """At a stride's close: the session's first stride (begun without a strike) is kept,
        and the second when it began at the strike that gave the up vector."""
        if self.cfg.first_stride_refit and summary.index == 0 and summary.start == "first_stride":
            self.summary, self.graph = summary, graph
        elif summary.index == 1 and self.attitude is not None:
            self.next_graph = graph

    @property
    def waiting(self) -> bool:
        """The first stride is kept and the first strike's up vector not yet known."""
        return self.graph is not None and self.attitude is None

    def strike(self, reason: str, anchor: KinematicMeasurement | None, imu, last_nav, t_s) -> None:
        """The second stride starts at ``t_s`` (``reason``, ``anchor``); ``imu``: the chain's
        :class:`~graph_slam.backend.prediction.ImuPredictor`; ``last_nav``: the first
        stride's end ``(t_s, NavEstimate, ...)``. Without a foot strike's anchor, or without
        IMU across it, the first stride is let go."""
        if not self.waiting:
            return
        if reason != "foot_strike" or anchor is None or last_nav is None:
            self.release()
            return
        t_last_s, nav = last_nav[0], last_nav[1]
        seg = imu.buffer.integrate(t_last_s, t_s, nav.bias) if t_s > t_last_s else None
        if seg is None or not seg.ok:
            self.release()  # nothing to carry the up vector back
            return
        self.attitude = strike_attitude(anchor, self.camera_T_imu, seg.pim)

    def release(self) -> None:
        self.graph = self.summary = self.attitude = self.next_graph = None

    def apply(self, strides: list[StrideSummary], deferred: list) -> bool:
        """At the end of a run: smooth the first stride again and chain the second to it
        (module docstring). ``deferred``: the chain's queue of strides waiting for their
        smoothing; while the first waits there, nothing is done (called again after it).
        Returns whether the poses changed."""
        self.finished = True
        if self.graph is None or self.attitude is None or self.next_graph is None:
            self.release()
            return False
        g, s, a = self.graph, self.summary, self.attitude
        if any(dg is g for _, dg in deferred):
            return False  # after its deferred smoothing (StrideChain.smooth_deferred)
        values = self._solve(g, a, next_velocity(self.next_graph))
        self.release()
        if values is None:
            s.flags = tuple(sorted({*s.flags, "first_stride_refit_failed"}))
            return False
        n = g.n_states
        nav = g.nav(n - 1, values)
        pred = a.pim.predict(gtsam.NavState(nav.stride_T_imu, nav.velocity_m_s), nav.bias)
        inv_ext = np.linalg.inv(self.camera_T_imu)
        new = np.array([values.atPose3(X(k)).matrix() @ inv_ext for k in range(n)])
        old_T_new = frame_fit(s.smoothed_stride_T_camera, new)  # the stride frame as it was
        s.smoothed_stride_T_camera = old_T_new @ new
        # the second stride chains from the new end state; the later ones follow it rigidly
        next_T_imu = old_T_new @ pred.pose().matrix()
        world_T_next = s.world_T_stride @ next_T_imu @ np.linalg.inv(a.stride_T_imu)
        correction = world_T_next @ np.linalg.inv(strides[1].world_T_stride)
        for later in strides[1:]:
            later.world_T_stride = correction @ later.world_T_stride
        s.velocity_end_m_s = old_T_new[:3, :3] @ nav.velocity_m_s
        s.bias_end = np.asarray(nav.bias.vector())
        s.flags = tuple(sorted({*s.flags, "first_stride_refit"}))
        return True

    def _solve(self, g: StrideGraph, a: StrikeAttitude, body_v) -> gtsam.Values | None:
        """LM over the first stride with the relaxed first tilt and the strike's attitude,
        then again with the second stride's first velocity carried back (``body_v``: that
        velocity in its IMU frame and its covariance; None: not known)."""
        graph = gtsam.NonlinearFactorGraph(g.graph)
        first = graph.at(0)
        if g.factor_tags[0] != "prior" or not isinstance(first, gtsam.PriorFactorPose3):
            log.warning("first stride: no pose prior to relax; not smoothed again")
            return None
        graph.replace(0, relaxed_pose_prior(first, self.cfg.first_stride_refit_tilt_sigma_rad))
        model = gtsam.noiseModel.Isotropic.Sigma(2, max(a.sigma_rad, 1e-4))
        last = g.n_states - 1
        graph.add(
            gtsam.AttitudeFactorPose3(X(last), gtsam.Unit3(UP), model, gtsam.Unit3(a.up_in_imu))
        )
        values = _lm(graph, g.estimate, g.n_states)
        for _ in range(2 if body_v is not None and values is not None else 0):
            with_v = gtsam.NonlinearFactorGraph(graph)
            with_v.add(carried_back_velocity(last, values, a.pim, *body_v))
            values = _lm(with_v, values, g.n_states)
            if values is None:
                break
        return values


def frame_fit(old_T_camera: np.ndarray, new_T_camera: np.ndarray) -> np.ndarray:
    """``old_T_new``: the rigid motion that best maps the poses ``new_T_camera`` onto
    ``old_T_camera`` (n×4×4; NaN poses left out): the chordal mean of the rotations, then the
    mean of the positions. Identity when none is finite."""
    ok = np.isfinite(old_T_camera).all(axis=(1, 2)) & np.isfinite(new_T_camera).all(axis=(1, 2))
    out = np.eye(4)
    if not ok.any():
        return out
    old, new = old_T_camera[ok], new_T_camera[ok]
    u, _, vt = np.linalg.svd(np.einsum("kij,klj->il", old[:, :3, :3], new[:, :3, :3]))
    rot = u @ np.diag([1.0, 1.0, np.linalg.det(u @ vt)]) @ vt
    out[:3, :3] = rot
    out[:3, 3] = np.mean(old[:, :3, 3] - new[:, :3, 3] @ rot.T, axis=0)
    return out


def next_velocity(g: StrideGraph) -> tuple[np.ndarray, np.ndarray] | None:
    """The stride's first velocity in its IMU frame and its covariance (iSAM2's)."""
    try:
        rot = g.estimate.atPose3(X(0)).rotation().matrix()
        v = np.asarray(g.estimate.atVector(V(0)))
        cov = rot.T @ g.marginal_covariance(V(0)) @ rot
    except RuntimeError as err:
        log.warning("first stride: no velocity from the next stride (%s)", err)
        return None
    return rot.T @ v, cov


def carried_back_velocity(k: int, values: gtsam.Values, pim, body_v, cov_body_v):
    """A prior on ``V(k)``: the velocity ``pim`` later (``body_v``, IMU frame then) carried
    back by the preintegration, at the rotation of ``X(k)`` in ``values``
    (``v_j = v_i + g·Δt + R_i·ΔV``)."""
    nav = NavEstimate(values.atPose3(X(k)), np.asarray(values.atVector(V(k))),
                      values.atConstantBias(B(k)))  # fmt: skip
    rot_i = nav.stride_T_imu.rotation().matrix()
    rot_j = rot_i @ np.asarray(pim.deltaRij().matrix())
    still = pim.predict(gtsam.NavState(nav.stride_T_imu, np.zeros(3)), nav.bias)
    v_i = rot_j @ body_v - np.asarray(still.velocity())
    cov = rot_j @ cov_body_v @ rot_j.T + rot_i @ np.asarray(pim.preintMeasCov())[6:9, 6:9] @ rot_i.T
    return gtsam.PriorFactorVector(V(k), v_i, noise.covariance(cov))


def _lm(graph: gtsam.NonlinearFactorGraph, init: gtsam.Values, n: int) -> gtsam.Values | None:
    try:
        params = gtsam.LevenbergMarquardtParams()
        params.setMaxIterations(50)
        params.setLinearSolverType("MULTIFRONTAL_QR")
        values = gtsam.LevenbergMarquardtOptimizer(graph, init, params).optimize()
    except RuntimeError as err:  # GTSAM's exceptions arrive as bare RuntimeError
        log.warning("first stride: smoothing again failed (%s)", err)
        return None
    return values if all(_finite_state(values, k) for k in range(n)) else None

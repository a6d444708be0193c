"""IMU prediction between frames: preintegration, gap bridging, the predicted covariance.

:class:`ImuPredictor` owns the :class:`~graph_slam.backend.imu.ImuBuffer` and answers:

* :meth:`ImuPredictor.predict` — the new state of a frame from the stride graph's last one:
  ``pim.predict`` with a ``CombinedImuFactor`` when the interval's samples are usable, else
  (an ``imu_gap``) a constant-velocity guess and weak :func:`~graph_slam.backend.factors.
  gap_bridge_factors`. The bridge builder is also handed to the graph, which adds bridges when
  it has to drop the IMU factor. The predicted pose's covariance for the stance gate is
  computed on request (:meth:`Prediction.covariance`: it needs iSAM2 marginals);
* :meth:`ImuPredictor.carry` — the previous stride's end state propagated to a new stride's
  first frame, with the preintegration covariance added;
* :meth:`ImuPredictor.up_at` — the up vector at a time: the caller's (:class:`StrikeUp`)
  carried by the gyro, else the accelerometer mean over ``kinematics.gravity_window_s``.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass, field

import gtsam
import numpy as np

from graph_slam.backend import factors
from graph_slam.backend.config import BackendConfig
from graph_slam.backend.imu import ImuBuffer, ImuCheck, ImuSegment
from graph_slam.backend.keys import B, V, X
from graph_slam.backend.stride_graph import NavEstimate, StrideGraph
from graph_slam.errors import EstimationError

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class StrikeUp:
    """The caller's up vector at a foot strike: ``up_in_imu`` holds at ``t_s``; ``sigma_rad``
    (None: unknown) is its direction's σ."""

    t_s: float
    up_in_imu: np.ndarray
    sigma_rad: float | None = None
    assumed: bool = False
    """The up vector rests on an assumption (a plane taken as level at a session's first
    strike): the stride's bias is not trusted (``priors.loose_tilt_bias_*``)."""

    @classmethod
    def checked(
        cls, t_s, up_in_imu, up_sigma_rad=None, up_t_s=None, assumed=False
    ) -> StrikeUp | None:
        """Validate ``foot_strike``'s arguments (:class:`EstimationError` stating the rule)."""
        if up_sigma_rad is not None and not (np.isfinite(up_sigma_rad) and up_sigma_rad > 0):
            raise EstimationError(
                f"foot_strike: up_sigma_rad must be finite and > 0, got {up_sigma_rad!r}"
            )
        if up_in_imu is None:
            return None
        up = np.asarray(up_in_imu, float)
        if up.shape != (3,) or not np.isfinite(up).all() or np.linalg.norm(up) < 1e-9:
            raise EstimationError(
                f"foot_strike: up_in_imu must be a finite non-zero 3-vector, got {up_in_imu!r}"
            )
        return cls(float(t_s if up_t_s is None else up_t_s), up, up_sigma_rad, bool(assumed))


@dataclass(eq=False)
class Prediction:
    """The predicted state ``k`` and the IMU-side factors linking it to ``k - 1``."""

    k: int
    nav: gtsam.NavState
    bias: gtsam.imuBias.ConstantBias
    segment: ImuSegment
    tagged: list[tuple[str, object]]
    """``("imu", CombinedImuFactor)``, or ``("bridge", ...)`` factors across a gap."""
    bridge: Callable[[], list]
    covariance: Callable[[], np.ndarray | None]
    """Covariance of the predicted pose (IMU local), computed on request."""
    flags: list[str] = field(default_factory=list)

    @property
    def pose(self) -> gtsam.Pose3:
        return self.nav.pose()

    def values(self) -> gtsam.Values:
        """Initial values of ``X(k)``, ``V(k)``, ``B(k)`` for iSAM2."""
        values = gtsam.Values()
        values.insert(X(self.k), self.nav.pose())
        values.insert(V(self.k), self.nav.velocity())
        values.insert(B(self.k), self.bias)
        return values


class ImuPredictor:
    """IMU samples in, predictions out (see the module docstring)."""

    def __init__(self, config: BackendConfig):
        self.cfg = config
        self.buffer = ImuBuffer(config.imu)

    @property
    def counts(self) -> dict[str, int]:
        return self.buffer.counts

    def add(self, t_s, gyro_rad_s, accel_m_s2) -> ImuCheck:
        return self.buffer.add(t_s, gyro_rad_s, accel_m_s2)

    def drop_before(self, t_s: float) -> None:
        self.buffer.drop_before(t_s)

    def gravity(self, t_s: float) -> np.ndarray | None:
        """Accelerometer mean over ``kinematics.gravity_window_s`` before ``t_s``."""
        return self.buffer.mean_accel(t_s - self.cfg.kinematics.gravity_window_s, t_s)

    def up_at(self, t_s: float, strike_up: StrikeUp | None) -> np.ndarray | None:
        """Up in the IMU frame at ``t_s``: ``strike_up`` rotated from its time to ``t_s`` by the
        gyro, else (or without IMU to carry it) :meth:`gravity`."""
        if strike_up is not None:
            if t_s <= strike_up.t_s:
                return strike_up.up_in_imu
            seg = self.buffer.integrate(strike_up.t_s, t_s, gtsam.imuBias.ConstantBias())
            if seg.ok:  # strike_R_now: up_now = strike_R_nowᵀ · up_strike
                return np.asarray(seg.pim.deltaRij().matrix()).T @ strike_up.up_in_imu
            log.warning("t=%.3f s: no IMU to carry the strike's up vector (%s)", t_s, seg.reason)
        return self.gravity(t_s)

    def predict(self, g: StrideGraph, t_s: float) -> Prediction:
        """State ``k = g.n_states`` at ``t_s`` from ``k - 1`` (module docstring)."""
        k = g.n_states
        prev = g.nav(k - 1)
        dt = t_s - g.t_s[-1]
        seg = self.buffer.integrate(g.t_s[-1], t_s, prev.bias)
        v_body = prev.stride_T_imu.rotation().unrotate(prev.velocity_m_s)
        bridge = self._bridge_builder(k, dt, v_body)
        if seg.ok:
            nav = seg.pim.predict(gtsam.NavState(prev.stride_T_imu, prev.velocity_m_s), prev.bias)
            tagged, flags = [("imu", factors.imu_factor(k - 1, k, seg.pim))], []
        else:  # constant velocity in the body frame, weak bridges instead of the IMU factor
            step = gtsam.Pose3(gtsam.Rot3(), v_body * dt)
            nav = gtsam.NavState(prev.stride_T_imu.compose(step), prev.velocity_m_s)
            tagged, flags = [("bridge", f) for f in bridge()], [seg.reason]
        return Prediction(
            k,
            nav,
            prev.bias,
            seg,
            tagged,
            bridge,
            lambda: predicted_covariance(g, k, seg, dt),
            flags,
        )

    def _bridge_builder(self, k: int, dt_s: float, v_body: np.ndarray) -> Callable[[], list]:
        cfg, imu = self.cfg, self.cfg.imu

        def bridge() -> list:
            return factors.gap_bridge_factors(
                k - 1,
                k,
                dt_s,
                v_body,
                cfg.gap_bridge_rot_sigma_rad,
                cfg.gap_bridge_trans_sigma_m,
                imu.gravity_m_s2,
                imu.accel_random_walk_m_s3_sqrt_hz,
                imu.gyro_random_walk_rad_s2_sqrt_hz,
            )

        return bridge

    def carry(
        self, t_last_s: float, nav: NavEstimate, cov_x: np.ndarray, cov_v: np.ndarray, t_s: float
    ) -> tuple[gtsam.NavState, np.ndarray, np.ndarray, list[str]]:
        """``nav`` (at ``t_last_s``, covariances of pose and velocity) predicted to ``t_s``.

        Without usable IMU: constant velocity in the stride frame, pose σ grown by 0.05 rad and
        2 m/s·dt, velocity σ by g·dt (flagged with the segment's reason)."""
        seg = self.buffer.integrate(t_last_s, t_s, nav.bias) if t_s > t_last_s else None
        if seg is not None and seg.ok:
            pred = seg.pim.predict(gtsam.NavState(nav.stride_T_imu, nav.velocity_m_s), nav.bias)
            pcov = np.asarray(seg.pim.preintMeasCov())
            return pred, cov_x + pcov[:6, :6], cov_v + pcov[6:9, 6:9], []
        flags = [] if seg is None else [seg.reason]
        dt = max(t_s - t_last_s, 0.0)
        pred = gtsam.NavState(
            gtsam.Pose3(
                nav.stride_T_imu.rotation(),
                nav.stride_T_imu.translation() + nav.velocity_m_s * dt,
            ),
            nav.velocity_m_s,
        )
        cov_x = cov_x + np.diag(np.r_[np.full(3, 0.05**2), np.full(3, (2.0 * dt) ** 2)])
        cov_v = cov_v + np.eye(3) * (self.cfg.imu.gravity_m_s2 * dt) ** 2
        return pred, cov_x, cov_v, flags


def predicted_covariance(g: StrideGraph, k: int, seg: ImuSegment, dt_s: float) -> np.ndarray | None:
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


def make_imu_predictor(config: BackendConfig) -> ImuPredictor:
    """The IMU prediction component of :class:`~graph_slam.backend.estimator.StrideSLAM`."""
    return ImuPredictor(config)

"""Simulated back-end measurements from a ground-truth camera trajectory (tests, examples).

Not the gait simulator (``graph_slam.sim``): this turns *known* camera poses into the records
the back end consumes — ICP odometry between consecutive frames, leg-kinematic camera poses
in the stride frame — with seeded Gaussian noise drawn from the very covariance that is
reported, so that an estimator's errors can be judged against a known answer.

Stride frames of the truth: at each foot strike, origin on the floor (z = 0) below the camera,
z up, x along the world x axis (the walking direction of :mod:`graph_slam.session.synthetic`).
"""

from __future__ import annotations

from dataclasses import dataclass

import gtsam
import numpy as np

from graph_slam.backend.measurements import IcpMeasurement, KinematicMeasurement


@dataclass(frozen=True)
class SimulatedFrame:
    """What the back end is given at one frame, and the truth to judge it by."""

    t_s: float
    strike_before: bool
    """A foot strike happens at this frame's time (call ``foot_strike`` first)."""
    foot_loaded: bool
    icp: IcpMeasurement | None
    kinematics: KinematicMeasurement
    stride_T_camera_true: np.ndarray
    world_T_camera_true: np.ndarray
    stride_index: int
    phase: float


def _noisy(a_T_b: np.ndarray, cov: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    xi = rng.multivariate_normal(np.zeros(6), cov)
    return a_T_b @ gtsam.Pose3.Expmap(xi).matrix()


def simulate_measurements(
    t_s: np.ndarray,
    world_T_camera: np.ndarray,
    strikes_s: np.ndarray,
    *,
    stance_fraction: float = 0.6,
    icp_sigmas: tuple[float, float] = (1e-3, 1e-3),
    kin_sigmas: tuple[float, float] = (np.deg2rad(0.5), 5e-3),
    swing_icp_drop: float = 1.0,
    seed: int = 0,
) -> list[SimulatedFrame]:
    """One :class:`SimulatedFrame` per frame time.

    ``icp_sigmas``/``kin_sigmas``: (rotation rad, translation m) per axis. In swing, each
    registration fails (``ok=False``) with probability ``swing_icp_drop``.
    """
    rng = np.random.default_rng(seed)
    cov_icp = np.diag(np.r_[np.full(3, icp_sigmas[0] ** 2), np.full(3, icp_sigmas[1] ** 2)])
    cov_kin = np.diag(np.r_[np.full(3, kin_sigmas[0] ** 2), np.full(3, kin_sigmas[1] ** 2)])
    info_icp = np.linalg.inv(cov_icp)
    strikes = np.asarray(strikes_s, float)
    out: list[SimulatedFrame] = []
    world_T_stride = np.eye(4)
    stride = -1
    for i, (t, w_T_c) in enumerate(zip(t_s, world_T_camera, strict=True)):
        past = np.flatnonzero(strikes <= t + 1e-9)
        s = int(past[-1]) if past.size else -1
        strike_now = s != stride
        if strike_now:
            stride = s
            world_T_stride = np.eye(4)
            world_T_stride[:2, 3] = w_T_c[:2, 3]
        t0 = strikes[s] if s >= 0 else t_s[0]
        period = strikes[1] - strikes[0] if strikes.size > 1 else t_s[-1] - t_s[0] + 1e-3
        t1 = strikes[s + 1] if s + 1 < strikes.size else t0 + period
        phase = float((t - t0) / (t1 - t0))
        loaded = phase < stance_fraction
        s_T_c = np.linalg.inv(world_T_stride) @ w_T_c
        icp = None
        if i > 0:
            truth = np.linalg.inv(world_T_camera[i - 1]) @ w_T_c
            if not loaded and rng.random() < swing_icp_drop:
                icp = IcpMeasurement(
                    i,
                    i - 1,
                    np.eye(4),
                    np.zeros((6, 6)),
                    0.0,
                    np.inf,
                    0,
                    ok=False,
                    reason="simulated swing failure",
                )
            else:
                icp = IcpMeasurement(
                    source_index=i,
                    target_index=i - 1,
                    target_T_source=_noisy(truth, cov_icp, rng),
                    information=info_icp,
                    fitness=0.9,
                    inlier_rmse_m=0.004,
                    correspondences=2000,
                )
        kin = KinematicMeasurement(_noisy(s_T_c, cov_kin, rng), cov_kin)
        out.append(
            SimulatedFrame(
                float(t), strike_now and i > 0, loaded, icp, kin, s_T_c, w_T_c, stride, phase
            )
        )
    return out

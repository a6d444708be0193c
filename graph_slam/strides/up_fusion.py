"""The up vector at a foot strike from two sources: the accelerometer and the graph's own
estimate of the IMU's attitude.

The accelerometer's up (:class:`graph_slam.strides.gravity.GravityEstimator`, σ about
``gravity_sigma_rad`` in every direction) carries the mean acceleration of the last stride
(not zero on a ramp's or a stair's first strides, where the walker speeds up and climbs)
and the accelerometer's bias. The open stride's online estimate (its latest state's
attitude, carried to the strike by the gyro) knows the tilt about the thigh's lateral axis
well: the thigh swings about that axis, so the IMU factors tell the bias in the sagittal
plane from the tilt. About the heading it knows little (a lateral bias looks like a roll),
and its marginal covariance says so. :func:`fuse_with_graph` weighs the two by their
covariances in the plane normal to up, and keeps the accelerometer's alone when they
disagree beyond a χ² gate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

CHI2_2DOF_3SIGMA = 11.83
"""χ² of 2 degrees of freedom at the 3σ (99.73 %) level."""


@dataclass(frozen=True)
class GraphUp:
    """Up in the IMU frame at ``t_s`` from the estimator's attitude, with the covariance of
    that attitude (rotation, rad², IMU frame at ``t_s``, GTSAM's right perturbation)."""

    t_s: float
    up_in_imu: np.ndarray
    cov_rotation_rad2: np.ndarray
    lateral_in_imu: np.ndarray | None = None
    """The stride frame's lateral axis (y) in the IMU frame at ``t_s``: given, only the tilt
    about it (along the heading) is taken from the graph (module text)."""


@dataclass(frozen=True)
class FusedUp:
    up_in_imu: np.ndarray
    sigma_rad: float
    """The fused direction's largest σ (the anchor takes one σ for both tilt axes)."""
    mahalanobis2: float
    """The two sources' disagreement, χ² of 2 degrees of freedom."""
    fused: bool


def tangent_basis(up: np.ndarray) -> np.ndarray:
    """3×2: two unit vectors normal to ``up`` and to each other."""
    u = np.asarray(up, float) / np.linalg.norm(up)
    a = np.array([1.0, 0.0, 0.0]) if abs(u[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = a - (a @ u) * u
    e1 /= np.linalg.norm(e1)
    return np.column_stack([e1, np.cross(u, e1)])


def up_covariance(up: np.ndarray, cov_rotation_rad2: np.ndarray) -> np.ndarray:
    """3×3 covariance of the unit vector ``up = Rᵀ·z`` under ``R·Exp(δ)``, δ ~ N(0, Σ):
    ``d up = up × δ`` (the part of δ about ``up`` itself, the yaw, does not move it)."""
    u = np.asarray(up, float) / np.linalg.norm(up)
    cross = np.array([[0.0, -u[2], u[1]], [u[2], 0.0, -u[0]], [-u[1], u[0], 0.0]])
    return cross @ np.asarray(cov_rotation_rad2, float) @ cross.T


def fuse_with_graph(
    up_accel: np.ndarray,
    sigma_accel_rad: float,
    graph: GraphUp,
    gate_chi2: float = CHI2_2DOF_3SIGMA,
) -> FusedUp:
    """The accelerometer's up (isotropic σ) and the graph's (its covariance) fused by
    inverse covariance in the plane normal to the graph's up; the accelerometer's alone
    (``fused`` False) when their difference exceeds ``gate_chi2``."""
    ua = np.asarray(up_accel, float) / np.linalg.norm(up_accel)
    ug = graph.up_in_imu / np.linalg.norm(graph.up_in_imu)
    if graph.lateral_in_imu is None:
        e = tangent_basis(ug)
    else:  # e[:, 0]: the heading (tilt about the lateral axis), e[:, 1]: lateral
        lat = graph.lateral_in_imu - (graph.lateral_in_imu @ ug) * ug
        lat /= np.linalg.norm(lat)
        e = np.column_stack([np.cross(lat, ug), lat])
    cg = e.T @ up_covariance(ug, graph.cov_rotation_rad2) @ e
    ca = np.eye(2) * sigma_accel_rad**2
    d = e.T @ (ua - ug)
    if graph.lateral_in_imu is not None:  # roll: the accelerometer's alone
        return _fuse_heading(ua, sigma_accel_rad, ug, e, cg[0, 0], d[0], gate_chi2)
    s = cg + ca
    m2 = float(d @ np.linalg.solve(s, d))
    if not (np.isfinite(m2) and m2 <= gate_chi2):
        return FusedUp(ua, float(sigma_accel_rad), m2, False)
    gain = cg @ np.linalg.inv(s)
    fused = ug + e @ (gain @ d)
    cf = cg - gain @ cg
    sigma = math.sqrt(max(float(np.linalg.eigvalsh(0.5 * (cf + cf.T)).max()), 0.0))
    return FusedUp(fused / np.linalg.norm(fused), sigma, m2, True)


def _fuse_heading(ua, sigma_a, ug, e, var_g, d0, gate_chi2) -> FusedUp:
    """Only the tilt along the heading (``e[:, 0]``) fused; the lateral one the accelerometer's."""
    m2 = float(d0**2 / (var_g + sigma_a**2))
    if not (np.isfinite(m2) and m2 <= gate_chi2):
        return FusedUp(ua, float(sigma_a), m2, False)
    shift = -d0 * sigma_a**2 / (var_g + sigma_a**2)  # from the accelerometer's toward the graph's
    fused = ua + shift * e[:, 0]
    return FusedUp(fused / np.linalg.norm(fused), float(sigma_a), m2, True)

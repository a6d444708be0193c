"""SE(2) helpers: poses are ``a_T_b`` 3x3 homogeneous arrays; ``xyt`` is (x_m, y_m, theta_rad)."""

from __future__ import annotations

import numpy as np


def se2(x_m: float, y_m: float, theta_rad: float) -> np.ndarray:
    """The 3x3 homogeneous transform of a 2D pose."""
    c, s = np.cos(theta_rad), np.sin(theta_rad)
    return np.array([[c, -s, x_m], [s, c, y_m], [0.0, 0.0, 1.0]])


def xyt(a_T_b: np.ndarray) -> np.ndarray:
    """(x_m, y_m, theta_rad) of a 3x3 transform."""
    return np.array([a_T_b[0, 2], a_T_b[1, 2], np.arctan2(a_T_b[1, 0], a_T_b[0, 0])])


def inverse(a_T_b: np.ndarray) -> np.ndarray:
    """b_T_a."""
    rot = a_T_b[:2, :2]
    out = np.eye(3)
    out[:2, :2] = rot.T
    out[:2, 2] = -rot.T @ a_T_b[:2, 2]
    return out


def apply(a_T_b: np.ndarray, points_b: np.ndarray) -> np.ndarray:
    """Map (n, 2) points from frame b to frame a."""
    return points_b @ a_T_b[:2, :2].T + a_T_b[:2, 2]


def wrap_angle(theta_rad: np.ndarray | float) -> np.ndarray:
    """Angles wrapped to [-pi, pi)."""
    return (np.asarray(theta_rad) + np.pi) % (2 * np.pi) - np.pi


def to_pose2(a_T_b: np.ndarray):
    """The same transform as a ``gtsam.Pose2`` (gtsam imported here, lazily)."""
    import gtsam

    return gtsam.Pose2(*xyt(a_T_b))

"""Conversions between pose types: 4x4 arrays, ``pinocchio.SE3`` and ``gtsam.Pose3``.

All three represent ``a_T_b`` (maps points from frame b to frame a). Pinocchio and GTSAM are
imported inside the functions that need them, so importing this module is cheap.

Tangent-space ordering also differs: Pinocchio motions are [linear; angular], GTSAM Pose3
local coordinates are [rotation; translation]. :func:`swap_twist_order` converts 6-vectors,
6xN Jacobians and 6x6 covariances between the two (the permutation is its own inverse).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from kinematics.errors import KinematicsError

if TYPE_CHECKING:  # pragma: no cover
    import gtsam
    import pinocchio as pin

_PERM = np.array([3, 4, 5, 0, 1, 2])


def as_matrix4(a_T_b: Any) -> np.ndarray:
    """A 4x4 float array of a pose given as 4x4 array, ``pin.SE3`` or ``gtsam.Pose3``."""
    package = type(a_T_b).__module__.split(".")[0]
    if package == "pinocchio":
        return se3_to_matrix4(a_T_b)
    if package == "gtsam":
        return pose3_to_matrix4(a_T_b)
    return check_matrix4(a_T_b)


def not_rigid(a_T_b: Any, atol: float = 1e-6) -> np.ndarray:
    """The one rigid-transform check: per 4x4 of ``a_T_b`` (4x4 or Nx4x4), True where it is
    not a homogeneous rigid transform: an entry NaN or inf, the 3x3 block not orthonormal or
    its determinant not +1, the last row not 0 0 0 1 (each within ``atol``). Callers raise
    their own error from it (:func:`check_matrix4`; ``graph_slam.session.checks.check_pose``)."""
    poses = np.asarray(a_T_b, dtype=float).reshape(-1, 4, 4)
    finite = np.isfinite(poses).all(axis=(1, 2))
    poses = np.where(finite[:, None, None], poses, np.eye(4))
    rot = poses[:, :3, :3]
    ortho_err = np.abs(np.einsum("nij,nkj->nik", rot, rot) - np.eye(3)).max(axis=(1, 2))
    det_err = np.abs(np.linalg.det(rot) - 1.0)
    bottom_err = np.abs(poses[:, 3, :] - np.array([0.0, 0.0, 0.0, 1.0])).max(axis=1)
    return ~finite | (ortho_err > atol) | (det_err > atol) | (bottom_err > atol)


def check_matrix4(a_T_b: Any, name: str = "pose", atol: float = 1e-6) -> np.ndarray:
    """Validate a 4x4 homogeneous transform (:func:`not_rigid`)."""
    m = np.asarray(a_T_b, dtype=float)
    if m.shape != (4, 4):
        raise KinematicsError(f"{name}: expected a 4x4 homogeneous matrix, got shape {m.shape}")
    if not np.all(np.isfinite(m)):
        raise KinematicsError(f"{name}: contains NaN or inf")
    if not_rigid(m, atol)[0]:
        raise KinematicsError(
            f"{name}: not a rigid transform (the 3x3 block is not a rotation: orthonormal, "
            f"det +1; or the last row is not [0, 0, 0, 1], got {m[3].tolist()})"
        )
    return m


def matrix4_to_se3(a_T_b: np.ndarray) -> pin.SE3:
    """4x4 array -> ``pinocchio.SE3``."""
    import pinocchio as pin

    m = check_matrix4(a_T_b)
    return pin.SE3(m[:3, :3].copy(), m[:3, 3].copy())


def se3_to_matrix4(a_T_b: pin.SE3) -> np.ndarray:
    """``pinocchio.SE3`` -> 4x4 array."""
    return np.array(a_T_b.homogeneous, dtype=float)


def matrix4_to_pose3(a_T_b: np.ndarray) -> gtsam.Pose3:
    """4x4 array -> ``gtsam.Pose3``."""
    import gtsam

    m = check_matrix4(a_T_b)
    return gtsam.Pose3(gtsam.Rot3(m[:3, :3]), gtsam.Point3(*m[:3, 3]))


def pose3_to_matrix4(a_T_b: gtsam.Pose3) -> np.ndarray:
    """``gtsam.Pose3`` -> 4x4 array."""
    return np.array(a_T_b.matrix(), dtype=float)


def se3_to_pose3(a_T_b: pin.SE3) -> gtsam.Pose3:
    """``pinocchio.SE3`` -> ``gtsam.Pose3``."""
    return matrix4_to_pose3(se3_to_matrix4(a_T_b))


def pose3_to_se3(a_T_b: gtsam.Pose3) -> pin.SE3:
    """``gtsam.Pose3`` -> ``pinocchio.SE3``."""
    return matrix4_to_se3(pose3_to_matrix4(a_T_b))


def swap_twist_order(x: np.ndarray) -> np.ndarray:
    """Reorder [linear; angular] <-> [angular; linear] (Pinocchio <-> GTSAM).

    Works on a 6-vector, a 6xN Jacobian (rows) or a 6x6 covariance (rows and columns).
    """
    x = np.asarray(x, dtype=float)
    if x.shape == (6, 6):
        return x[np.ix_(_PERM, _PERM)]
    if x.ndim >= 1 and x.shape[0] == 6:
        return x[_PERM]
    raise KinematicsError(f"swap_twist_order: expected 6, 6xN or 6x6, got shape {x.shape}")


def skew(w: np.ndarray) -> np.ndarray:
    """The 3x3 cross-product matrix: ``skew(w) @ v == np.cross(w, v)``."""
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def adjoint_rot_first(a_T_b: np.ndarray) -> np.ndarray:
    """6x6 adjoint of ``a_T_b`` for twists ordered [rotation; translation] (GTSAM order).

    Maps a twist expressed in frame b to the same twist expressed in frame a:
    ``xi_a = Ad @ xi_b`` with ``Ad = [[R, 0], [skew(t) R, R]]``.
    """
    m = np.asarray(a_T_b, dtype=float)
    r, t = m[:3, :3], m[:3, 3]
    ad = np.zeros((6, 6))
    ad[:3, :3] = r
    ad[3:, 3:] = r
    ad[3:, :3] = skew(t) @ r
    return ad


def expmap_rot_first(xi: np.ndarray) -> np.ndarray:
    """SE(3) exponential of a twist [ω; v] (GTSAM order) as a 4x4 array (numpy only)."""
    xi = np.asarray(xi, dtype=float)
    w, v = xi[:3], xi[3:]
    theta = float(np.linalg.norm(w))
    k = skew(w)
    if theta < 1e-9:
        r = np.eye(3) + k
        jl = np.eye(3) + 0.5 * k
    else:
        a = np.sin(theta) / theta
        b = (1 - np.cos(theta)) / theta**2
        c = (theta - np.sin(theta)) / theta**3
        r = np.eye(3) + a * k + b * k @ k
        jl = np.eye(3) + b * k + c * k @ k
    m = np.eye(4)
    m[:3, :3] = r
    m[:3, 3] = jl @ v
    return m


def logmap_rot_first(a_T_b: np.ndarray) -> np.ndarray:
    """SE(3) logarithm of a 4x4 pose as a twist [ω; v] (GTSAM order; numpy only)."""
    m = np.asarray(a_T_b, dtype=float)
    r, t = m[:3, :3], m[:3, 3]
    cos_theta = np.clip((np.trace(r) - 1.0) / 2.0, -1.0, 1.0)
    theta = float(np.arccos(cos_theta))
    if theta < 1e-9:
        w = 0.5 * np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])
    elif np.pi - theta < 1e-6:
        raise KinematicsError("logmap_rot_first: rotation of ~180 deg is ambiguous")
    else:
        w = (
            theta
            / (2 * np.sin(theta))
            * np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])
        )
    k = skew(w)
    if theta < 1e-9:
        jl_inv = np.eye(3) - 0.5 * k
    else:
        jl_inv = (
            np.eye(3)
            - 0.5 * k
            + (1 / theta**2 - (1 + np.cos(theta)) / (2 * theta * np.sin(theta))) * k @ k
        )
    return np.concatenate([w, jl_inv @ t])

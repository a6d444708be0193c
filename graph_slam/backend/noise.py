"""Named noise-model builders. Pose3 sigmas and covariances are **rotation first** (rad),
then translation (m), in the pose's local (right-perturbation) coordinates, as GTSAM's Pose3.
Robust kernels are explicit: :func:`robust` wraps a base model with the named M-estimator.
"""

from __future__ import annotations

import gtsam
import numpy as np

from graph_slam.backend.config import RobustKernel

__all__ = ["RobustKernel"]


def pose_sigmas(rot_rad: float | np.ndarray, trans_m: float | np.ndarray) -> gtsam.noiseModel.Base:
    """Diagonal Pose3 noise: rotation sigmas (rad) first, then translation sigmas (m)."""
    rot = np.broadcast_to(np.asarray(rot_rad, float), (3,))
    trans = np.broadcast_to(np.asarray(trans_m, float), (3,))
    return gtsam.noiseModel.Diagonal.Sigmas(np.concatenate([rot, trans]))


def vector_sigmas(sigmas: float | np.ndarray, dim: int = 3) -> gtsam.noiseModel.Base:
    """Diagonal noise on a vector (velocity m/s, ...)."""
    return gtsam.noiseModel.Diagonal.Sigmas(np.broadcast_to(np.asarray(sigmas, float), (dim,)))


def bias_sigmas(accel_m_s2: float | np.ndarray, gyro_rad_s: float | np.ndarray):
    """Diagonal noise on ``imuBias.ConstantBias`` (GTSAM order: accelerometer, then gyro)."""
    acc = np.broadcast_to(np.asarray(accel_m_s2, float), (3,))
    gyr = np.broadcast_to(np.asarray(gyro_rad_s, float), (3,))
    return gtsam.noiseModel.Diagonal.Sigmas(np.concatenate([acc, gyr]))


def covariance(cov: np.ndarray) -> gtsam.noiseModel.Base:
    """Full Gaussian from a (positive-definite) covariance, symmetrised first."""
    cov = np.asarray(cov, float)
    return gtsam.noiseModel.Gaussian.Covariance(0.5 * (cov + cov.T))


def sqrt_information(r: np.ndarray) -> gtsam.noiseModel.Base:
    """Gaussian from a square root information matrix ``R`` (``RᵀR`` = information).

    Rows of zeros are allowed: those directions carry **no** information (a projected,
    rank-deficient ICP information). ``smart=False`` keeps GTSAM from turning it into a
    diagonal model with infinite sigmas.
    """
    return gtsam.noiseModel.Gaussian.SqrtInformation(np.asarray(r, float), False)


def sqrt_of_information(information: np.ndarray) -> np.ndarray:
    """A square ``R`` with ``RᵀR = information`` for a positive *semi*-definite matrix
    (eigen-decomposition; negative round-off eigenvalues are clipped to zero)."""
    info = 0.5 * (np.asarray(information, float) + np.asarray(information, float).T)
    lam, vec = np.linalg.eigh(info)
    lam = np.clip(lam, 0.0, None)
    return np.sqrt(lam)[:, None] * vec.T


def robust(base: gtsam.noiseModel.Base, kernel: RobustKernel, k: float) -> gtsam.noiseModel.Base:
    """Wrap ``base`` in an M-estimator; ``k`` is in whitened units (sigmas)."""
    if kernel == "none":
        return base
    est = {
        "huber": gtsam.noiseModel.mEstimator.Huber,
        "cauchy": gtsam.noiseModel.mEstimator.Cauchy,
        "tukey": gtsam.noiseModel.mEstimator.Tukey,
    }[kernel].Create(float(k))
    return gtsam.noiseModel.Robust.Create(est, base)

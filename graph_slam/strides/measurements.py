"""The kinematic measurement the stride stage hands the back end: the camera pose in the
stride frame from leg kinematics, with its covariance (frozen, checked on construction)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from graph_slam.errors import EstimationError


def _rigid(name: str, a_T_b: np.ndarray) -> np.ndarray:
    m = np.asarray(a_T_b, float)
    if m.shape != (4, 4) or not np.all(np.isfinite(m)):
        raise EstimationError(f"{name}: must be a finite 4×4 matrix, got shape {m.shape}")
    r = m[:3, :3]
    if (
        np.abs(r @ r.T - np.eye(3)).max() > 1e-6
        or abs(np.linalg.det(r) - 1) > 1e-6
        or np.abs(m[3] - [0, 0, 0, 1]).max() > 1e-9
    ):
        raise EstimationError(f"{name}: not a rigid transform (rotation orthonormal, det +1)")
    return m


@dataclass(frozen=True, eq=False)
class KinematicMeasurement:
    """The camera pose in the stride frame from leg kinematics, with its covariance.

    ``covariance``: 6×6, rotation first, camera local coordinates (right perturbation), as
    :meth:`kinematics.leg_model.LegModel.camera_covariance` returns it.
    """

    stride_T_camera: np.ndarray
    covariance: np.ndarray

    def __post_init__(self) -> None:
        object.__setattr__(
            self,
            "stride_T_camera",
            _rigid("KinematicMeasurement.stride_T_camera", self.stride_T_camera),
        )
        cov = np.asarray(self.covariance, float)
        if cov.shape != (6, 6) or not np.all(np.isfinite(cov)):
            raise EstimationError("KinematicMeasurement.covariance: must be a finite 6×6 matrix")
        if np.linalg.eigvalsh(0.5 * (cov + cov.T)).min() <= 0:
            raise EstimationError("KinematicMeasurement.covariance: must be positive definite")
        object.__setattr__(self, "covariance", cov)

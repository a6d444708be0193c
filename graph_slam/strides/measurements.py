"""The kinematic measurement the stride stage hands the back end: the camera pose in the
stride frame from leg kinematics, with its covariance (frozen, checked on construction)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from graph_slam.errors import EstimationError
from kinematics.conversions import not_rigid


def rigid_pose(name: str, a_T_b: np.ndarray) -> np.ndarray:
    """``a_T_b`` as a 4×4 float array, checked (:func:`kinematics.conversions.not_rigid`):
    an :class:`EstimationError` naming ``name`` when it is not a finite rigid transform."""
    m = np.asarray(a_T_b, float)
    if m.shape != (4, 4) or not_rigid(m)[0]:
        raise EstimationError(
            f"{name}: not a finite rigid 4×4 transform (rotation orthonormal, det +1, last row "
            f"0 0 0 1), got shape {m.shape}"
        )
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
            rigid_pose("KinematicMeasurement.stride_T_camera", self.stride_T_camera),
        )
        cov = np.asarray(self.covariance, float)
        if cov.shape != (6, 6) or not np.all(np.isfinite(cov)):
            raise EstimationError("KinematicMeasurement.covariance: must be a finite 6×6 matrix")
        if np.linalg.eigvalsh(0.5 * (cov + cov.T)).min() <= 0:
            raise EstimationError("KinematicMeasurement.covariance: must be positive definite")
        object.__setattr__(self, "covariance", cov)

"""Measurement records the back end consumes (frozen dataclasses, checked on construction).

:class:`IcpMeasurement` is what the back end needs from a registration; the front end's
``RegistrationResult`` converts into it with a one-line adapter (``graph_slam.frontend``).
The back end never imports open3d.
"""

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
class IcpMeasurement:
    """One registration between two frames of the *same* stride.

    ``target_T_source`` maps points of the source frame into the target frame:
    ``camera_target_T_camera_source``. ``information`` (6×6, rotation first) is in the source
    camera's local coordinates: ``target_T_source · Exp(ξ)``, ``ξ = [ω, v]``. A front end that
    linearises on the left must convert with the adjoint before building this record.
    ``eigenvalues``/``eigenvectors`` (columns) describe the registration's Hessian in the same
    coordinates (degeneracy report); when absent they are computed from ``information``.
    ``ok=False`` (with ``reason``) marks a registration that failed: it is never turned into
    a zero-motion factor.
    """

    source_index: int
    target_index: int
    target_T_source: np.ndarray
    information: np.ndarray
    fitness: float
    inlier_rmse_m: float
    correspondences: int
    eigenvalues: np.ndarray | None = None
    eigenvectors: np.ndarray | None = None
    ok: bool = True
    reason: str = ""

    def __post_init__(self) -> None:
        if not self.ok:
            return
        object.__setattr__(
            self, "target_T_source", _rigid("IcpMeasurement.target_T_source", self.target_T_source)
        )
        info = np.asarray(self.information, float)
        if info.shape != (6, 6):
            raise EstimationError(f"IcpMeasurement.information: must be 6×6, got {info.shape}")
        object.__setattr__(self, "information", info)


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

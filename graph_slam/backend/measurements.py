"""Measurement records the back end consumes (frozen dataclasses, checked on construction).

``KinematicMeasurement`` comes from the stride stage (:mod:`graph_slam.strides.measurements`),
which builds it from the encoders; it is re-exported here.

:class:`IcpMeasurement` is what the back end needs from a registration; the front end's
``RegistrationResult`` converts into it with a one-line adapter (``graph_slam.frontend``).
The back end never imports open3d.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from graph_slam.errors import EstimationError
from graph_slam.strides.measurements import KinematicMeasurement, rigid_pose

__all__ = ["IcpMeasurement", "KinematicMeasurement"]


@dataclass(frozen=True, eq=False)
class IcpMeasurement:
    """One registration between two frames of the *same* stride.

    ``target_T_source`` maps points of the source frame into the target frame:
    ``camera_target_T_camera_source``. ``information`` (6×6, rotation first) is in the source
    camera's local coordinates: ``target_T_source · Exp(ξ)``, ``ξ = [ω, v]``. A front end that
    linearises on the left must convert with the adjoint before building this record.
    ``eigenvalues``/``eigenvectors`` (columns) describe the registration's Hessian in the same
    coordinates (degeneracy report); when absent they are computed from ``information``.
    ``dof``: the number of directions the front end found constrained (its degeneracy test,
    :class:`graph_slam.frontend.registration.DegeneracyReport`); when given, ``information``
    is already zero along the others and the gate trusts that count instead of an
    eigen-decomposition of ``information`` (whose rotation and translation units do not
    compare). ``ok=False`` (with ``reason``) marks a registration that failed: it is never
    turned into a zero-motion factor.
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
    dof: int | None = None

    def __post_init__(self) -> None:
        if not self.ok:
            return
        object.__setattr__(
            self,
            "target_T_source",
            rigid_pose("IcpMeasurement.target_T_source", self.target_T_source),
        )
        info = np.asarray(self.information, float)
        if info.shape != (6, 6):
            raise EstimationError(f"IcpMeasurement.information: must be 6×6, got {info.shape}")
        object.__setattr__(self, "information", info)

"""Is the registration's information honest? Normalised errors (χ²) against the truth.

For consecutive frame pairs of a dataset with ground truth (a simulated session, or the TUM
sample), every registration that returns is compared with the true relative pose:
``ξ = Log(estimate⁻¹ · truth)`` in GTSAM's tangent (rotation first, right perturbation, the
information's coordinates) and ``χ² = ξᵀ I ξ``. ``I`` is zero along the directions the
degeneracy test found free, so the χ² has ``dof`` (the constrained directions) degrees of
freedom. An honest information gives ``median(χ²/dof)`` near 1 (the χ²_6 median is 5.3);
the target is 0.5–2. :func:`calibration_scale` is the factor that would put the
median at 1. Documented in docs/frontend.md ("Calibrated information").
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from graph_slam.errors import RegistrationError


@dataclass(frozen=True)
class Chi2Report:
    """χ² of one configuration's registrations on one dataset."""

    name: str
    chi2: np.ndarray  # per returned registration
    dof: np.ndarray
    failed: int

    @property
    def ratio(self) -> np.ndarray:
        """χ² / dof per registration that held at least one direction."""
        held = self.dof > 0
        return self.chi2[held] / self.dof[held]

    @property
    def median_ratio(self) -> float:
        return float(np.median(self.ratio)) if self.ratio.size else float("nan")

    def line(self) -> str:
        r = self.ratio
        if not r.size:
            return f"  {self.name}: no registration returned ({self.failed} failed)"
        return (
            f"  {self.name}: {r.size} pairs (dof median {np.median(self.dof):.0f}, "
            f"{self.failed} failed): χ²/dof median {np.median(r):.2f}, p90 "
            f"{np.percentile(r, 90):.2f}; χ² median {np.median(self.chi2):.1f}"
        )


def relative_error(estimate: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """``Log(estimate⁻¹ · truth)``, rotation first (GTSAM ``Pose3.Logmap``)."""
    from scipy.spatial.transform import Rotation

    delta = np.linalg.solve(estimate, truth)
    rotvec = Rotation.from_matrix(delta[:3, :3]).as_rotvec()
    # Pose3.Logmap's translation part: V(ω)⁻¹ t (first order in ω: t − ω×t/2)
    t = delta[:3, 3]
    return np.concatenate([rotvec, t - 0.5 * np.cross(rotvec, t)])


def chi2_of_pairs(data, config, cloud_config=None, name: str | None = None) -> Chi2Report:
    """χ² of every consecutive pair of ``data`` (a
    :class:`graph_slam.bench.registration_data.Dataset`) registered with the method
    ``config`` names (:func:`graph_slam.frontend.make_registration`) from the identity, each
    frame prepared on its own grid."""
    from graph_slam.frontend import make_registration

    method = make_registration(config, data.intrinsics, cloud_config)
    chi2, dof, failed, target = [], [], 0, None
    for k, frame in enumerate(data.frames):
        source = method.prepare(frame)
        if target is not None:
            truth = np.linalg.solve(data.world_T_camera[k - 1], data.world_T_camera[k])
            try:
                result = method.register(source, target)
            except RegistrationError:
                failed += 1
            else:
                xi = relative_error(result.target_T_source, truth)
                chi2.append(float(xi @ result.information @ xi))
                dof.append(result.degeneracy.dof)
        target = source
    return Chi2Report(name or data.name, np.array(chi2), np.array(dof, dtype=int), failed)


def calibration_scale(reports: list[Chi2Report]) -> float:
    """The factor on the information that puts the pooled median of χ²/dof at 1."""
    ratios = np.concatenate([r.ratio for r in reports])
    return float(1.0 / np.median(ratios)) if ratios.size else float("nan")

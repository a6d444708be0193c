"""The ICP objective's shared machinery: its weighted rows, their analysis and information.

Every registration path (Open3D's colored ICP in :mod:`graph_slam.frontend.registration`, the
projective preset in :mod:`graph_slam.frontend.projective`, small_gicp's GICP in
:mod:`graph_slam.frontend.gicp`) ends with the same three steps on the rows of the
objective it minimised (:class:`Rows`: point-to-plane and photometric residuals, their
Jacobians for a left perturbation about the target origin, the robust kernel's weights):

* :func:`analyse`: the Gauss-Newton system in a unit-free parameterisation, its
  eigen-analysis and the degeneracy report (:mod:`graph_slam.frontend.degeneracy`), and the
  step restricted to the constrained directions (:func:`restricted_step`);
* :func:`rows_information`: ``scale · JᵀWJ / σ²`` in GTSAM's tangent space, kept on the
  constrained directions, plus the optional covariance floor;
* :func:`exp_left`: applying a step.

The sums are compiled (:func:`graph_slam.frontend.kernels.normal_equations`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from graph_slam.frontend import kernels
from graph_slam.frontend.degeneracy import (
    DegeneracyReport,
    floor_information,
    project_information,
    significant_stiffness,
    unit_coordinates,
)
from kinematics.conversions import adjoint_rot_first, skew

if TYPE_CHECKING:
    from graph_slam.frontend.cloud import Cloud


def kernel_weights(residuals: np.ndarray, kernel: str, k: float) -> np.ndarray:
    """IRLS weights of Open3D's robust kernels (``RobustKernel::Weight``)."""
    a = np.abs(residuals)
    if kernel == "none":
        return np.ones_like(a)
    if kernel == "huber":
        return np.where(a <= k, 1.0, k / np.maximum(a, 1e-300))
    if kernel == "tukey":
        return np.where(a <= k, (1.0 - (a / k) ** 2) ** 2, 0.0)
    if kernel == "cauchy":
        return 1.0 / (1.0 + (a / k) ** 2)
    raise ValueError(f"unknown kernel {kernel!r}")


@dataclass(frozen=True, eq=False)
class Rows:
    """Weighted residuals of an ICP objective at a pose, for fixed correspondences.

    ``jac`` is the Jacobian for a left perturbation about the target origin, ``(ω, t)``;
    the first ``n_geo`` rows are point-to-plane, the rest photometric; ``geo_scale`` is the
    factor each point-to-plane residual (metres) was multiplied by.
    """

    r: np.ndarray
    jac: np.ndarray
    w: np.ndarray
    q: np.ndarray
    geo_scale: np.ndarray
    n_geo: int
    pho_scale: float = 0.0


def cloud_rows(
    source: Cloud,
    target: Cloud,
    corr: np.ndarray,
    target_T_source: np.ndarray,
    *,
    geo_scale: np.ndarray | float,
    pho_scale: float,
    kernel: str,
    k: float,
    gradients: np.ndarray | None,
) -> Rows:
    """Point-to-plane rows (``geo_scale · n·(q - p)``) and, when ``gradients`` (intensity
    gradients of the target points) are given, Open3D colored ICP's photometric rows
    (``pho_scale · (I_s - C_p(proj q))``), with the robust kernel's weights."""
    rot, trans = target_T_source[:3, :3], target_T_source[:3, 3]
    q = source.points_m[corr[:, 0]] @ rot.T + trans
    p = target.points_m[corr[:, 1]]
    n = target.normals[corr[:, 1]]
    geo_scale = np.broadcast_to(np.asarray(geo_scale, dtype=float), (len(q),))
    r = geo_scale * np.einsum("ij,ij->i", q - p, n)
    jac = geo_scale[:, None] * np.hstack([np.cross(q, n), n])
    if gradients is not None:
        d = gradients[corr[:, 1]]
        q_proj = q - np.einsum("ij,ij->i", q - p, n)[:, None] * n
        i_source = source.colors[corr[:, 0]].mean(axis=1)
        i_target = target.colors[corr[:, 1]].mean(axis=1)
        r_pho = pho_scale * (i_source - (np.einsum("ij,ij->i", d, q_proj - p) + i_target))
        d_m = -(d - np.einsum("ij,ij->i", d, n)[:, None] * n)  # -(I - n nᵀ) d
        j_pho = pho_scale * np.hstack([np.cross(q, d_m), d_m])
        r, jac = np.concatenate([r, r_pho]), np.vstack([jac, j_pho])
    return Rows(r, jac, kernel_weights(r, kernel, k), q, geo_scale, len(q), float(pho_scale))


@dataclass(frozen=True, eq=False)
class Analysis:
    degeneracy: DegeneracyReport
    step_origin: np.ndarray  # Gauss-Newton step (ω, t) about the target origin
    step_m: float
    step_rad: float


def analyse(
    rows: Rows, config, significance: bool = True, system: UnitSystem | None = None
) -> Analysis:
    """Eigen-analysis of the unit-free Hessian, the significant stiffness of each direction
    (see :class:`DegeneracyReport`; ``config``: any config with ``degeneracy_threshold``,
    ``degeneracy_min_alignment``, ``degeneracy_min_share`` and ``degeneracy_min_gradient``)
    and the Gauss-Newton step restricted to the directions whose eigenvalue reaches the
    threshold (the optimiser's behaviour before the significance test). ``significance:
    False`` skips the significance test (the step does not use it: the optimisers' inner
    iterations; the solution's report is made with it). ``system``: :func:`unit_system` of
    these ``rows`` when the caller has it (its last iteration's), else computed."""
    system = unit_system(rows) if system is None else system
    center, length, to_unit, norm, values, vectors, grad_n = system
    significant = share = None
    if significance:
        significant, share = significant_stiffness(
            rows, to_unit @ vectors, vectors, center, length, norm, config
        )
    report = DegeneracyReport(
        values, vectors, center, length, config.degeneracy_threshold, significant, share,
        config.degeneracy_min_share,
    )  # fmt: skip
    step_n = restricted_step(values, vectors, grad_n, config.degeneracy_threshold)
    return Analysis(
        degeneracy=report,
        step_origin=to_unit @ step_n,
        step_m=float(np.linalg.norm(step_n[3:])),
        step_rad=float(np.linalg.norm(step_n[:3]) / length),
    )


class UnitSystem(NamedTuple):
    """The Gauss-Newton system of some rows in unit-free coordinates (:func:`unit_system`)."""

    center: np.ndarray
    length: float
    to_unit: np.ndarray
    norm: float
    values: np.ndarray
    vectors: np.ndarray
    grad_n: np.ndarray

    def step(self, threshold: float) -> np.ndarray:
        """:func:`analyse`'s ``step_origin`` alone (the optimisers' inner iterations): the
        Gauss-Newton step (ω, t) about the target origin restricted to the directions whose
        eigenvalue reaches ``threshold``; the same arithmetic, without the report."""
        return self.to_unit @ restricted_step(self.values, self.vectors, self.grad_n, threshold)


def unit_system(rows: Rows) -> UnitSystem:
    """The Gauss-Newton system of ``rows`` in unit-free coordinates: the centre and length of
    the matched points, ``U`` (:func:`unit_coordinates`), the geometric weight ``norm``, the
    eigen-decomposition of ``Uᵀ H U / norm`` and ``Uᵀ g / norm``."""
    center = rows.q.mean(axis=0)
    length = max(float(np.sqrt(np.mean(np.sum((rows.q - center) ** 2, axis=1)))), 1e-6)
    to_unit = unit_coordinates(center, length)
    norm = max(float(np.sum(rows.w[: rows.n_geo] * rows.geo_scale**2)), 1e-300)
    hess, grad = kernels.normal_equations(rows.jac, rows.r, rows.w)
    values, vectors = np.linalg.eigh(to_unit.T @ hess @ to_unit / norm)
    grad_n = to_unit.T @ grad / norm
    return UnitSystem(center, length, to_unit, norm, values, vectors, grad_n)


def restricted_step(
    values: np.ndarray, vectors: np.ndarray, grad_n: np.ndarray, threshold: float
) -> np.ndarray:
    """The Gauss-Newton step in unit coordinates restricted to the eigen-directions whose
    eigenvalue reaches ``threshold`` (the step before the significance test)."""
    strong = values >= threshold
    return -vectors[:, strong] @ ((vectors[:, strong].T @ grad_n) / values[strong])


def rows_information(
    rows: Rows,
    target_T_source: np.ndarray,
    min_sigma_m: float,
    degeneracy: DegeneracyReport | None = None,
    scale: float = 1.0,
    *,
    floor_m: float = 0.0,
    floor_rad: float = 0.0,
) -> tuple[np.ndarray, float]:
    """``scale · JᵀWJ / σ²`` in GTSAM's tangent space (right perturbation, source frame) and σ,
    the weighted rms residual, floored at ``min_sigma_m`` (in the geometric residual's scale).
    With a ``degeneracy`` report, only its constrained directions keep information (``Mᵀ I M``,
    :meth:`DegeneracyReport.projector`): the weak ones get exactly zero. ``floor_m`` /
    ``floor_rad`` add a fixed covariance floor (σ per translation / rotation axis) in the
    constrained subspace (:func:`floor_information`); 0 (the default) adds none."""
    sigma2 = float(np.sum(rows.w * rows.r**2) / max(float(rows.w.sum()), 1e-300))
    sigma = max(np.sqrt(sigma2), min_sigma_m * _median(rows.geo_scale))
    info_left = (rows.jac * rows.w[:, None]).T @ rows.jac / sigma**2
    ad = adjoint_rot_first(target_T_source)
    info = scale * (ad.T @ info_left @ ad)
    if degeneracy is not None:
        info = project_information(info, degeneracy, target_T_source)
    info = floor_information(info, floor_m, floor_rad, degeneracy, target_T_source)
    return info, float(sigma)


def _median(values: np.ndarray) -> float:
    """``np.median(values)``; a constant array's (one ``geo_scale`` for every row, as the
    projective rows have) without the partial sort: the median of equal numbers is that
    number (the mean of two equal doubles is exact)."""
    if values.size and values[0] == values.min() == values.max():
        return float(values[0])
    return float(np.median(values))


def exp_left(xi: np.ndarray) -> np.ndarray:
    """The update ``[Exp(ω) | t]`` of a step ``(ω, t)`` about the target origin (Rodrigues'
    formula: scipy's ``Rotation`` took 0.2 ms per call, a tenth of a real-time registration)."""
    delta = np.eye(4)
    w = np.asarray(xi[:3], dtype=float)
    theta = float(np.sqrt(w @ w))
    k = skew(w)
    if theta < 1e-8:  # second order: the remainder is below 1e-24
        delta[:3, :3] += k + 0.5 * (k @ k)
    else:
        delta[:3, :3] += (np.sin(theta) / theta) * k + ((1.0 - np.cos(theta)) / theta**2) * (k @ k)
    delta[:3, 3] = xi[3:]
    return delta

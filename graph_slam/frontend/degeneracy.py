"""The registration's constraint analysis: which directions of the motion the scene holds.

:class:`DegeneracyReport` (the unit-free Hessian's eigen-structure and, per eigen-direction,
the stiffness and weight share of the rows that hold it significantly),
:func:`project_information` (the information kept on the constrained directions only) and
the significance test itself. :func:`graph_slam.frontend.objective.analyse` builds the
report from an objective's rows; docs/frontend.md ("Degeneracy report") explains the test and
its measured margins.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from graph_slam.frontend.kernels import significance
from kinematics.conversions import adjoint_rot_first, skew


@dataclass(frozen=True, eq=False)
class DegeneracyReport:
    """What constrains the registration: the ICP Hessian JᵀWJ at the solution, made unit-free,
    and per eigen-direction the share of it that *significant* constraints carry.

    The Hessian is taken for a motion of the source about ``center_m`` (the centroid of the
    matched source points, target frame) in the coordinates ``(L·ω, t)``, ``L = length_m`` the
    rms distance of those points from the centre, and divided by the summed weights of the
    geometric residuals. A pure translation ``t`` (unit) then has stiffness ``mean (n·t)²`` —
    the share of the correspondences whose normals hold it — and a rotation about the centre
    the same share at the cloud's scale.

    An eigenvalue alone can be fooled: the noise of the normals of a plane gives its three free
    directions a stiffness of ``mean sin²θ`` (0.001–0.02 measured at quarter resolution).
    ``significant`` (per eigen-direction ``v``) therefore counts a point-to-plane row only
    where its normal is aligned with the point's displacement ``δ = ω × (q − c)/L + t`` under
    ``v`` (``|n·δ| ≥ degeneracy_min_alignment · |δ|``: within 60° at 0.5; the lever does not
    count), and a photometric row only where the texture's gradient along ``δ`` is at least
    ``degeneracy_min_gradient`` per metre of it. A direction is *constrained* when that significant stiffness is at least ``threshold`` and
    the significant rows carry at least ``degeneracy_min_share`` of the correspondences' weight (far
    points of a floor, 3 m away at 2.7 cm depth noise, have near-random normals and long
    levers: about 1 % of the rows, which alone gave a floor's yaw a stiffness of 0.01). A
    flat floor gives three free directions (two translations along it, the rotation about
    its normal), a textured floor none.
    """

    eigenvalues: np.ndarray  # (6,) ascending
    eigenvectors: np.ndarray  # 6×6, column i for eigenvalues[i]; coordinates (L·ω, t)
    center_m: np.ndarray
    length_m: float
    threshold: float
    significant: np.ndarray | None = None  # (6,) significant stiffness per eigen-direction
    share: np.ndarray | None = None  # (6,) weight share of the significant rows
    min_share: float = 0.0

    @property
    def weak(self) -> np.ndarray:
        """Mask of the under-constrained eigen-directions."""
        weak = self.eigenvalues < self.threshold
        if self.significant is not None:
            weak |= self.significant < self.threshold
        if self.share is not None:
            weak |= self.share < self.min_share
        return weak

    @property
    def dof(self) -> int:
        """The number of constrained directions (6: every direction; 0: none)."""
        return int(6 - self.weak.sum())

    @property
    def is_degenerate(self) -> bool:
        return bool(self.weak.any())

    @property
    def weak_directions(self) -> np.ndarray:
        """k×6 unit vectors (rows) spanning the under-constrained subspace, ``(L·ω, t)``."""
        return self.eigenvectors[:, self.weak].T

    @property
    def hessian(self) -> np.ndarray:
        """The normalised 6×6 Hessian (rotation first)."""
        return (self.eigenvectors * self.eigenvalues) @ self.eigenvectors.T

    def to_origin(self) -> np.ndarray:
        """``U``: a left twist about the target origin ``(ω, t)`` = ``U · (L·ω, t about c)``."""
        return unit_coordinates(self.center_m, self.length_m)

    def projector(self, target_T_source: np.ndarray) -> np.ndarray:
        """``M``, 6×6: a right twist (source frame, GTSAM's ``BetweenFactor`` tangent) → its
        component along the constrained directions (oblique projection along the weak ones).
        ``Mᵀ I M`` keeps an information ``I`` on the constrained subspace and gives the weak
        directions exactly zero."""
        strong = self.eigenvectors[:, ~self.weak]
        unit = self.to_origin()
        left = unit @ (strong @ strong.T) @ np.linalg.inv(unit)
        ad = adjoint_rot_first(target_T_source)
        return np.linalg.inv(ad) @ left @ ad

    def stiffness(
        self, *, translation: np.ndarray | None = None, rotation_axis: np.ndarray | None = None
    ) -> float:
        """Normalised curvature of the objective along a unit translation or rotation (about
        the centre), in the report's unit-free scale (compare with ``threshold``)."""
        direction = np.zeros(6)
        if translation is not None:
            direction[3:] = translation
        if rotation_axis is not None:
            direction[:3] = rotation_axis
        direction /= np.linalg.norm(direction)
        return float(direction @ self.hessian @ direction)

    def describe(self) -> list[str]:
        """One line per weak direction: a translation axis or a rotation axis (target frame)."""
        lines = []
        for value, vec in zip(self.eigenvalues[self.weak], self.weak_directions, strict=True):
            rot, trans = vec[:3], vec[3:]
            if np.linalg.norm(trans) >= np.linalg.norm(rot):
                axis, kind = trans / np.linalg.norm(trans), "translation along"
            else:
                axis, kind = rot / np.linalg.norm(rot), "rotation about"
            lines.append(f"{kind} ({axis[0]:+.2f}, {axis[1]:+.2f}, {axis[2]:+.2f}): {value:.2g}")
        return lines


def unit_coordinates(center_m: np.ndarray, length_m: float) -> np.ndarray:
    """``U`` with origin twist ``(ω, t) = U · (L·ω, t about the centre)``."""
    unit = np.eye(6)
    unit[3:, :3] = skew(center_m)
    unit[:, :3] /= length_m
    return unit


def significant_stiffness(
    rows, along_map: np.ndarray, vectors, center, length: float, norm: float, config
) -> tuple[np.ndarray, np.ndarray]:
    """Per eigen-direction ``v`` of an objective's ``rows`` (:class:`graph_slam.frontend.
    objective.Rows`; ``along_map``: ``U·vectors``, a row's stiffness along ``v`` in
    ``(L·ω, t)`` is its Jacobian times a column), the normalised stiffness of the rows that
    hold it significantly: point-to-plane rows whose normal is aligned with the point's
    displacement ``δ`` under ``v`` (``|n·δ| ≥ degeneracy_min_alignment · |δ|``), photometric
    rows whose intensity gradient along ``δ`` is at least ``degeneracy_min_gradient`` per metre
    of it; and the share of the geometric rows' weight those rows carry (a photometric row
    counts as much as a geometric one). One compiled pass
    (:func:`graph_slam.frontend.kernels.significance`)."""
    n_geo = rows.n_geo
    geo_scale = np.ascontiguousarray(np.broadcast_to(rows.geo_scale, (n_geo,)), dtype=float)
    total, count = significance(
        rows.jac, rows.w, rows.q, n_geo, geo_scale, float(rows.pho_scale), along_map,
        np.asarray(center, float), float(length), vectors, config.degeneracy_min_alignment,
        config.degeneracy_min_gradient,
    )  # fmt: skip
    return total / norm, count / max(float(rows.w[:n_geo].sum()), 1e-300)


def project_information(
    information: np.ndarray, degeneracy: DegeneracyReport, target_T_source: np.ndarray
) -> np.ndarray:
    """The information (right tangent, rotation first) kept on the report's constrained
    directions only (``Mᵀ I M``, symmetrised); unchanged when every direction is held."""
    if not degeneracy.is_degenerate:
        return information
    m = degeneracy.projector(target_T_source)
    info = m.T @ information @ m
    return 0.5 * (info + info.T)


def floor_information(
    information: np.ndarray,
    floor_m: float,
    floor_rad: float,
    degeneracy: DegeneracyReport | None = None,
    target_T_source: np.ndarray | None = None,
) -> np.ndarray:
    """The information of a covariance that adds a fixed floor to the solver's: ``I' =
    (I⁻¹ + Σ_f)⁻¹``, ``Σ_f = diag(floor_rad², ×3, floor_m², ×3)`` (right tangent, rotation
    first), taken in the constrained subspace only.

    With a degeneracy report the (projected) ``I = Pᵀ A P`` lives on the ``d`` constrained
    directions: ``P = B⁺ M`` (``M`` the report's oblique projector, ``B`` an orthonormal basis
    of its range) maps a twist to its constrained coordinates and ``A = B I Bᵀ`` is their
    information; the floor is carried through the same map, ``I' = Pᵀ (A⁻¹ + P Σ_f Pᵀ)⁻¹ P``.
    The weak directions keep exactly zero information, and ``dof`` is unchanged. A zero floor
    returns ``information`` as it is."""
    if floor_m <= 0.0 and floor_rad <= 0.0:
        return information
    floor = np.diag([floor_rad**2] * 3 + [floor_m**2] * 3)
    if degeneracy is None or not degeneracy.is_degenerate:
        basis = p = np.eye(6)
    else:
        if target_T_source is None:
            raise ValueError("floor_information: a degeneracy report needs target_T_source")
        if degeneracy.dof == 0:
            return np.zeros_like(information)
        m = degeneracy.projector(target_T_source)
        basis = np.linalg.svd(m)[0][:, : degeneracy.dof]  # orthonormal basis B of range(M)
        p = basis.T @ m  # M B = B, so Bᵀ I B = A
    a = basis.T @ information @ basis
    # (A⁻¹ + S)⁻¹ = (1 + A S)⁻¹ A: no inverse of A (it may be ill-conditioned)
    floored = np.linalg.solve(np.eye(len(a)) + a @ (p @ floor @ p.T), a)
    floored = p.T @ floored @ p
    return 0.5 * (floored + floored.T)

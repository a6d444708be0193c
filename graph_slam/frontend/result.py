"""What every registration method returns, and the checks they share.

:class:`RegistrationResult` (a registration that converged with enough overlap, with its
information and degeneracy report) is the one result of the three methods
(:mod:`graph_slam.frontend.registration`, Open3D; :mod:`graph_slam.frontend.gicp`, small_gicp;
:mod:`graph_slam.frontend.projective`); a registration that cannot be trusted raises
:class:`~graph_slam.errors.RegistrationError` (:func:`registration_failure`). The gates they
share: :func:`start_pose` (the initial pose and the frames' sizes), :func:`gate_correspondences`,
:func:`fail_if_degenerate` and :func:`conclude` (the checks at a Gauss-Newton solution).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import StrEnum

import numpy as np

from graph_slam.errors import RegistrationError, RegistrationFailure
from graph_slam.frontend.degeneracy import DegeneracyReport
from graph_slam.session.checks import check_pose


class RegistrationStatus(StrEnum):
    """A returned result is either well constrained or degenerate (failures raise)."""

    OK = "ok"
    DEGENERATE = "degenerate"


@dataclass(frozen=True, eq=False)
class RegistrationResult:
    """A registration that converged with enough overlap.

    ``information`` is 6×6, rotation first then translation (GTSAM ``Pose3`` order), in the
    tangent space GTSAM uses for ``BetweenFactor<Pose3>(target, source, target_T_source)``:
    ``target_T_source_true = target_T_source · Exp(ξ)``, ``ξ = (ω, t)`` in the source frame.
    It is ``(Σ_solver + Σ_floor)⁻¹`` with ``Σ_solver = (scale · JᵀWJ / σ²)⁻¹`` (σ the weighted
    rms residual, floored) and a fixed floor in the constrained directions (the accurate path's
    ``information_floor_m`` / ``information_floor_rad``; see docs/frontend.md, "Calibrated
    information").
    """

    target_T_source: np.ndarray
    fitness: float
    inlier_rmse_m: float
    correspondences: int
    information: np.ndarray
    degeneracy: DegeneracyReport
    residual_sigma: float
    final_step_m: float
    final_step_rad: float
    timing_s: dict[str, float] = field(default_factory=dict)

    @property
    def status(self) -> RegistrationStatus:
        return (
            RegistrationStatus.DEGENERATE
            if self.degeneracy.is_degenerate
            else RegistrationStatus.OK
        )

    @property
    def is_reliable(self) -> bool:
        """True when every direction of the motion is constrained (status OK)."""
        return self.status is RegistrationStatus.OK


def gate_correspondences(config, fitness: float, count: int) -> None:
    """Too few correspondences or too low a fitness for ``config`` (any config with
    ``min_correspondences`` and ``min_fitness``): a :class:`RegistrationError`."""
    if count < config.min_correspondences:
        raise RegistrationError(
            RegistrationFailure.TOO_FEW_CORRESPONDENCES,
            f"{count} correspondences (min_correspondences {config.min_correspondences})",
            fitness=fitness,
            correspondences=count,
        )
    if fitness < config.min_fitness:
        raise RegistrationError(
            RegistrationFailure.LOW_FITNESS,
            f"fitness {fitness:.3f} (min_fitness {config.min_fitness})",
            fitness=fitness,
            correspondences=count,
        )


def registration_failure(
    reason: RegistrationFailure, message: str, fitness=None, count=None
) -> RegistrationError:
    """The error of a registration that failed, with what is known of its fitness and
    correspondences (the real-time front ends raise it)."""
    return RegistrationError(reason, message, fitness=fitness, correspondences=count)


def start_pose(where: str, source, target, config, initial: np.ndarray | None) -> np.ndarray:
    """The checked initial ``target_T_source`` (identity when None) of a registration of
    prepared frames; ``EMPTY_SOURCE`` / ``EMPTY_TARGET`` below ``config.min_points``."""
    init = np.eye(4) if initial is None else np.asarray(initial, dtype=float)
    check_pose(where, "initial_target_T_source", init)
    for name, frame, reason in (
        ("source", source, RegistrationFailure.EMPTY_SOURCE),
        ("target", target, RegistrationFailure.EMPTY_TARGET),
    ):
        if len(frame) < config.min_points:
            raise registration_failure(
                reason, f"{name} has {len(frame)} points (min_points {config.min_points})"
            )
    return init


def fail_if_degenerate(config, degeneracy, fitness: float, count: int) -> None:
    """``DEGENERATE`` when ``config.fail_on_degenerate`` and the report has a free direction."""
    if config.fail_on_degenerate and degeneracy.is_degenerate:
        raise registration_failure(
            RegistrationFailure.DEGENERATE,
            "under-constrained: " + "; ".join(degeneracy.describe()),
            fitness,
            count,
        )


def conclude(
    target_T_source: np.ndarray,
    analysis,
    information: np.ndarray,
    sigma: float,
    fitness: float,
    count: int,
    inlier_rmse_m: float,
    config,
    timing_s: dict[str, float] | None = None,
) -> RegistrationResult:
    """The checks at a Gauss-Newton solution (still moving: ``NOT_CONVERGED`` when
    ``config.check_convergence``; under-constrained: ``DEGENERATE`` when
    ``config.fail_on_degenerate``) and its :class:`RegistrationResult`, for the front ends that
    end in a Gauss-Newton solution (the accurate path, ``realtime``, ``realtime-gicp``'s
    photometric stage)."""
    if config.check_convergence and (
        analysis.step_m > config.max_final_step_m or analysis.step_rad > config.max_final_step_rad
    ):
        raise registration_failure(
            RegistrationFailure.NOT_CONVERGED,
            f"a Gauss-Newton step at the solution still moves {analysis.step_m * 1e3:.2f} mm, "
            f"{np.degrees(analysis.step_rad):.3f} deg (max_final_step_m "
            f"{config.max_final_step_m}, max_final_step_rad {config.max_final_step_rad})",
            fitness,
            count,
        )
    fail_if_degenerate(config, analysis.degeneracy, fitness, count)
    return RegistrationResult(
        target_T_source=target_T_source,
        fitness=fitness,
        inlier_rmse_m=inlier_rmse_m,
        correspondences=count,
        information=information,
        degeneracy=analysis.degeneracy,
        residual_sigma=sigma,
        final_step_m=analysis.step_m,
        final_step_rad=analysis.step_rad,
        timing_s=timing_s or {},
    )

"""Gate ICP registrations before they become factors, and project away degenerate directions.

Rules, checked in this order (the first that fails is the recorded reason):

1. ``registration_failed`` — the front end said ``ok=False`` (its reason is appended);
2. ``nonfinite`` — NaN/inf in the transform or the information;
3. ``low_fitness`` / ``high_rmse`` / ``few_correspondences`` — against :class:`GateConfig`;
4. ``implausible_step`` — a motion from the target frame larger than ``max_step_m``/``max_step_rad``;
5. degeneracy: when the front end counted the constrained directions (``IcpMeasurement.dof``,
   its well-scaled test, docs/frontend.md), its information is already zero along the others
   and that count is the rank. Otherwise (a record without it) eigen-directions of the
   information with ``λ < max(min_eigenvalue, degenerate_eigenvalue_ratio·λmax)`` get **zero**
   information (``P I P``). If fewer than ``min_rank`` directions are left: ``degenerate``
   (the frame is bridged). Otherwise accepted: ``ok`` (6 DoF: registered) or
   ``partial (k DoF)`` (a factor on the k constrained directions only).

Fitness alone is never trusted (a flat floor slid sideways registers with fitness 1.0).

:class:`RegistrationGate` (built by :func:`make_registration_gate`) applies these rules to the
estimator's frames and turns an accepted registration into its ICP between-factor.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace

import numpy as np

from graph_slam.backend import factors
from graph_slam.backend.config import BackendConfig, GateConfig
from graph_slam.backend.measurements import IcpMeasurement
from graph_slam.backend.noise import sqrt_of_information

log = logging.getLogger(__name__)


@dataclass(frozen=True, eq=False)
class GateDecision:
    """The gate's verdict on one registration."""

    accepted: bool
    reason: str
    rank: int = 0
    dropped_directions: np.ndarray | None = None
    """6×m eigenvectors (rotation first) that got zero information."""
    information: np.ndarray | None = None
    """The (projected, scaled) 6×6 information used for the factor; None if rejected."""
    sqrt_information: np.ndarray | None = None
    """Square R with RᵀR = information (zero rows for dropped directions)."""

    def record(self) -> GateDecision:
        """The decision as a frame's record keeps it: the verdict, rank and dropped
        directions, without the two 6×6 matrices the factor was built from (0.6 KB a frame,
        a fifth of a long run's per-frame memory)."""
        return replace(self, information=None, sqrt_information=None)


def _log_so3_angle(r: np.ndarray) -> float:
    return float(np.arccos(np.clip((np.trace(r) - 1.0) / 2.0, -1.0, 1.0)))


def gate_icp(meas: IcpMeasurement, cfg: GateConfig) -> GateDecision:
    """Apply the rules of the module docstring; return the decision with its reason."""
    if not meas.ok:
        return GateDecision(False, f"registration_failed: {meas.reason or 'no reason given'}")
    info = np.asarray(meas.information, float)
    if not (np.all(np.isfinite(info)) and np.all(np.isfinite(meas.target_T_source))):
        return GateDecision(False, "nonfinite")
    if not np.isfinite(meas.fitness) or meas.fitness < cfg.min_fitness:
        return GateDecision(False, f"low_fitness ({meas.fitness:.3g} < {cfg.min_fitness})")
    if not np.isfinite(meas.inlier_rmse_m) or meas.inlier_rmse_m > cfg.max_inlier_rmse_m:
        return GateDecision(
            False, f"high_rmse ({meas.inlier_rmse_m:.3g} m > {cfg.max_inlier_rmse_m} m)"
        )
    if meas.correspondences < cfg.min_correspondences:
        return GateDecision(
            False,
            f"few_correspondences ({meas.correspondences} < {cfg.min_correspondences})",
        )
    step_m = float(np.linalg.norm(meas.target_T_source[:3, 3]))
    step_rad = _log_so3_angle(meas.target_T_source[:3, :3])
    if step_m > cfg.max_step_m or step_rad > cfg.max_step_rad:
        return GateDecision(False, f"implausible_step ({step_m:.3f} m, {step_rad:.3f} rad)")

    info = 0.5 * (info + info.T)
    if meas.dof is not None:
        return _decide_counted(info, int(meas.dof), cfg)
    if meas.eigenvalues is not None and meas.eigenvectors is not None:
        lam = np.asarray(meas.eigenvalues, float).reshape(6)
        vec = np.asarray(meas.eigenvectors, float).reshape(6, 6)
        if not (np.all(np.isfinite(lam)) and np.all(np.isfinite(vec))):
            return GateDecision(False, "nonfinite")
    else:
        lam, vec = np.linalg.eigh(info)
    threshold = max(cfg.min_eigenvalue, cfg.degenerate_eigenvalue_ratio * float(lam.max()))
    keep = lam >= threshold
    rank = int(keep.sum())
    dropped = vec[:, ~keep]
    if rank < cfg.min_rank:
        return GateDecision(False, f"degenerate (rank {rank} < {cfg.min_rank})", rank, dropped)
    if rank < 6:
        basis, _ = np.linalg.qr(vec[:, keep])
        proj = basis @ basis.T
        info = proj @ info @ proj
    info = cfg.information_scale * 0.5 * (info + info.T)
    return GateDecision(
        True, _accepted_reason(rank), rank, dropped, info, sqrt_of_information(info)
    )


def _accepted_reason(rank: int) -> str:
    return "ok" if rank == 6 else f"partial ({rank} DoF)"


def _decide_counted(info: np.ndarray, rank: int, cfg: GateConfig) -> GateDecision:
    """The front end counted ``rank`` constrained directions and zeroed the others."""
    _, vec = np.linalg.eigh(info)
    dropped = vec[:, : 6 - rank]  # the (near-)zero eigen-directions
    if rank < cfg.min_rank:
        return GateDecision(False, f"degenerate (rank {rank} < {cfg.min_rank})", rank, dropped)
    info = cfg.information_scale * info
    return GateDecision(
        True, _accepted_reason(rank), rank, dropped, info, sqrt_of_information(info)
    )


class RegistrationGate:
    """ICP measurement -> ``BetweenFactorPose3`` or a rejection, within one stride.

    Knows which frames belong to the open stride (``frame index -> k``): a registration whose
    source is not this frame, or whose target is not an earlier frame of the stride, is
    rejected before :func:`gate_icp`'s rules.
    """

    def __init__(self, cfg: GateConfig, camera_T_imu: np.ndarray):
        self.cfg = cfg
        self.camera_T_imu = np.asarray(camera_T_imu, float)
        self.frame_to_k: dict[int, int] = {}

    def start_stride(self) -> None:
        self.frame_to_k = {}

    def add_frame(self, index: int, k: int) -> None:
        """Frame ``index`` is state ``k`` of the open stride (a target for later frames)."""
        self.frame_to_k[index] = k

    def factor(self, icp: IcpMeasurement, index: int, k: int) -> tuple[GateDecision, object]:
        """The decision on ``icp`` for frame ``index`` (state ``k``) and its factor or None."""
        if icp.source_index != index:
            reason = f"source_index {icp.source_index} is not this frame ({index})"
            return GateDecision(False, reason), None
        if icp.target_index not in self.frame_to_k or icp.target_index >= index:
            return GateDecision(False, "target frame not in this stride"), None
        decision = gate_icp(icp, self.cfg)
        if not decision.accepted:
            log.info("frame %d: ICP rejected (%s)", index, decision.reason)
            return decision, None
        f = factors.icp_between_factor(
            self.frame_to_k[icp.target_index],
            k,
            icp.target_T_source,
            decision.sqrt_information,
            self.camera_T_imu,
            self.cfg.robust_kernel,
            self.cfg.robust_k,
        )
        return decision, f


def make_registration_gate(config: BackendConfig, camera_T_imu: np.ndarray) -> RegistrationGate:
    """The registration gate of :class:`~graph_slam.backend.estimator.StrideSLAM`."""
    return RegistrationGate(config.gate, camera_T_imu)

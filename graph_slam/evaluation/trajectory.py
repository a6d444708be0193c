"""Camera-trajectory errors of one stride, computed with evo.

Both trajectories are ``stride_T_camera`` (F×4×4) on the same timestamps. A frame whose estimate
is missing (any NaN: a failed registration nothing bridged) is left out and counted, never taken
as zero motion. Metrics (translation part, metres):

- ``rmse_unaligned_m``: APE RMSE in the stride frame as estimated (both start at foot strike).
- ``rmse_aligned_m``: APE RMSE after evo's SE(3) Umeyama alignment of the estimate onto the
  reference (no scale), as the thesis aligned its trajectories before comparing.
- per gait phase (``stance``/``swing``): the RMSE of the same per-frame errors restricted to
  the phase's frames (alignment is fitted on the whole stride, once).
- ``rpe_rmse_m``: RPE RMSE of the translation between consecutive evaluated frames (optional).
"""

from __future__ import annotations

import copy
import logging
from dataclasses import dataclass, field

import numpy as np

from graph_slam.errors import EvaluationError
from graph_slam.evaluation._evo import require_evo
from graph_slam.strides.reference import gait_cycle_percent, stance_mask  # noqa: F401 (re-export)

log = logging.getLogger(__name__)

PHASES = ("stance", "swing")


@dataclass(frozen=True, eq=False)
class StrideTrajectoryMetrics:
    """Trajectory errors of one stride (metres); NaN where not computable (too few frames)."""

    n_frames: int
    n_evaluated: int
    rmse_unaligned_m: float
    rmse_aligned_m: float
    rmse_by_phase_m: dict[str, dict[str, float]]
    """``{"stance": {"unaligned": .., "aligned": .., "n": ..}, "swing": {...}}``."""
    rpe_rmse_m: float | None
    errors_unaligned_m: np.ndarray = field(repr=False)
    """Per-frame translation error (NaN for frames not evaluated)."""
    errors_aligned_m: np.ndarray = field(repr=False)

    def to_dict(self) -> dict:
        return {
            "n_frames": self.n_frames,
            "n_evaluated": self.n_evaluated,
            "rmse_unaligned_m": self.rmse_unaligned_m,
            "rmse_aligned_m": self.rmse_aligned_m,
            "rmse_by_phase_m": self.rmse_by_phase_m,
            "rpe_rmse_m": self.rpe_rmse_m,
        }


def _rmse(errors: np.ndarray) -> float:
    return float(np.sqrt(np.mean(errors**2))) if errors.size else float("nan")


def _check(name: str, poses: np.ndarray, n: int) -> np.ndarray:
    poses = np.asarray(poses, dtype=np.float64)
    if poses.shape != (n, 4, 4):
        raise EvaluationError(
            f"stride_trajectory_metrics: {name} has shape {poses.shape}, want ({n}, 4, 4)"
        )
    return poses


def stride_trajectory_metrics(
    t_s: np.ndarray,
    estimate_stride_T_camera: np.ndarray,
    reference_stride_T_camera: np.ndarray,
    in_stance: np.ndarray | None = None,
    *,
    rpe: bool = True,
) -> StrideTrajectoryMetrics:
    """APE (unaligned and SE(3)-aligned), per phase, and optionally RPE, via evo.

    Args:
        t_s: F frame times (seconds, increasing).
        estimate_stride_T_camera: F×4×4 estimate; frames with NaN are not evaluated.
        reference_stride_T_camera: F×4×4 ground truth (finite).
        in_stance: F booleans (see :func:`stance_mask`); None: no per-phase split.
    """
    evo = require_evo()
    t = np.asarray(t_s, dtype=np.float64).reshape(-1)
    n = t.size
    est = _check("estimate_stride_T_camera", estimate_stride_T_camera, n)
    ref = _check("reference_stride_T_camera", reference_stride_T_camera, n)
    if not np.isfinite(ref).all():
        raise EvaluationError("stride_trajectory_metrics: the reference has NaN or inf poses")
    if n > 1 and not (np.diff(t) > 0).all():
        raise EvaluationError("stride_trajectory_metrics: t_s must be strictly increasing")
    valid = np.isfinite(est).all(axis=(1, 2))
    errors_unaligned = np.full(n, np.nan)
    errors_aligned = np.full(n, np.nan)
    rpe_rmse = None
    n_valid = int(valid.sum())
    if n_valid >= 1:
        traj_ref = evo.trajectory.PoseTrajectory3D(poses_se3=list(ref[valid]), timestamps=t[valid])
        traj_est = evo.trajectory.PoseTrajectory3D(poses_se3=list(est[valid]), timestamps=t[valid])
        relation = evo.metrics.PoseRelation.translation_part
        ape = evo.metrics.APE(relation)
        ape.process_data((traj_ref, traj_est))
        errors_unaligned[valid] = ape.error
        if n_valid >= 3:
            aligned = copy.deepcopy(traj_est)
            aligned.align(traj_ref, correct_scale=False)
            ape_aligned = evo.metrics.APE(relation)
            ape_aligned.process_data((traj_ref, aligned))
            errors_aligned[valid] = ape_aligned.error
        else:
            log.info("stride_trajectory_metrics: %d frame(s) evaluated, too few to align", n_valid)
        if rpe and n_valid >= 2:
            metric = evo.metrics.RPE(relation, delta=1, delta_unit=evo.metrics.Unit.frames)
            metric.process_data((traj_ref, traj_est))
            rpe_rmse = float(metric.get_statistic(evo.metrics.StatisticsType.rmse))
    by_phase: dict[str, dict[str, float]] = {}
    if in_stance is not None:
        stance = np.asarray(in_stance, dtype=bool).reshape(-1)
        if stance.size != n:
            raise EvaluationError(
                f"stride_trajectory_metrics: in_stance has {stance.size} values for {n} frames"
            )
        for phase, mask in zip(PHASES, (stance, ~stance), strict=True):
            m = mask & valid
            by_phase[phase] = {
                "unaligned": _rmse(errors_unaligned[m]),
                "aligned": _rmse(errors_aligned[m]) if n_valid >= 3 else float("nan"),
                "n": int(m.sum()),
            }
    return StrideTrajectoryMetrics(
        n_frames=n,
        n_evaluated=n_valid,
        rmse_unaligned_m=_rmse(errors_unaligned[valid]),
        rmse_aligned_m=_rmse(errors_aligned[valid]) if n_valid >= 3 else float("nan"),
        rmse_by_phase_m=by_phase,
        rpe_rmse_m=rpe_rmse,
        errors_unaligned_m=errors_unaligned,
        errors_aligned_m=errors_aligned,
    )

"""Gait events (foot strike, toe-off) from a load cell or from a thigh IMU, and gait phase.

Load cell (:func:`detect_from_load_cell`): a hysteresis comparator on the axial load; foot
strike when the load rises through the upper threshold, toe-off when it falls through the
lower one; contacts or swings shorter than a minimum are chatter and are dropped (counted).

Thigh IMU in an unknown mounting orientation (:func:`detect_from_thigh_imu`):

1. resample to a uniform grid, low-pass the gyro (zero-phase Butterworth, 8 Hz);
2. the sagittal axis is the principal axis of the angular velocity (walking is mostly
   flexion/extension of the thigh); its sign is chosen so that the signal matches the
   reference thigh angular velocity (flexion +) better than its negative does;
3. swing peaks (the large flexion-velocity peak of mid-swing) mark each stride; their
   spacing gives the local stride time T and, through the adult stride-time/speed relation,
   the walking speed whose reference thigh-velocity curve (:mod:`kinematics.gait_curves`) is
   the template;
4. each foot strike is located by aligning the template with the measured signal over the
   phases -0.30 .. +0.25 around it (terminal-swing deceleration, loading plateau, onset of
   stance extension) by normalised cross-correlation (insensitive to gain and bias); toe-off
   likewise over the phases around the template's toe-off. Alignments with a correlation below
   ``min_correlation`` are rejected (not walking: standing, shuffling, gait initiation);
5. foot strikes closer than the plausible minimum stride time are merged, with a warning,
   and counted.

When the accelerometer shows heel-strike shocks (:mod:`kinematics.gait_impact`), the axis
sign is the one whose strikes carry the shocks (a toe-off has none), and each strike is moved
to its shock's onset minus the impact lag (the template's shape bias is then gone).

Gait phase (:func:`gait_phase`): linear in time between consecutive foot strikes of a walking
bout (0 at a strike, 1 at the next); NaN outside walking.

The pieces: :mod:`kinematics.gait_event_config` (configuration, result record),
:mod:`kinematics.gait_io` (IMU and events CSV), :mod:`kinematics.gait_templates` (steps 1, 3
and 4), :mod:`kinematics.gait_event_times` (step 5, matching, gait phase),
:mod:`kinematics.gait_load_cell`. This module is their public entry point: each name in
``__all__`` imports from here.
"""

from __future__ import annotations

import logging
import math

import numpy as np

from kinematics.errors import GaitDetectionError
from kinematics.gait_event_config import EVENT_KINDS, DetectedEvents, GaitEventConfig
from kinematics.gait_event_times import gait_phase, match_events, merge_close_strikes
from kinematics.gait_io import (
    MAX_ACCEL_M_S2,
    MAX_GYRO_RAD_S,
    MAX_RATE_HZ,
    MIN_RATE_HZ,
    read_events_csv,
    read_imu_csv,
    validate_imu,
    write_events_csv,
    write_imu_csv,
)
from kinematics.gait_load_cell import detect_from_load_cell
from kinematics.gait_templates import detect_with_axis, prepare_signal
from kinematics.imu import ImuSeries

__all__ = [
    "EVENT_KINDS",
    "MAX_ACCEL_M_S2",
    "MAX_GYRO_RAD_S",
    "MAX_RATE_HZ",
    "MIN_RATE_HZ",
    "DetectedEvents",
    "GaitEventConfig",
    "detect_from_load_cell",
    "detect_from_thigh_imu",
    "gait_phase",
    "match_events",
    "merge_close_strikes",
    "read_events_csv",
    "read_imu_csv",
    "sagittal_axis",
    "validate_imu",
    "write_events_csv",
    "write_imu_csv",
]

logger = logging.getLogger(__name__)


def _long_axis(imu: ImuSeries) -> np.ndarray:
    """The thigh's long axis in the sensor frame: the mean specific force (gravity, on average
    along the thigh, which swings about the vertical)."""
    a = np.asarray(imu.accel_m_s2, dtype=float).mean(axis=0)
    return a / max(float(np.linalg.norm(a)), 1e-9)


def sagittal_axis(
    gyro_rad_s: np.ndarray, long_axis: np.ndarray | None = None
) -> tuple[np.ndarray, float]:
    """Principal axis of the angular velocity (unsigned) and its share of the variance.

    ``long_axis`` (unit, sensor frame): the rotation about the thigh's long axis (turning,
    internal/external rotation) is removed first, so that turns while walking do not tilt the
    flexion axis; the share is then that of the remaining variance."""
    g = np.asarray(gyro_rad_s, dtype=float)
    if long_axis is not None:
        u = np.asarray(long_axis, dtype=float)
        g = g - np.outer(g @ u, u)
    cov = np.cov((g - np.median(g, axis=0)).T)
    eigval, eigvec = np.linalg.eigh(cov)
    share = float(eigval[-1] / max(eigval.sum(), 1e-30))
    return eigvec[:, -1], share


def detect_from_thigh_imu(imu: ImuSeries, config: GaitEventConfig | None = None) -> DetectedEvents:
    """Foot strikes and toe-offs from a thigh IMU in any mounting orientation.

    See the module docstring for the method. Returns empty event lists (not an error) when no
    walking is found, e.g. when the wearer only stands.
    """
    cfg = config or GaitEventConfig()
    t, gyro, rate = prepare_signal(imu, cfg)
    if t.size < 3:
        raise GaitDetectionError(f"{imu.source}: recording too short ({t.size} samples)")
    axis, share = sagittal_axis(gyro, _long_axis(imu))
    if share < 0.5:
        logger.warning(
            "%s: the principal rotation axis carries only %.0f%% of the angular-velocity "
            "variance; the sagittal axis may be ill-defined",
            imu.source,
            100 * share,
        )
    omega = gyro @ axis
    # The axis sign that makes the signal look like thigh flexion velocity (template score).
    results = []
    for sign in (1.0, -1.0):
        res = detect_with_axis(t, sign * omega, cfg)
        res["sign"] = sign
        results.append(res)
    best = max(results, key=lambda r: (r["score"], len(r["strikes"])))
    if cfg.use_impacts:
        best, refined, sign_flag = _impact_sign_and_strikes(imu, t, omega, results, best)
    else:
        from kinematics.gait_impact import ImpactRefinement

        refined = ImpactRefinement(np.asarray(best["strikes"]), 0, 0.0, 0.0)
        best, sign_flag = {**best, "burst_ratio": math.nan}, False
    strikes, merged = merge_close_strikes(refined.strikes_s, cfg.min_stride_s, imu.source)
    toe_offs = np.asarray(best["toe_offs"])
    if toe_offs.size:
        toe_offs, _ = merge_close_strikes(toe_offs, cfg.min_stride_s * 0.5)
    if best["n_peaks"] == 0:
        logger.info(
            "%s: no swing peaks above %.2f rad/s: no walking found",
            imu.source,
            cfg.min_swing_peak_rad_s,
        )
    return DetectedEvents(
        foot_strikes_s=strikes,
        toe_offs_s=toe_offs,
        method="thigh_imu",
        merged_strikes=merged,
        rejected=int(best["rejected"]),
        sagittal_axis=best["sign"] * axis,
        details={
            "axis_variance_share": share,
            "template_score": best["score"],
            "input_rate_hz": rate,
            "swing_peaks": float(best["n_peaks"]),
            "impact_strikes": float(refined.from_impact),
            "impact_strength": refined.strength,
            "template_bias_s": refined.template_bias_s,
            "burst_ratio": best["burst_ratio"],
            "sign_disagreement": float(sign_flag),
        },
    )


def _impact_sign_and_strikes(imu: ImuSeries, t: np.ndarray, omega: np.ndarray, results, best):
    """The axis sign from the impact transients, and the strikes placed on them
    (:mod:`kinematics.gait_impact`).

    When the accelerometer shows impacts, the sign whose strikes carry the bursts (burst ratio
    above ``min_burst_ratio`` while the other sign's is below one) wins; when it differs from
    the template's choice, a warning says so and ``sign_disagreement`` is set. Without impacts,
    or when the ratios do not decide, the template's choice stands."""
    from kinematics.gait_impact import (
        ImpactConfig,
        burst_ratio,
        envelope,
        refine_strikes,
        typical_peak,
    )

    cfg = ImpactConfig()
    t_in = np.asarray(imu.t_s, dtype=float)
    env = envelope(t_in, imu.accel_m_s2, cfg)
    ratios = [
        burst_ratio(t_in, env, np.asarray(r["strikes"]), np.asarray(r["toe_offs"]), cfg)
        for r in results
    ]
    k_best = next(k for k, r in enumerate(results) if r is best)
    k_chosen, disagree = k_best, False
    strong = max(typical_peak(t_in, env, np.asarray(r["strikes"]), cfg)[1] for r in results)
    for k in range(len(results) if strong >= cfg.min_strength else 0):
        other = ratios[1 - k]
        if ratios[k] >= cfg.min_burst_ratio and (not math.isfinite(other) or other < 1.0):
            k_chosen, disagree = k, k != k_best
    if disagree:
        logger.warning(
            "%s: the flexion sign from the impact transients (strikes where the bursts are: "
            "ratio %.1f against %.1f) disagrees with the template fit; taking the impacts'",
            imu.source,
            max(ratios),
            min(ratios),
        )
    chosen = {**results[k_chosen], "burst_ratio": ratios[k_chosen]}
    refined = refine_strikes(t_in, env, np.asarray(chosen["strikes"]), cfg)
    return chosen, refined, disagree

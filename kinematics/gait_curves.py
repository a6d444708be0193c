"""Gait reference curves: sagittal hip, knee and ankle angles over the cycle vs walking speed.

Smooth, periodic functions of the gait phase (cycles; 0 = foot strike of this leg, 1 = its
next foot strike) for adult walking speeds 0.6-1.8 m/s, plus the stride time, stride length
and stance fraction at a speed. The curves are 8-harmonic Fourier series fitted to the
published mean curves of each speed bin (Schwartz et al. 2008) and interpolated in speed
(shape-preserving PCHIP of the coefficients); the tables and every assumption are in
``models/gait/`` and :mod:`kinematics.gait_tables`.

Sign conventions (radians): hip flexion + (thigh relative to pelvis), knee flexion +, ankle
dorsiflexion +, pelvic tilt anterior +. :func:`thigh_angle` gives the thigh's inclination from
the vertical in the sagittal plane (flexion sense +), i.e. hip flexion minus anterior pelvic
tilt: the quantity a thigh-mounted IMU sees.

Example::

    from kinematics.gait_curves import joint_angles, stride_time_s
    q = joint_angles(np.linspace(0, 1, 101, endpoint=False), speed_m_s=1.3)
    q["knee"].max()  # ~1.04 rad of peak swing flexion
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy.interpolate import PchipInterpolator

from kinematics.errors import GaitCurveError
from kinematics.gait_tables import JSON_NAME

JOINTS: tuple[str, ...] = ("hip", "knee", "ankle")
_SPEED_TOL = 1e-9


@dataclass(frozen=True)
class _Reference:
    speeds_m_s: np.ndarray
    n_harmonics: int
    interpolators: dict[str, PchipInterpolator]  # speed -> coefficient vector (radians)
    walk_ratio: float
    stance_intercept: float
    stance_slope: float


@lru_cache(maxsize=1)
def _reference() -> _Reference:
    from graph_slam_models import model_path

    path = model_path(f"gait/{JSON_NAME}")
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
        speeds = np.asarray(doc["speeds_m_s"], dtype=float)
        n = int(doc["n_harmonics"])
        interps = {}
        for key, rows in doc["fourier_rad"].items():
            coeffs = np.asarray(rows, dtype=float)
            if coeffs.shape != (speeds.size, 2 * n + 1):
                raise ValueError(f"fourier_rad/{key} has shape {coeffs.shape}")
            interps[key] = PchipInterpolator(speeds, coeffs, axis=0, extrapolate=False)
        st = doc["spatiotemporal"]
        return _Reference(
            speeds_m_s=speeds,
            n_harmonics=n,
            interpolators=interps,
            walk_ratio=float(st["walk_ratio_m_per_step_per_min"]),
            stance_intercept=float(st["stance_fraction_intercept"]),
            stance_slope=float(st["stance_fraction_slope_per_m_s"]),
        )
    except (OSError, ValueError, KeyError, TypeError) as err:
        raise GaitCurveError(f"{path}: malformed gait reference table ({err})") from None


def valid_speed_range_m_s() -> tuple[float, float]:
    """The walking speeds (m/s) the curves are valid for, inclusive."""
    speeds = _reference().speeds_m_s
    return float(speeds[0]), float(speeds[-1])


def _check_speed(speed_m_s: float) -> float:
    try:
        speed = float(speed_m_s)
    except (TypeError, ValueError):
        raise GaitCurveError(f"speed_m_s must be a number, got {speed_m_s!r}") from None
    lo, hi = valid_speed_range_m_s()
    if not (lo - _SPEED_TOL <= speed <= hi + _SPEED_TOL):  # also rejects NaN
        raise GaitCurveError(
            f"speed_m_s={speed!r} is outside the range of the gait reference curves "
            f"[{lo}, {hi}] m/s (derived from Schwartz et al. 2008; see docs/kinematics.md)"
        )
    return min(max(speed, lo), hi)


def _check_phase(phase: float | np.ndarray) -> np.ndarray:
    phase_arr = np.asarray(phase, dtype=float)
    if not np.all(np.isfinite(phase_arr)):
        raise GaitCurveError("phase must be finite (cycles, 0 = foot strike); got NaN or inf")
    return phase_arr


def _evaluate(key: str, phase: np.ndarray, speed: float, derivative: int) -> np.ndarray:
    if derivative not in (0, 1, 2):
        raise GaitCurveError(f"derivative must be 0, 1 or 2, got {derivative!r}")
    ref = _reference()
    c = ref.interpolators[key](speed)
    k = np.arange(1, ref.n_harmonics + 1)
    a, b = c[1::2], c[2::2]
    arg = 2.0 * np.pi * np.multiply.outer(phase, k)
    w = 2.0 * np.pi * k
    if derivative == 0:
        value = c[0] + np.cos(arg) @ a + np.sin(arg) @ b
    elif derivative == 1:
        value = np.cos(arg) @ (w * b) - np.sin(arg) @ (w * a)
    else:
        value = -(np.cos(arg) @ (w**2 * a)) - np.sin(arg) @ (w**2 * b)
    return np.asarray(value, dtype=float)


def joint_angles(
    phase: float | np.ndarray, speed_m_s: float, derivative: int = 0
) -> dict[str, np.ndarray]:
    """Sagittal hip, knee and ankle angles (rad) at gait ``phase`` and walking speed.

    ``phase`` is in cycles (scalar or array; 0 = foot strike of this leg; the curves are
    periodic, so any finite value is taken modulo 1). ``derivative`` = 1 or 2 gives d/dphase
    (rad per cycle, per cycle²); divide by the stride time for rad/s. Returns arrays of the
    shape of ``phase`` under keys "hip" (flexion +), "knee" (flexion +), "ankle"
    (dorsiflexion +). Raises :class:`GaitCurveError` outside 0.6-1.8 m/s or for NaN phase.
    """
    phase_arr = _check_phase(phase)
    speed = _check_speed(speed_m_s)
    return {key: _evaluate(key, phase_arr, speed, derivative) for key in JOINTS}


def pelvis_tilt(phase: float | np.ndarray, speed_m_s: float, derivative: int = 0) -> np.ndarray:
    """Sagittal pelvic tilt (rad, anterior +) at gait ``phase`` and speed (see joint_angles)."""
    return _evaluate("pelvis_tilt", _check_phase(phase), _check_speed(speed_m_s), derivative)


def thigh_angle(phase: float | np.ndarray, speed_m_s: float, derivative: int = 0) -> np.ndarray:
    """Thigh inclination from the vertical in the sagittal plane (rad, flexion sense +).

    Equals hip flexion minus anterior pelvic tilt: what a thigh-mounted IMU integrates.
    """
    phase_arr = _check_phase(phase)
    speed = _check_speed(speed_m_s)
    return _evaluate("hip", phase_arr, speed, derivative) - _evaluate(
        "pelvis_tilt", phase_arr, speed, derivative
    )


def cadence_steps_per_min(speed_m_s: float) -> float:
    """Adult cadence (steps/min) at ``speed_m_s``, from a constant walk ratio.

    Walk ratio W = step length / cadence ≈ 0.0063 m per step/min (Sekiya & Nagasaki 1998),
    so cadence = sqrt(60 v / W).
    """
    speed = _check_speed(speed_m_s)
    return math.sqrt(60.0 * speed / _reference().walk_ratio)


def stride_time_s(speed_m_s: float) -> float:
    """Adult stride time (s, foot strike to the same foot's next strike) at ``speed_m_s``."""
    return 120.0 / cadence_steps_per_min(speed_m_s)


def stride_length_m(speed_m_s: float) -> float:
    """Adult stride length (m, two steps) at ``speed_m_s``: speed times stride time."""
    return float(speed_m_s) * stride_time_s(speed_m_s)


def stance_fraction(speed_m_s: float) -> float:
    """Fraction of the cycle in stance at ``speed_m_s``: 0.642 - 0.035 v (Kirtley et al. 1985).

    Toe-off of this leg happens at this phase.
    """
    speed = _check_speed(speed_m_s)
    ref = _reference()
    return ref.stance_intercept + ref.stance_slope * speed

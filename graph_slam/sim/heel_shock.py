"""The heel-contact transient of a thigh-mounted IMU's accelerometer.

At heel contact the ground stops the leg within milliseconds; the shock travels up the skeleton
as a wave and reaches a skin-mounted sensor on the thigh as a short burst of specific force
along the limb, damped within ~0.1 s. Its size lies between the tibia's and the head's: about
5 g at the tibia and 0.5 g at the skull with hard heels (half with resilient heels) in normal
walking (Light, McLellan & Klenerman 1980, *Skeletal transients on heel strike in normal
walking with different footwear*, J. Biomech. 13:477-480); on a real thigh walk (the Xsens
MTx thigh sensor of ``shared/data/real_thigh_imu``, scikit-kinematics test data, 120 Hz) the
bursts peak 30-45 ms after contact, 15-20 m/s² above the smooth signal.

The burst is modelled as a real vibration of the sensor's mount along the thigh's long axis: a
displacement ``d(τ) = D (τ/τd)³ e^{-τ/τd} sin(2π f τ)`` for ``τ ≥ 0`` after each heel contact
(τd = 10 ms: the envelope peaks 30 ms after contact; f = 25 Hz; D scaled so that the acceleration ``d''`` peaks at the amplitude
asked, 0.4 mm for 15 m/s²). ``d`` and its first three derivatives are zero at contact (a sampled
integration sees no kink) and all decay to zero, so the
burst integrates to zero velocity and zero displacement: IMU integration still reproduces the
thigh's trajectory (during the burst the sensor is off the thigh pose by at most ``D``, after
it by nothing; the thigh's own rotation during the 0.1 s bends the integral by < 0.1 mm/s).
The gyro is unchanged (a translation of the mount).
"""

from __future__ import annotations

import math

import numpy as np

SHOCK_HZ = 25.0
DECAY_S = 0.010
SPAN_S = 30 * DECAY_S
"""The burst is cut here (its displacement is below 1e-8 of its peak)."""


def _unit_accel(tau_s: np.ndarray) -> np.ndarray:
    """``d''(τ)`` for D = 1 m (zero before contact and after ``SPAN_S``)."""
    tau = np.asarray(tau_s, dtype=float)
    inside = (tau >= 0) & (tau < SPAN_S)
    x = np.where(inside, tau, 0.0) / DECAY_S
    w = 2 * math.pi * SHOCK_HZ
    e = np.exp(-x)
    g = x**3 * e
    g1 = (3 * x**2 - x**3) * e / DECAY_S
    g2 = (6 * x - 6 * x**2 + x**3) * e / DECAY_S**2
    s, c = np.sin(w * np.where(inside, tau, 0.0)), np.cos(w * np.where(inside, tau, 0.0))
    return np.where(inside, g2 * s + 2 * g1 * w * c - g * w * w * s, 0.0)


_PEAK_PER_M = float(np.abs(_unit_accel(np.linspace(0.0, SPAN_S, 20001))).max())


def heel_shock_displacement_m(tau_s: np.ndarray, amplitude_m_s2: float) -> np.ndarray:
    """The mount's displacement along the limb ``τ`` after contact (for checks)."""
    tau = np.asarray(tau_s, dtype=float)
    inside = (tau >= 0) & (tau < SPAN_S)
    x = np.where(inside, tau, 0.0) / DECAY_S
    d = x**3 * np.exp(-x) * np.sin(2 * math.pi * SHOCK_HZ * np.where(inside, tau, 0.0))
    return np.where(inside, d, 0.0) * amplitude_m_s2 / _PEAK_PER_M


def heel_shock_accel(t_s: np.ndarray, strikes_s: np.ndarray, amplitude_m_s2: float) -> np.ndarray:
    """(n,) acceleration along the limb (m/s², up the thigh +) of the bursts of the heel
    contacts ``strikes_s`` at ``t_s``; zeros when ``amplitude_m_s2`` is 0."""
    t = np.atleast_1d(np.asarray(t_s, dtype=float))
    out = np.zeros(t.size)
    if amplitude_m_s2 <= 0:
        return out
    for ts in np.asarray(strikes_s, dtype=float):
        near = (t >= ts) & (t < ts + SPAN_S)
        if near.any():
            out[near] += _unit_accel(t[near] - ts)
    return out * amplitude_m_s2 / _PEAK_PER_M


def heel_shock_in_frame(
    t_s: np.ndarray, strikes_s: np.ndarray, amplitude_m_s2: float, thigh_T_frame: np.ndarray
) -> np.ndarray:
    """(n, 3) the bursts in a thigh-fixed sensor frame: along the thigh's long axis (the thigh
    frame's z, up the thigh when the leg is straight)."""
    limb = np.asarray(thigh_T_frame, dtype=float)[:3, :3].T @ np.array([0.0, 0.0, 1.0])
    return np.outer(heel_shock_accel(t_s, strikes_s, amplitude_m_s2), limb)

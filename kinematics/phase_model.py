"""The measurement model of the gait-phase EKF: normalised reference thigh-angle curves.

The reference thigh angle (:func:`kinematics.gait_curves.thigh_angle`) is a Fourier series in
the phase; at each speed of a grid (0.6-1.8 m/s, 0.05 m/s) it is normalised to zero mean and unit
standard deviation over the cycle, ``c(φ; v) = (θ_ref(φ; v) - mean) / std``, and kept as its
8 harmonics. The EKF measures the thigh angle and rate normalised by the wearer's own running
offset ``m`` and scale ``s`` (:class:`kinematics.gait_phase.OnlineGaitEstimator`):

    z = [(θ - m) / s, ω / s],    h(φ, r) = [c(φ), c'(φ) r],
    H = ∂h/∂(φ, r) = [[c'(φ), 0], [c''(φ) r, c'(φ)]]

with ``φ`` the phase (cycles, 0 = foot strike), ``r`` its rate (cycles/s) and ``'`` = d/dφ. The
curve's speed follows the rate through the adult stride-time/speed relation
(:func:`kinematics.gait_curves.stride_time_s`); the Jacobian holds the speed fixed (the shape
changes little within one update, and the speed is a parameter of the model, not a state).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

N_HARMONICS = 8
_SPEED_GRID = np.round(np.arange(0.6, 1.8001, 0.05), 3)


@dataclass(frozen=True)
class PhaseReference:
    """Normalised thigh-angle Fourier coefficients on a speed grid (see the module docstring)."""

    speeds_m_s: np.ndarray
    rates_cyc_s: np.ndarray
    """Cadence of each speed (strides per second), increasing."""
    cos_coeffs: np.ndarray  # (speeds, harmonics)
    sin_coeffs: np.ndarray
    mean_rad: np.ndarray
    std_rad: np.ndarray
    stance_fraction: np.ndarray

    def coefficients(self, rate_cyc_s: float) -> tuple[np.ndarray, np.ndarray]:
        """(cos, sin) coefficients at the speed of ``rate_cyc_s`` (linear in speed)."""
        pos = float(np.interp(rate_cyc_s, self.rates_cyc_s, np.arange(self.speeds_m_s.size)))
        i = min(int(pos), self.speeds_m_s.size - 2)
        w = pos - i
        a = (1 - w) * self.cos_coeffs[i] + w * self.cos_coeffs[i + 1]
        b = (1 - w) * self.sin_coeffs[i] + w * self.sin_coeffs[i + 1]
        return a, b

    def at_rate(self, name: str, rate_cyc_s: float) -> float:
        """``mean_rad``, ``std_rad`` or ``stance_fraction`` at the speed of ``rate_cyc_s``."""
        return float(np.interp(rate_cyc_s, self.rates_cyc_s, getattr(self, name)))


def curve(phase: float, a: np.ndarray, b: np.ndarray) -> tuple[float, float, float]:
    """c(φ), c'(φ), c''(φ) of the series with coefficients ``a`` (cos), ``b`` (sin)."""
    k = np.arange(1, a.size + 1)
    w = 2.0 * np.pi * k
    arg = w * phase
    cos, sin = np.cos(arg), np.sin(arg)
    c = float(cos @ a + sin @ b)
    d1 = float(cos @ (w * b) - sin @ (w * a))
    d2 = float(-(cos @ (w**2 * a)) - sin @ (w**2 * b))
    return c, d1, d2


def measurement(x: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """h(x) for the state x = [phase_cyc, rate_cyc_s]: [c(φ), c'(φ) r]."""
    c, d1, _ = curve(float(x[0]), a, b)
    return np.array([c, d1 * float(x[1])])


def measurement_jacobian(x: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """∂h/∂x (2×2) at x = [phase_cyc, rate_cyc_s]."""
    _, d1, d2 = curve(float(x[0]), a, b)
    return np.array([[d1, 0.0], [d2 * float(x[1]), d1]])


@lru_cache(maxsize=1)
def phase_reference() -> PhaseReference:
    """The normalised reference curves on the speed grid (computed once)."""
    from kinematics.gait_curves import stance_fraction, stride_time_s, thigh_angle

    n = 256
    phase = np.arange(n) / n
    cos_c, sin_c, means, stds = [], [], [], []
    for v in _SPEED_GRID:
        theta = thigh_angle(phase, float(v))
        mean, std = float(theta.mean()), float(theta.std())
        spec = np.fft.rfft((theta - mean) / std) / n
        cos_c.append(2 * spec.real[1 : N_HARMONICS + 1])
        sin_c.append(-2 * spec.imag[1 : N_HARMONICS + 1])
        means.append(mean)
        stds.append(std)
    rates = np.array([1.0 / stride_time_s(float(v)) for v in _SPEED_GRID])
    return PhaseReference(
        speeds_m_s=_SPEED_GRID.copy(),
        rates_cyc_s=rates,
        cos_coeffs=np.asarray(cos_c),
        sin_coeffs=np.asarray(sin_c),
        mean_rad=np.asarray(means),
        std_rad=np.asarray(stds),
        stance_fraction=np.array([stance_fraction(float(v)) for v in _SPEED_GRID]),
    )

"""The up vector at a foot strike, from the thigh IMU alone (causal).

A plain mean of the accelerometer just before a foot strike is dominated by the swing leg's
deceleration (measured here: ~15° of pitch error in the stride frame). Over about one stride
the leg's mean acceleration is near zero (the velocity at consecutive foot strikes is nearly
the same), so the accelerometer samples of the last stride, each rotated into the IMU frame at
the strike by the integrated gyro, average to gravity.

:class:`GravityEstimator` is built once per pipeline and fed through the pipeline's own
``add_imu`` / ``foot_strike``: it reads nothing it was not given, and only samples at or
before the time it is asked about.
"""

from __future__ import annotations

import numpy as np

MIN_SAMPLES = 10
"""Fewer finite samples in the window: no up vector (None)."""


def rotated_mean_accel(
    t_s: np.ndarray, gyro_rad_s: np.ndarray, accel_m_s2: np.ndarray
) -> np.ndarray:
    """Mean of ``accel_m_s2`` with every sample rotated into the frame of the last one by the
    trapezoid-integrated gyro (backward from the last sample)."""
    from scipy.spatial.transform import Rotation

    n = t_s.size
    rot = np.empty((n, 3, 3))  # rot[k] = frame(t_last)_R_frame(t_k)
    rot[-1] = np.eye(3)
    if n > 1:  # every step's rotation at once (one scipy call per sample took 9 ms a stride)
        dt = np.diff(t_s)[:, None]
        steps = Rotation.from_rotvec(0.5 * (gyro_rad_s[:-1] + gyro_rad_s[1:]) * dt).as_matrix()
    for k in range(n - 2, -1, -1):
        rot[k] = rot[k + 1] @ steps[k].T
    return np.einsum("kij,kj->i", rot, accel_m_s2) / n


class GravityEstimator:
    """Up (m/s², IMU frame) from the gyro-rotated accelerometer mean over the last stride.

    ``default_window_s``: the averaging window when no earlier foot strike is known (the
    session's first); otherwise the previous stride's duration (strike to strike).
    ``keep_s``: at a foot strike, samples older than this are forgotten (memory stays flat on
    long recordings; a window longer than this is cut to it).
    """

    def __init__(self, default_window_s: float = 1.0, keep_s: float = 10.0) -> None:
        self.default_window_s = float(default_window_s)
        self.keep_s = float(keep_s)
        self._t = np.empty(0)
        self._gyro = np.empty((0, 3))
        self._accel = np.empty((0, 3))
        self._strikes: list[float] = []
        self.first_t_s: float | None = None
        """Time of the first IMU sample ever given (how much history a window can have)."""

    def add_imu(self, t_s, gyro_rad_s, accel_m_s2) -> None:
        """Append samples (time order). Non-finite ones are kept here and skipped when
        averaging: the estimator's own IMU buffer counts them."""
        t = np.asarray(t_s, float).reshape(-1)
        if t.size == 0:
            return
        if self.first_t_s is None:
            self.first_t_s = float(t[0])
        self._t = np.concatenate([self._t, t])
        self._gyro = np.concatenate([self._gyro, np.asarray(gyro_rad_s, float).reshape(-1, 3)])
        self._accel = np.concatenate([self._accel, np.asarray(accel_m_s2, float).reshape(-1, 3)])

    def foot_strike(self, t_s: float) -> None:
        """Note a foot strike (sets the next window to the stride's duration); samples more
        than ``keep_s`` before it are forgotten."""
        self._strikes = [*self._strikes[-3:], float(t_s)]  # a double strike keeps the stride
        self.drop_before(t_s - self.keep_s)

    def drop_before(self, t_s: float) -> None:
        """Forget samples before ``t_s`` (the pipelines call it at every frame with
        ``t - keep_s``: memory stays flat, with or without foot strikes)."""
        k = int(np.searchsorted(self._t, t_s, side="left"))
        if k:
            self._t, self._gyro, self._accel = self._t[k:], self._gyro[k:], self._accel[k:]

    def window_before(self, t_s: float) -> float:
        """The previous stride's duration (the last strike more than 0.3 s before ``t_s`` to
        ``t_s``) when known, else ``default_window_s``."""
        before = [s for s in self._strikes if s < t_s - 0.3]
        return float(t_s - before[-1]) if before else self.default_window_s

    def history_s(self, t_s: float) -> float:
        """How much IMU history lies before ``t_s`` (0 without samples)."""
        return 0.0 if self.first_t_s is None else float(t_s - self.first_t_s)

    def up_at(self, t_s: float, window_s: float) -> np.ndarray | None:
        """Up in the IMU frame at ``t_s`` from the finite samples in ``[t_s - window_s, t_s]``;
        None with fewer than :data:`MIN_SAMPLES`."""
        t = self._t
        m = (t >= t_s - window_s) & (t <= t_s)
        m &= np.isfinite(self._accel).all(1) & np.isfinite(self._gyro).all(1)
        idx = np.flatnonzero(m)
        if idx.size < MIN_SAMPLES:
            return None
        return rotated_mean_accel(t[idx], self._gyro[idx], self._accel[idx])

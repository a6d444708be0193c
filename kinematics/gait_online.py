"""Batch use of the online gait estimator, and its CSV output.

:func:`estimate_online` feeds a whole :class:`~kinematics.imu.ImuSeries` to
:class:`~kinematics.gait_phase.OnlineGaitEstimator` one sample at a time (a loop: the estimator
has not seen sample k + 1 when it answers for sample k, so the batch result is causal by
construction). :func:`write_online_events_csv` writes ``t_s,kind,detected_t_s`` rows (estimated
event time, kind, the time of the sample at which the event was emitted).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from kinematics.errors import GaitInputError
from kinematics.gait_phase import OnlineGaitEstimator
from kinematics.gait_phase_config import GaitPhaseConfig, OnlineEvent
from kinematics.imu import ImuSeries
from kinematics.thigh_attitude import SagittalAxis


@dataclass(frozen=True)
class OnlineGaitResult:
    """Per-sample states and the events of :func:`estimate_online`."""

    t_s: np.ndarray
    phase_cyc: np.ndarray
    phase_sigma_cyc: np.ndarray
    rate_cyc_s: np.ndarray
    angle_rad: np.ndarray
    flags: np.ndarray
    events: list[OnlineEvent]
    counts: dict[str, int]
    sagittal_axis: SagittalAxis | None = None
    """The axis the estimator ended with (None: never fixed); pass it to a later recording with
    the same mounting to skip learning."""
    strike_bias_s: float = 0.0
    """The phase model's strike bias learned at the end (reference strike − its own)."""
    strike_bias_source: str = "none"
    """Where it was learned: ``impact``, ``load cell`` or ``none``."""

    def times(self, kind: str, detected: bool = False) -> np.ndarray:
        """Estimated (or detection) times of the events of ``kind``."""
        return np.array(
            [e.detected_t_s if detected else e.t_s for e in self.events if e.kind == kind]
        )


def estimate_online(
    imu: ImuSeries,
    config: GaitPhaseConfig | None = None,
    sagittal_axis: SagittalAxis | None = None,
    load_n: np.ndarray | None = None,
    knee_rad: np.ndarray | None = None,
) -> OnlineGaitResult:
    """Run :class:`OnlineGaitEstimator` over a series one sample at a time (causal by
    construction: the loop hands the estimator sample k before it has seen k + 1).

    ``load_n``, ``knee_rad``: the prosthesis's load cell and knee encoder at the IMU's sample
    times (NaN where missing), when it has them."""
    est = OnlineGaitEstimator(config, sagittal_axis)
    t = np.asarray(imu.t_s, dtype=float)
    gyro = np.asarray(imu.gyro_rad_s, dtype=float)
    accel = np.asarray(imu.accel_m_s2, dtype=float)
    rows = np.full((t.size, 5), np.nan)
    flags = np.zeros(t.size, dtype=int)
    load = None if load_n is None else np.asarray(load_n, dtype=float)
    knee = None if knee_rad is None else np.asarray(knee_rad, dtype=float)
    for name, arr in (("load_n", load), ("knee_rad", knee)):
        if arr is not None and arr.shape != t.shape:
            raise GaitInputError(f"{imu.source}: {name} has {arr.shape}, the IMU {t.shape} samples")
    for k in range(t.size):
        est.update(
            t[k],
            gyro[k],
            accel[k],
            None if load is None else float(load[k]),
            None if knee is None else float(knee[k]),
        )
        s = est.state
        rows[k] = (s.t_s, s.phase_cyc, s.phase_sigma_cyc, s.rate_cyc_s, s.angle_rad)
        flags[k] = s.flags
    return OnlineGaitResult(
        t_s=t,
        phase_cyc=rows[:, 1],
        phase_sigma_cyc=rows[:, 2],
        rate_cyc_s=rows[:, 3],
        angle_rad=rows[:, 4],
        flags=flags,
        events=list(est.events),
        counts=dict(est.counts),
        sagittal_axis=est.thigh.axis if est.thigh is not None else None,
        strike_bias_s=est.timing.bias_s,
        strike_bias_source=est.timing.bias_source,
    )


def write_online_events_csv(path: str | Path, events: list[OnlineEvent]) -> Path:
    """Write ``t_s,kind,detected_t_s`` rows in emission order (estimated time, kind, time of the
    sample that emitted it; detected_t_s - t_s is the estimator's delay for that event)."""
    path = Path(path)
    with path.open("w", newline="", encoding="utf-8") as fh:
        fh.write("t_s,kind,detected_t_s\n")
        for e in events:
            fh.write(f"{e.t_s:.6f},{e.kind},{e.detected_t_s:.6f}\n")
    return path

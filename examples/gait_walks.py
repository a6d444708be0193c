"""The walks the gait examples score: the real thigh IMUs of ``../shared/data/real_thigh_imu/``
(the Xsens thigh walk with its shank-derived strikes; the two OpenSense femur walks, scored
against the reference derived from both thighs, :mod:`kinematics.gait_two_legs`) and the
synthetic prosthetic-gait set (:mod:`kinematics.gait_patterns`, one walk per axis
arrangement of the sensor). Used by ``real_gait_accuracy.py`` and ``phase_limits.py``."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np

from kinematics.gait_impact import envelope
from kinematics.gait_patterns import PROSTHETIC_SIDE, SOUND_SIDE
from kinematics.gait_real import (
    read_reference_strikes,
    read_xsens_orientation,
    read_xsens_txt,
    right_handed_arrangements,
)
from kinematics.gait_scenarios import simulate_walks
from kinematics.gait_synth import random_mounting
from kinematics.gait_two_legs import (
    DerivedStrikes,
    Leg,
    derive_strikes,
    thigh_inclination_rad,
)
from kinematics.imu import ImuSeries

REPO = Path(__file__).resolve().parents[1]
DEFAULT_DATA = REPO.parent / "shared" / "data" / "real_thigh_imu"


@dataclasses.dataclass
class Walk:
    name: str
    imu: ImuSeries
    strikes_s: np.ndarray | None
    """Reference strikes (None: no contact reference)."""
    derived: DerivedStrikes | None = None
    """A reference derived from the two thighs of the walk (when there is no other)."""
    legs: tuple[Leg, Leg] | None = None
    """(this thigh, the other thigh) of a two-thigh walk."""
    toe_offs_s: np.ndarray | None = None
    """True toe-offs (synthetic walks): the online toe-offs are then scored too."""


def unreferenced(walk: Walk) -> np.ndarray | None:
    """Swings without a reference strike (the derived reference's empty spans start at them):
    the phase is not scored across them."""
    return walk.derived.unreferenced_s[:, 0] if walk.derived is not None else None


def walk_start_s(imu: ImuSeries) -> float:
    from scipy.signal import butter, sosfiltfilt

    rate = 1.0 / float(np.median(np.diff(imu.t_s)))
    g = sosfiltfilt(butter(2, 2.0, fs=rate, output="sos"), imu.gyro_rad_s, axis=0)
    moving = np.flatnonzero(np.linalg.norm(g, axis=1) > 0.5)
    return float(imu.t_s[moving[0]]) if moving.size else math.inf


def real_walks(data: Path) -> list[Walk]:
    walks = []
    xsens = data / "walking_xsens_upperLeg.txt"
    if xsens.exists():
        ref = read_reference_strikes(data / "reference_events.csv")
        walks.append(Walk("Xsens thigh walk (120 Hz)", read_xsens_txt(xsens), ref))
    femurs = []
    for name, side in (("00B4227C.txt", "right"), ("00B421EE.txt", "left")):
        if (data / name).exists():
            imu = read_xsens_txt(data / name)
            walks.append(Walk(f"OpenSense {side} femur (100 Hz, turns)", imu, None))
            femurs.append((walks[-1], _leg(imu, data / name)))
    if len(femurs) == 2:
        for (walk, own), (_, other) in (femurs, femurs[::-1]):
            walk.legs = (own, other)
            walk.derived = derive_strikes(own, other)
            walk.strikes_s = walk.derived.strikes_s
    return walks


def _leg(imu: ImuSeries, path: Path) -> Leg:
    t, global_R_sensor = read_xsens_orientation(path)
    incl = thigh_inclination_rad(global_R_sensor, imu.accel_m_s2, imu.gyro_rad_s)
    return Leg(t, incl, envelope(t, imu.accel_m_s2))


def synthetic_walks(quick: bool) -> list[Walk]:
    arrangements = right_handed_arrangements()
    sets = [
        ("prosthesis side, overground 0.9 m/s", PROSTHETIC_SIDE, 0.9),
        ("prosthesis side, treadmill 1.1 m/s", dataclasses.replace(PROSTHETIC_SIDE, treadmill=True), 1.1),
        ("sound side, treadmill 0.7 m/s", dataclasses.replace(SOUND_SIDE, treadmill=True), 0.7),
    ]  # fmt: skip
    walks = []
    n = 2 if quick else 8
    for name, pattern, speed in sets:
        for k in range(n):
            idx = (len(walks) * 5 + k) % 24
            mount = arrangements[idx] @ random_mounting(100 + k) if k % 2 else arrangements[idx]
            sc = simulate_walks(
                [[speed] * 12],
                rate_hz=200.0 if k % 2 == 0 else 100.0,
                thigh_R_sensor=mount,
                seed=100 + len(walks),
                pattern=pattern,
            )
            walks.append(Walk(name, sc.imu, sc.foot_strikes_s))
    return walks

"""Configuration and result record of the offline gait-event detectors
(:mod:`kinematics.gait_events`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

EVENT_KINDS: tuple[str, ...] = ("foot_strike", "toe_off")


@dataclass(frozen=True)
class GaitEventConfig:
    """Parameters of the gait-event detectors (SI units)."""

    min_stride_s: float = 0.7
    """Plausible minimum stride time: closer foot strikes are merged (walking at 1.8 m/s has
    about 0.9 s strides)."""
    max_stride_s: float = 2.5
    """Longest stride still counted as continuous walking."""
    lowpass_hz: float = 8.0
    work_rate_hz: float = 100.0
    min_swing_peak_rad_s: float = 0.8
    """Smallest mid-swing thigh flexion velocity counted as a step (reference: 1.5 rad/s at
    0.6 m/s, 3-4 rad/s at 1.2-1.8 m/s)."""
    min_correlation: float = 0.8
    """Minimum normalised correlation of an event's template alignment."""
    strike_window: tuple[float, float] = (-0.30, 0.25)
    """Phases around the foot strike used to align it."""
    toe_off_window: tuple[float, float] = (-0.20, 0.12)
    """Phases around toe-off used to align it."""
    search_fraction: float = 0.15
    """Alignment search range, ± this fraction of the stride around the predicted time."""
    amplitude_ratio: tuple[float, float] = (0.35, 3.0)
    """Allowed ratio of the measured to the template angular-velocity spread in a window."""
    min_window_fraction: float = 0.6
    """At the ends of a recording, use an alignment window cut to at least this fraction."""
    use_impacts: bool = True
    """Place the strikes on the accelerometer's heel-strike shocks and check the axis sign with
    them when the shocks are there (:mod:`kinematics.gait_impact`); False: the template only."""
    # load cell
    min_contact_s: float = 0.15
    min_swing_s: float = 0.15


@dataclass(frozen=True)
class DetectedEvents:
    """What a detector found: the events and how (method, merged and rejected candidates).

    Not a session record: ``graph_slam.session.records.GaitEvents`` is the validated stream of
    events a session holds (time, kind and source per event)."""

    foot_strikes_s: np.ndarray
    toe_offs_s: np.ndarray
    method: str
    merged_strikes: int = 0
    """Foot strikes merged because they were closer than ``min_stride_s``."""
    rejected: int = 0
    """Candidate events dropped (low correlation, chatter)."""
    sagittal_axis: np.ndarray | None = None
    """IMU method: unit axis in the sensor frame about which thigh flexion is positive."""
    details: dict[str, float] = field(default_factory=dict)

    def rows(self) -> list[tuple[float, str]]:
        """(t_s, kind) sorted by time."""
        out = [(float(t), "foot_strike") for t in self.foot_strikes_s]
        out += [(float(t), "toe_off") for t in self.toe_offs_s]
        return sorted(out)

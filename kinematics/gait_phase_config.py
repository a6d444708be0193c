"""Configuration and records of the online gait estimator (:mod:`kinematics.gait_phase`):
the noise and rule parameters, the events it emits and its per-sample state."""

from __future__ import annotations

from dataclasses import dataclass, field

from kinematics.gait_first_strike import FirstStrikeConfig
from kinematics.gait_phase_angle import AnglePhaseConfig
from kinematics.gait_phase_impact import StrikeTimingConfig
from kinematics.gait_prosthesis import ProsthesisConfig
from kinematics.thigh_attitude import ThighAttitudeConfig

COUNT_NAMES = (
    "samples",
    "nonfinite",
    "saturated",
    "gaps",
    "reacquired",
    "phase_jumps",
    "axis_flipped",
    "stops",
    "impact_strikes",
    "sign_disagreement",
    "load_cell_strikes",
    "first_strikes",
    "first_strikes_unconfirmed",
    "holds",
    "shock_strikes",
)


@dataclass(frozen=True)
class GaitPhaseConfig:
    """Parameters of the phase EKF, the walking detector and the event rule."""

    phase_walk_cyc_per_sqrt_s: float = 0.015
    """Process noise of the phase beyond the constant-rate model."""
    rate_walk_cyc_s_per_sqrt_s: float = 0.15
    """Random walk of the stride rate (a change of ~0.25 strides/s within a second)."""
    angle_sigma: float = 0.6
    """σ of the normalised angle (model and shape mismatch, in units of the angle's std)."""
    rate_sigma: float = 2.5
    """σ of the normalised rate (units of the angle's std per second)."""
    walk_on_rms_rad_s: float = 0.5
    """Walking starts when the thigh-rate RMS over ``rms_window_s`` exceeds this."""
    walk_off_rms_rad_s: float = 0.2
    """... and stops (standing: the phase freezes) when it falls below this."""
    rms_window_s: float = 0.25
    still_window_s: float = 0.35
    """Standing is also declared at once when the thigh rate stayed below ``still_rate_rad_s``
    over this window."""
    still_rate_rad_s: float = 0.2
    standing_posture_s: float = 0.5
    """Still this long: the angle is the standing posture (the offset prior of the next walk)."""
    max_gap_s: float = 0.05
    """A longer gap between samples is counted (``gaps``) and its next sample flagged."""
    max_bridge_s: float = 0.15
    """A gap up to this long is predicted through (a tenth of a stride: lost packets of a
    wireless sensor); a longer one drops the phase lock, re-acquired after it."""
    gyro_range_rad_s: float = 34.9
    """Sensor range: a sample at or past it is saturated (counted, predicted through)."""
    accel_range_m_s2: float = 156.0
    max_nis: float = 20.0
    """Mean normalised innovation squared (2 dof) over ``rms_window_s`` beyond which the phase
    is re-acquired (counted)."""
    max_hold_s: float = 0.3
    """An update that holds the phase at its floor (it wanted to run backwards) or the rate at
    its lower bound this long drops the lock, re-acquired at once (counted as ``holds``):
    shorter than a swing (0.4-0.5 s), so that a lock held from a swing's start is regained
    before the strike that ends it. On the Xsens walk and the synthetic prosthetic set no hold
    within a walk lasts 0.1 s, except as a walk ends into standing."""
    max_phase_step_cyc: float = 0.08
    """An update that moves the phase by more than this is a jump (counted, flagged)."""
    acquire_grace_cyc: float = 0.05
    """At (re-)acquisition, an event phase passed by less than this is still emitted."""
    min_event_spacing_s: float = 0.35
    """Events of one kind closer than this are not emitted (a jump across a boundary)."""
    stall_ratio: float = 0.25
    """In stance (from ``stall_from_phase`` to toe-off) a thigh rate below this fraction of the
    model's for ``stall_s`` is a stop: the phase freezes at once (counted as ``stops``)."""
    stall_from_phase: float = 0.15
    stall_s: float = 0.06
    sign_by_fit: bool = False
    """Choose the axis sign by the phase model's fit over the learning buffer (else by the
    learner's peak asymmetry over a whole cycle)."""
    sign_check_s: float = 0.0
    """After the axis is fixed, the other sign keeps running this long; the estimator switches to
    it if its mean NIS since then is lower by ``sign_switch_margin`` (counted)."""
    sign_switch_margin: float = 0.5
    sign_recheck_strides: int = 2
    """After the axis is fixed, the sign is re-examined once this many strike and toe-off
    windows are seen, and at every sample after: when the impact bursts sit at the toe-offs
    rather than at the strikes (or, with a prosthesis's load cell or knee encoder, the thigh
    flexes in stance and extends in swing), the axis is flipped (counted as ``axis_flipped``
    and ``sign_disagreement``; 0 turns the impact check off)."""
    strike_timing: StrikeTimingConfig = field(default_factory=StrikeTimingConfig)
    first_strike: FirstStrikeConfig = field(default_factory=FirstStrikeConfig)
    """The first strikes of a walk, emitted before the axis is learned
    (:mod:`kinematics.gait_first_strike`)."""
    prosthesis: ProsthesisConfig = field(default_factory=ProsthesisConfig)
    attitude: ThighAttitudeConfig = field(default_factory=ThighAttitudeConfig)
    stride_phase: AnglePhaseConfig | None = field(default_factory=AnglePhaseConfig)
    """With impacts, the phase within a stride is re-timed by the thigh's landmarks
    (:mod:`kinematics.gait_phase_angle`); None: linear in time over the recent stride time."""


@dataclass(frozen=True)
class OnlineEvent:
    """A gait event as the estimator emits it: ``t_s`` the estimated event time, ``detected_t_s``
    the time of the sample at which it was emitted (latency = detected - true)."""

    kind: str
    t_s: float
    detected_t_s: float
    phase_sigma_cyc: float


@dataclass(frozen=True)
class GaitState:
    """The estimator's state after a sample (phase NaN when not walking)."""

    t_s: float
    walking: bool
    phase_cyc: float
    """Phase in [0, 1) (0 = foot strike); NaN while standing or before the first lock."""
    phase_sigma_cyc: float
    rate_cyc_s: float
    angle_rad: float
    rate_rad_s: float
    flags: int = 0
    """Bit 1 non-finite (dropped), 2 saturated, 4 after a gap, 8 phase jump, 16 re-acquired,
    32 stop detected in stance."""

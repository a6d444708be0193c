"""Online strike timing (kinematics.gait_phase_impact.StrikeTiming): an onset whose threshold
was learned from weaker bursts is held while its burst is followed, and placed where a settled
threshold puts it; with a settled typical peak nothing is held."""

from __future__ import annotations

import math

import numpy as np
import pytest

from kinematics.gait_impact import envelope, first_rise
from kinematics.gait_phase_impact import StrikeTiming, StrikeTimingConfig

RATE_HZ = 200.0
PRE_S, CONTACT_S = 1.95, 2.10
"""Quiet until 1.95 s; a weak precursor growing to a twelfth of the shock's amplitude until
2.10 s; the shock from 2.10 s: the shape of the right femur's first strike after its opening
turn (its envelope rose over 0.1 s to a fifth of the shock's peak)."""


def _accel(seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 2.6, 1.0 / RATE_HZ)
    a = np.tile([0.0, 0.0, 9.81], (t.size, 1)) + rng.normal(0.0, 0.02, (t.size, 3))
    osc = np.sin(2 * math.pi * 27.0 * t)
    pre = (t >= PRE_S) & (t < CONTACT_S)
    a[pre, 0] += 1.0 * osc[pre] * (t[pre] - PRE_S) / (CONTACT_S - PRE_S)
    shock = t >= CONTACT_S
    a[shock, 2] += 12.0 * osc[shock] * np.exp(-(t[shock] - CONTACT_S) / 0.06)
    return t, a


def _run(t, a, peaks: list[float], cfg: StrikeTimingConfig):
    """Feed the samples; a window opens at 1.9 s with ``peaks`` as the bursts measured so far.
    Returns (onset, the time of the sample that returned it)."""
    timing = StrikeTiming(cfg)
    for tk, ak in zip(t, a, strict=True):
        timing.sample(float(tk), ak)
        if abs(tk - 1.9) < 0.5 / RATE_HZ:
            timing.peaks.extend(peaks)
            timing.arm(0, close_at_s=2.4, raw_s=2.0, calibrated_s=2.0)
        if timing.window is not None and tk > 1.9:
            onset = timing.poll()
            if onset is not None:
                return onset, float(tk)
    return math.nan, math.nan


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_an_onset_from_a_weak_typical_is_placed_on_the_shock_within_the_hold(seed):
    """Known answer: the onset at 30 % of this burst's own peak (the offline envelope over the
    same samples). Learned from one weak burst (the precursor's size) the threshold is crossed
    in the precursor, more than 50 ms early; held while the burst is followed, the onset lands
    within 10 ms of the known answer, returned no later than ``follow_s`` after the first
    rise."""
    cfg = StrikeTimingConfig()
    t, a = _accel(seed)
    env = envelope(t, a, cfg.impact)
    peak = float(env[t >= CONTACT_S].max())
    truth = first_rise(t, env, cfg.impact.threshold_fraction * peak, CONTACT_S - 0.05, 2.4)
    weak = float(env[(t >= PRE_S) & (t < CONTACT_S)].max())
    early = first_rise(t, env, cfg.impact.threshold_fraction * weak, 1.95, 2.4)
    assert truth - early > 0.05  # the weak threshold is crossed in the precursor
    onset, at = _run(t, a, [weak], cfg)
    assert abs(onset - truth) < 0.01
    assert at - early <= cfg.follow_s + 1.0 / RATE_HZ
    # without the hold (a typical taken as settled after one burst) the onset is early
    unheld, at_once = _run(t, a, [weak], StrikeTimingConfig(settle_bursts=1))
    assert truth - unheld > 0.05 and at_once - unheld < 0.02


def test_a_settled_typical_returns_the_onset_at_once():
    """Three bursts of the shock's size measured: the threshold is the walk's, the onset comes
    at the sample after its rise (nothing held) and is where the held one lands."""
    cfg = StrikeTimingConfig()
    t, a = _accel(0)
    env = envelope(t, a, cfg.impact)
    peak = float(env[t >= CONTACT_S].max())
    onset, at = _run(t, a, [peak] * 3, cfg)
    assert 0.0 <= at - onset < 1.0 / RATE_HZ + 1e-9
    held, _ = _run(t, a, [float(env[(t >= PRE_S) & (t < CONTACT_S)].max())], cfg)
    assert abs(onset - held) < 0.01


def test_floor_is_the_median_of_the_recent_envelope_at_every_sample():
    """The floor is kept between envelope samples (every 5th IMU sample): it must equal the
    median of the recent envelope whenever it is read, including after the buffer is full."""
    rng = np.random.default_rng(7)
    timing = StrikeTiming()
    for i in range(2200):  # past the 400-sample buffer (5 IMU samples each)
        accel = np.array([0.0, 0.0, 9.81]) + rng.normal(0.0, 0.5 + (i % 97 == 0) * 20.0, 3)
        timing.sample(i / 200.0, accel)
        if i % 3 == 0 and timing._envs:
            assert timing.floor == max(float(np.median(timing._envs)), 1e-12)

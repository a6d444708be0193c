"""The first strikes of a walk, emitted before the sensor's axis is learned: prompt, on the
shock of this leg's contact only, the same in any mounting, never while standing."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from kinematics.gait_events import match_events
from kinematics.gait_first_strike import FirstStrikes
from kinematics.gait_online import estimate_online
from kinematics.gait_patterns import PROSTHETIC_SIDE, SOUND_SIDE, shock
from kinematics.gait_real import rearranged, right_handed_arrangements
from kinematics.gait_scenarios import simulate_walks
from kinematics.gait_synth import random_mounting
from kinematics.imu import ImuSeries


def _first(imu: ImuSeries) -> list[tuple[float, float]]:
    fs = FirstStrikes()
    out = [
        fs.update(float(t), g, a)
        for t, g, a in zip(imu.t_s, imu.gyro_rad_s, imu.accel_m_s2, strict=True)
    ]
    return [x for x in out if x is not None]


@pytest.fixture(scope="module")
def walk():
    return simulate_walks(
        [[0.9] * 4], rate_hz=100.0, thigh_R_sensor=random_mounting(7), seed=7,
        pattern=PROSTHETIC_SIDE, stand_s=2.0,
    )  # fmt: skip


def test_the_first_strike_comes_out_within_100_ms(walk):
    res = estimate_online(walk.imu)
    assert res.counts["first_strikes"] >= 1 and res.counts["first_strikes_unconfirmed"] == 0
    strikes = res.times("foot_strike")
    err, missed, extra = match_events(strikes, walk.foot_strikes_s)
    assert (missed, extra) == (0, 0) and np.max(np.abs(err)) <= 0.030
    first = int(np.argmin(strikes))
    latency = res.times("foot_strike", detected=True)[first] - walk.foot_strikes_s[0]
    assert 0.0 < latency <= 0.100
    ((start, _),) = walk.walking_intervals_s
    assert all(e.detected_t_s > start for e in res.events)


def test_same_strikes_in_every_mounting(walk):
    base = _first(walk.imu)
    assert base
    for r in right_handed_arrangements()[::7]:
        other = _first(rearranged(walk.imu, r))
        assert len(other) == len(base)
        np.testing.assert_allclose(np.array(other), np.array(base), atol=2e-3)


def test_the_other_legs_shock_and_a_smooth_walk_give_none():
    """Shocks as strong as this leg's at the other leg's contacts (half a stride later) are not
    taken; a walk without shocks gives no first strike (the axis-learned path gives them)."""
    mount = random_mounting(9)
    sc = simulate_walks(
        [[1.0] * 5], rate_hz=200.0, thigh_R_sensor=mount, seed=9, pattern=SOUND_SIDE,
        stand_s=2.0,
    )  # fmt: skip
    other = sc.foot_strikes_s[:-1] + 0.5 * np.diff(sc.foot_strikes_s)
    other = np.concatenate([[sc.foot_strikes_s[0] - 0.5 * np.diff(sc.foot_strikes_s)[0]], other])
    extra = shock(sc.imu.t_s, other, SOUND_SIDE.impact_m_s2) @ mount  # thigh -> sensor frame
    imu = dataclasses.replace(sc.imu, accel_m_s2=sc.imu.accel_m_s2 + extra)
    found = np.array([s for s, _ in _first(imu)])
    assert found.size >= 3
    assert np.min(np.abs(found[:, None] - sc.foot_strikes_s[None, :]), axis=1).max() < 0.03
    smooth = simulate_walks(
        [[1.0] * 3], rate_hz=100.0, thigh_R_sensor=mount, seed=9,
        pattern=dataclasses.replace(SOUND_SIDE, impact_m_s2=0.0), stand_s=2.0,
    )  # fmt: skip
    assert _first(smooth.imu) == []


def test_none_while_standing_or_without_a_standing_start():
    sc = simulate_walks([], stand_s=20.0, rate_hz=100.0, seed=2)
    bump = np.zeros_like(sc.imu.accel_m_s2)
    bump[:, 2] = shock(sc.imu.t_s, np.arange(2.0, 19.0, 1.5), 30.0)[:, 2]  # knocks on the sensor
    assert _first(dataclasses.replace(sc.imu, accel_m_s2=sc.imu.accel_m_s2 + bump)) == []
    walk = simulate_walks([[1.0] * 4], rate_hz=100.0, seed=3, pattern=PROSTHETIC_SIDE, stand_s=2.0)
    moving = walk.imu.t_s > walk.walking_intervals_s[0][0] + 0.1
    cut = ImuSeries(walk.imu.t_s[moving], walk.imu.gyro_rad_s[moving], walk.imu.accel_m_s2[moving])
    assert _first(cut) == []  # no standing posture seen: nothing (the learned axis decides)

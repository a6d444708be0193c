"""Prosthetic gait in the synthetic generator, and both detectors on it in every kind of
mounting: the heel-strike shock, the strike bias learned online, the sign that cannot flip."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from kinematics.gait_curves import stance_fraction
from kinematics.gait_events import detect_from_thigh_imu, match_events
from kinematics.gait_impact import ImpactEnvelope, envelope
from kinematics.gait_online import estimate_online
from kinematics.gait_patterns import PROSTHETIC_SIDE, SOUND_SIDE, knee_angle
from kinematics.gait_phase_metrics import score_online
from kinematics.gait_real import right_handed_arrangements
from kinematics.gait_scenarios import simulate_walks
from kinematics.gait_synth import random_mounting
from kinematics.thigh_attitude import flipped

TREADMILL = dataclasses.replace(PROSTHETIC_SIDE, treadmill=True)


def test_pattern_moves_the_toe_off_smoothly_and_keeps_the_knee_stiff_in_stance():
    phase = np.linspace(0, 1, 2001)
    for pattern in (PROSTHETIC_SIDE, SOUND_SIDE):
        warped = pattern.warp(phase[:-1], 1.0)
        assert np.all(np.diff(warped) > 0)  # monotonic
        assert pattern.warp(np.array([pattern.stance(1.0)]), 1.0)[0] == pytest.approx(
            stance_fraction(1.0), abs=1e-9
        )
        # no kink: the second difference of the thigh angle stays small everywhere
        theta = pattern.thigh(phase, 1.0)
        assert np.max(np.abs(np.diff(theta, 2))) < 5e-5
    knee = knee_angle(PROSTHETIC_SIDE, phase, 1.0)
    stance = phase < PROSTHETIC_SIDE.stance(1.0)
    assert knee[stance].max() < np.radians(5.0) < np.radians(35.0) < knee[~stance].max()


def test_impact_envelope_is_causal_and_sees_only_the_shock():
    sc = simulate_walks([[1.0] * 3], rate_hz=200.0, seed=1, pattern=PROSTHETIC_SIDE)
    env = envelope(sc.imu.t_s, sc.imu.accel_m_s2)
    one = ImpactEnvelope()
    n = env.size // 2
    prefix = [one.update(t, a) for t, a in zip(sc.imu.t_s[:n], sc.imu.accel_m_s2[:n], strict=True)]
    np.testing.assert_array_equal(prefix, env[:n])
    quiet = np.median(env)
    bursts = []
    for ts in sc.foot_strikes_s:  # a burst right after each strike, far less near toe-off
        near = (sc.imu.t_s > ts) & (sc.imu.t_s < ts + 0.1)
        bursts.append(env[near].max())
    assert min(bursts) > 100 * quiet
    for to in sc.toe_offs_s:
        near = np.abs(sc.imu.t_s - to) < 0.1
        assert env[near].max() < min(bursts) / 10


@pytest.fixture(scope="module", params=range(0, 24, 5))
def prosthetic_walk(request):
    """Prosthetic-side walks in right-handed axis arrangements (with flipped axes), one with a
    random rotation on top; overground and on a treadmill; 100 and 200 Hz."""
    k = request.param
    mount = right_handed_arrangements()[k]
    if k % 2:
        mount = mount @ random_mounting(k)
    pattern = TREADMILL if k % 10 == 0 else PROSTHETIC_SIDE
    return simulate_walks(
        [[0.8 + 0.05 * (k % 5)] * 6],
        rate_hz=100.0 if k % 3 else 200.0,
        thigh_R_sensor=mount,
        seed=k,
        pattern=pattern,
        stand_s=2.0,
    )


def _check(strikes, truth, walking):
    err, missed, extra = match_events(strikes, truth)
    assert (missed, extra) == (0, 0)
    assert np.median(np.abs(err)) <= 0.030 and np.max(np.abs(err)) <= 0.060, err
    ((start, end),) = walking
    assert np.all((strikes > start) & (strikes < end))  # none while standing


def test_offline_on_prosthetic_gait(prosthetic_walk):
    sc = prosthetic_walk
    ev = detect_from_thigh_imu(sc.imu)
    _check(ev.foot_strikes_s, sc.foot_strikes_s, sc.walking_intervals_s)
    assert ev.details["impact_strikes"] >= 5


def test_online_on_prosthetic_gait(prosthetic_walk):
    sc = prosthetic_walk
    res = estimate_online(sc.imu)
    _check(res.times("foot_strike"), sc.foot_strikes_s, sc.walking_intervals_s)
    score = score_online(res, sc.foot_strikes_s, sc.toe_offs_s)
    assert np.max(score.foot_strike.latencies_s) <= 0.100  # the first too (its shock)
    assert score.phase_rmse_cyc <= 0.05  # 6 strides (2.5-3.0 %): the first one after the lock too
    assert res.counts["impact_strikes"] >= 3 and res.counts["axis_flipped"] == 0


def test_a_wrong_sign_is_found_and_flipped_after_a_few_strides():
    """Start the estimator with the axis the wrong way round (strikes and toe-offs swapped):
    the bursts fall at its toe-offs, it flips the axis, says so, and the later strikes are
    right."""
    sc = simulate_walks(
        [[1.0] * 10], rate_hz=100.0, thigh_R_sensor=random_mounting(3), seed=3,
        pattern=PROSTHETIC_SIDE, stand_s=2.0,
    )  # fmt: skip
    learned = estimate_online(sc.imu).sagittal_axis
    assert learned is not None
    res = estimate_online(sc.imu, sagittal_axis=flipped(learned))
    assert res.counts["axis_flipped"] == 1 and res.counts["sign_disagreement"] == 1
    late = sc.foot_strikes_s[-3:]  # the last three strides, after the flip
    strikes = res.times("foot_strike")
    err, missed, extra = match_events(strikes[strikes > late[0] - 0.3], late)
    assert (missed, extra) == (0, 0) and np.max(np.abs(err)) <= 0.060
    assert res.sagittal_axis.axis @ learned.axis > 0.99


def test_sound_side_longer_stance_and_the_strike_bias_is_kept_without_impacts():
    sc = simulate_walks(
        [[0.9] * 8], rate_hz=100.0, thigh_R_sensor=random_mounting(5), seed=5,
        pattern=dataclasses.replace(SOUND_SIDE, treadmill=True), stand_s=2.0,
    )  # fmt: skip
    res = estimate_online(sc.imu)
    _check(res.times("foot_strike"), sc.foot_strikes_s, sc.walking_intervals_s)
    # the same walk without shocks after the fourth strike: the bias learned is kept
    cut = sc.foot_strikes_s[3] + 0.3
    smooth = simulate_walks(
        [[0.9] * 8], rate_hz=100.0, thigh_R_sensor=random_mounting(5), seed=5,
        pattern=dataclasses.replace(SOUND_SIDE, treadmill=True, impact_m_s2=0.0), stand_s=2.0,
    )  # fmt: skip
    accel = np.where((sc.imu.t_s > cut)[:, None], smooth.imu.accel_m_s2, sc.imu.accel_m_s2)
    mixed = dataclasses.replace(sc.imu, accel_m_s2=accel)
    res2 = estimate_online(mixed)
    err, missed, extra = match_events(res2.times("foot_strike"), sc.foot_strikes_s)
    assert (missed, extra) == (0, 0) and np.max(np.abs(err)) <= 0.060


def test_load_cell_defines_the_strikes_and_its_bias_outlives_it():
    """No shock in the accelerometer (a soft prosthetic foot): the load cell gives the strikes,
    the IMU learns its strike bias from them, and keeps it when the load cell is lost."""
    sc = simulate_walks(
        [[0.9] * 10], rate_hz=100.0, thigh_R_sensor=random_mounting(4), seed=4,
        pattern=dataclasses.replace(TREADMILL, impact_m_s2=0.0), stand_s=2.0,
    )  # fmt: skip
    cut = sc.foot_strikes_s[5] + 0.3
    load = np.where(sc.imu.t_s > cut, np.nan, sc.load_n)
    res = estimate_online(sc.imu, load_n=load, knee_rad=sc.knee_rad)
    assert res.counts["load_cell_strikes"] >= 4
    strikes = res.times("foot_strike")
    before = sc.foot_strikes_s[sc.foot_strikes_s < cut]
    err, _, _ = match_events(strikes[strikes < cut], before)
    assert np.max(np.abs(err)) <= 0.015  # the load cell's own events
    after = sc.foot_strikes_s[sc.foot_strikes_s > cut]
    err_kept, missed, extra = match_events(strikes[strikes > cut], after)
    assert (missed, extra) == (0, 0)
    imu_only = estimate_online(sc.imu).times("foot_strike")
    err_raw, _, _ = match_events(imu_only[imu_only > cut], after)
    # the calibration kept: the IMU's strikes after the loss are better than without it
    assert np.median(np.abs(err_kept)) < 0.5 * np.median(np.abs(err_raw))
    assert np.max(np.abs(err_kept)) <= 0.030


def test_knee_encoder_flips_a_wrong_sign_without_impacts():
    sc = simulate_walks(
        [[0.9] * 8], rate_hz=100.0, thigh_R_sensor=random_mounting(6), seed=6,
        pattern=dataclasses.replace(PROSTHETIC_SIDE, impact_m_s2=0.0), stand_s=2.0,
    )  # fmt: skip
    learned = estimate_online(sc.imu).sagittal_axis
    res = estimate_online(sc.imu, sagittal_axis=flipped(learned), knee_rad=sc.knee_rad)
    assert res.counts["axis_flipped"] == 1 and res.counts["sign_disagreement"] == 1
    assert res.sagittal_axis.axis @ learned.axis > 0.99
    strikes = res.times("foot_strike")
    err, missed, _ = match_events(
        strikes[strikes > 6.0], sc.foot_strikes_s[sc.foot_strikes_s > 6.0]
    )
    assert missed == 0 and np.max(np.abs(err)) <= 0.060


@pytest.mark.parametrize("rate_hz", [100.0, 250.0])
def test_a_long_standing_start_changes_nothing(rate_hz):
    """The axis learner's buffer (8 s) filled with a standing start is not a reason to fix the
    axis from the first partial swing: a walk after 11 s of standing (a treadmill trial's quiet
    start) gives the same strikes, relative to its start, as after 3 s, and its phase within 3 %
    (before, the axis was fixed at the first swing: the first strike was missed and the phase
    RMSE was 5-6 %)."""
    out = []
    for stand_s in (3.0, 11.0):
        sc = simulate_walks(
            [[0.9] * 8], rate_hz=rate_hz, thigh_R_sensor=right_handed_arrangements()[5],
            seed=200, pattern=PROSTHETIC_SIDE, stand_s=stand_s,
        )  # fmt: skip
        res = estimate_online(sc.imu)
        _check(res.times("foot_strike"), sc.foot_strikes_s, sc.walking_intervals_s)
        score = score_online(res, sc.foot_strikes_s, sc.toe_offs_s)
        assert score.phase_rmse_cyc <= 0.03, stand_s
        out.append(res.times("foot_strike") - stand_s)
    np.testing.assert_allclose(out[1], out[0], atol=0.002)


@pytest.mark.parametrize("rate_hz", [100.0, 250.0])
def test_a_slow_prosthetic_walk_gets_a_phase(rate_hz):
    """At 0.6 m/s the prosthesis side's thigh swings at 1.2 rad/s at most (reduced swing
    flexion): the axis learner still fixes its axis, so the walk has a phase and toe-offs, not
    only the strikes from the shock (before, the axis needed a 1.2 rad/s peak: no phase at
    all)."""
    sc = simulate_walks(
        [[0.6] * 10], rate_hz=rate_hz, thigh_R_sensor=right_handed_arrangements()[7],
        seed=300, pattern=TREADMILL, stand_s=3.0,
    )  # fmt: skip
    res = estimate_online(sc.imu)
    _check(res.times("foot_strike"), sc.foot_strikes_s, sc.walking_intervals_s)
    score = score_online(res, sc.foot_strikes_s, sc.toe_offs_s)
    assert score.phase_scored_fraction >= 0.85
    assert score.phase_rmse_cyc <= 0.03
    assert score.toe_off.missed == 0 and score.toe_off.extra == 0

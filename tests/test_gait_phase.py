"""Online gait phase from a thigh IMU (kinematics.gait_phase): Jacobian, causality, standing,
stop-and-go, speed change, malformed streams and known-answer accuracy on simulated walking."""

from __future__ import annotations

import math

import numpy as np
import pytest

from kinematics.errors import GaitInputError
from kinematics.gait_online import estimate_online
from kinematics.gait_phase import OnlineGaitEstimator
from kinematics.gait_phase_metrics import reference_phase, score_online
from kinematics.gait_scenarios import simulate_walks, speed_change
from kinematics.gait_synth import random_mounting, thigh_imu_from_reference
from kinematics.imu import ImuSeries
from kinematics.phase_model import measurement, measurement_jacobian, phase_reference


def test_measurement_jacobian_matches_numerical_derivative():
    ref = phase_reference()
    rng = np.random.default_rng(0)
    for _ in range(20):
        x = np.array([rng.uniform(-1, 3), rng.uniform(0.5, 1.2)])
        a, b = ref.coefficients(float(x[1]))
        h = 1e-6
        num = np.column_stack(
            [
                (measurement(x + h * e, a, b) - measurement(x - h * e, a, b)) / (2 * h)
                for e in np.eye(2)
            ]
        )
        np.testing.assert_allclose(measurement_jacobian(x, a, b), num, rtol=1e-6, atol=1e-6)


def test_reference_is_normalised_and_periodic():
    ref = phase_reference()
    a, b = ref.coefficients(0.9)
    phase = np.arange(256) / 256
    c = np.array([measurement(np.array([p, 1.0]), a, b)[0] for p in phase])
    assert abs(c.mean()) < 1e-9
    assert c.std() == pytest.approx(1.0, rel=0.01)
    np.testing.assert_allclose(
        measurement(np.array([0.3, 1.0]), a, b), measurement(np.array([2.3, 1.0]), a, b)
    )


@pytest.fixture(scope="module")
def walk():
    return thigh_imu_from_reference(
        1.2, n_strides=5, rate_hz=100.0, thigh_R_sensor=random_mounting(7), seed=7
    )


def test_sample_at_a_time_equals_batch_and_prefix_is_unchanged(walk):
    """Causality: the batch helper equals one update per sample, and the output on a prefix of
    the stream equals the same prefix of the output on the whole stream."""
    imu = walk.imu
    full = estimate_online(imu)
    est = OnlineGaitEstimator()
    phases = []
    for t, g, a in zip(imu.t_s, imu.gyro_rad_s, imu.accel_m_s2, strict=True):
        est.update(t, g, a)
        phases.append(est.state.phase_cyc)
    np.testing.assert_array_equal(np.asarray(phases), full.phase_cyc)
    assert [e.t_s for e in est.events] == [e.t_s for e in full.events]
    n = imu.t_s.size * 2 // 3
    prefix = estimate_online(ImuSeries(imu.t_s[:n], imu.gyro_rad_s[:n], imu.accel_m_s2[:n]))
    np.testing.assert_array_equal(prefix.phase_cyc, full.phase_cyc[:n])
    assert [e.t_s for e in prefix.events] == [
        e.t_s for e in full.events if e.detected_t_s <= imu.t_s[n - 1]
    ]


@pytest.mark.parametrize("speed", [0.6, 1.2, 1.8])
def test_known_answer_simulated_walking(speed):
    sim = thigh_imu_from_reference(
        speed, n_strides=6, rate_hz=100.0, thigh_R_sensor=random_mounting(20), seed=20
    )
    res = estimate_online(sim.imu)
    score = score_online(res, sim.foot_strikes_s, sim.toe_offs_s)
    assert score.foot_strike.missed == 0 and score.foot_strike.extra == 0
    assert score.toe_off.extra == 0 and score.toe_off.missed <= 1
    assert np.max(np.abs(score.foot_strike.errors_s)) < 0.040
    assert np.max(np.abs(score.toe_off.errors_s)) < 0.060
    # after the first strike (the first may be emitted when the axis is fixed, late)
    assert np.max(score.foot_strike.latencies_s[1:]) < 0.060
    assert score.phase_rmse_cyc < 0.05


def test_speed_change_slow_to_fast_within_three_strides():
    sc = simulate_walks(
        [speed_change(0.7, 1.6, 10)], rate_hz=100.0, thigh_R_sensor=random_mounting(31), seed=31
    )
    res = estimate_online(sc.imu)
    score = score_online(res, sc.foot_strikes_s, sc.toe_offs_s)
    assert score.foot_strike.missed == 0 and score.foot_strike.extra == 0
    assert score.toe_off.missed == 0 and score.toe_off.extra == 0
    assert np.max(np.abs(score.foot_strike.errors_s)) < 0.030
    assert np.max(np.abs(score.toe_off.errors_s)) < 0.060
    assert score.phase_rmse_cyc < 0.05


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_standing_sixty_seconds_gives_no_events(seed):
    sc = simulate_walks(
        [], stand_s=60.0, rate_hz=100.0, thigh_R_sensor=random_mounting(seed), seed=seed
    )
    res = estimate_online(sc.imu)
    assert res.events == []
    assert np.all(np.isnan(res.phase_cyc))


def test_stop_and_go_no_events_while_standing_and_clean_restart():
    sc = simulate_walks(
        [[1.0] * 4, [1.4] * 4],
        stand_s=4.0,
        rate_hz=100.0,
        thigh_R_sensor=random_mounting(5),
        seed=5,
    )
    res = estimate_online(sc.imu)
    times = np.array([e.detected_t_s for e in res.events])
    walking = np.zeros(times.size, dtype=bool)
    for start, end in sc.walking_intervals_s:
        walking |= (times >= start) & (times <= end + 0.05)
    assert walking.all(), times[~walking]
    score = score_online(res, sc.foot_strikes_s, sc.toe_offs_s)
    assert score.foot_strike.missed == 0 and score.foot_strike.extra == 0
    # the phase is frozen (NaN, no advance) in the middle of each standing period
    (_, e0), (s1, _) = sc.walking_intervals_s
    mid = (res.t_s > e0 + 1.0) & (res.t_s < s1 - 0.5)
    assert np.all(np.isnan(res.phase_cyc[mid]))


def _corrupt(imu: ImuSeries, kind: str) -> ImuSeries:
    t, g, a = imu.t_s.copy(), imu.gyro_rad_s.copy(), imu.accel_m_s2.copy()
    k = np.searchsorted(t, 6.0)
    if kind == "nan":
        g[k : k + 5] = np.nan
    elif kind == "saturation":
        g[k : k + 5, 0] = 34.9  # at full scale (2000 deg/s)
    elif kind == "gap":
        keep = np.ones(t.size, dtype=bool)
        keep[k : k + 20] = False
        t, g, a = t[keep], g[keep], a[keep]
    return ImuSeries(t, g, a, f"<{kind}>")


@pytest.mark.parametrize(
    "kind,counter", [("nan", "nonfinite"), ("saturation", "saturated"), ("gap", "gaps")]
)
def test_malformed_stream_is_counted_and_flagged_never_a_silent_jump(walk, kind, counter):
    res = estimate_online(_corrupt(walk.imu, kind))
    assert res.counts[counter] >= 1
    assert np.count_nonzero(res.flags) >= 1
    # every phase step larger than the jump bound is a flagged sample (or a re-acquisition)
    ph = np.unwrap(res.phase_cyc * 2 * math.pi) / (2 * math.pi)
    step = np.abs(np.diff(ph))
    big = np.flatnonzero(step > 0.08) + 1
    assert all(res.flags[i] != 0 for i in big)
    score = score_online(res, walk.foot_strikes_s, walk.toe_offs_s)
    assert score.foot_strike.extra == 0


def test_time_going_backwards_is_an_error():
    est = OnlineGaitEstimator()
    est.update(0.0, np.zeros(3), np.array([0, 0, 9.81]))
    with pytest.raises(GaitInputError, match="t_s"):
        est.update(-0.01, np.zeros(3), np.array([0, 0, 9.81]))


def test_reference_phase_is_linear_between_strikes_and_nan_across_standing():
    t = np.array([0.5, 1.0, 1.5, 2.0, 5.0, 9.0])
    ph = reference_phase(t, np.array([1.0, 2.0, 8.0]))
    np.testing.assert_allclose(ph[1:3], [0.0, 0.5])
    assert np.isnan(ph[0]) and np.isnan(ph[4]) and np.isnan(ph[5])


def test_angle_offset_is_the_mean_over_the_last_complete_stride():
    """The phase EKF's angle offset and scale come from the last stride strike to strike: a
    window of the last stride's length ending now would cover 1/1.3 of a longer stride's cycle
    here (mean 0.155 rad instead of 0.100)."""
    est = OnlineGaitEstimator()
    est._stride_s, est._last_event_t["foot_strike"] = 1.0, 2.0
    dt = 0.01
    for t in np.arange(0.0, 3.0 + dt / 2, dt):
        period, t0 = (1.0, 0.0) if t < 2.0 else (1.3, 2.0)
        est._track_norm(0.1 + 0.3 * math.sin(2 * math.pi * (t - t0) / period), dt, float(t))
    mean, scale = est._norm
    assert mean == pytest.approx(0.100, abs=0.004)
    assert scale == pytest.approx(0.3 / math.sqrt(2), abs=0.005)


def test_a_short_gap_is_bridged_and_a_long_one_drops_the_lock(walk):
    """A gap up to ``max_bridge_s`` (lost packets of a wireless sensor) is counted, flagged and
    predicted through: no re-acquisition, the same strikes; a longer one drops the lock."""
    clean = estimate_online(walk.imu)
    t, g, a = walk.imu.t_s, walk.imu.gyro_rad_s, walk.imu.accel_m_s2
    k = int(np.searchsorted(t, 6.0))
    out = {}
    for n in (8, 20):  # 90 ms and 210 ms at 100 Hz
        keep = np.ones(t.size, dtype=bool)
        keep[k : k + n] = False
        out[n] = estimate_online(ImuSeries(t[keep], g[keep], a[keep]))
        assert out[n].counts["gaps"] == 1
    assert out[8].counts["reacquired"] == clean.counts["reacquired"]
    np.testing.assert_allclose(out[8].times("foot_strike"), clean.times("foot_strike"), atol=0.011)
    sc, sc_clean = (score_online(r, walk.foot_strikes_s, walk.toe_offs_s) for r in (out[8], clean))
    assert abs(sc.phase_rmse_cyc - sc_clean.phase_rmse_cyc) < 0.005
    assert out[20].counts["reacquired"] > clean.counts["reacquired"]

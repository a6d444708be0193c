"""The contact reference derived from two thighs of one walk, and the offline onset search that
reaches past a template strike placed before the shock. Known answers on constructed signals;
the OpenSense femur walks (skipped when the shared data is absent)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import REAL_THIGH_IMU
from scipy.spatial.transform import Rotation

from kinematics.gait_curves import stride_time_s, thigh_angle
from kinematics.gait_impact import ImpactConfig, refine_strikes
from kinematics.gait_two_legs import (
    Leg,
    TwoLegConfig,
    derive_strikes,
    physical_checks,
    score_against,
    thigh_inclination_rad,
)

DATA = REAL_THIGH_IMU
RATE_HZ = 100.0
LAG_S = ImpactConfig().lag_s


def _burst(t: np.ndarray, onset_s: float, peak: float) -> np.ndarray:
    """An envelope burst whose rise crosses every fraction of its peak at ``onset_s``
    (to the sample), decaying over 60 ms."""
    e = np.zeros_like(t)
    after = t >= onset_s
    e[after] = peak * np.exp(-(t[after] - onset_s) / 0.06)
    return e


def _two_legs(strides: int = 8, speed: float = 1.2, early_bump_s: float | None = None):
    """Two thighs half a cycle apart following the reference thigh curve; each leg's shock
    (peak 3) rises ``LAG_S`` after its strike, felt in the other thigh at 0.1 of it."""
    period = stride_time_s(speed)
    t = np.arange(0.0, (strides + 1) * period, 1.0 / RATE_HZ)
    right_strikes = period * np.arange(1, strides + 1) - period / 2
    left_strikes = right_strikes + period / 2
    angle = {
        "R": thigh_angle(np.mod((t - right_strikes[0]) / period, 1.0), speed),
        "L": thigh_angle(np.mod((t - left_strikes[0]) / period, 1.0), speed),
    }
    env = {"R": np.full_like(t, 1e-3), "L": np.full_like(t, 1e-3)}
    for side, other, strikes in (("R", "L", right_strikes), ("L", "R", left_strikes)):
        for s in strikes:
            env[side] += _burst(t, s + LAG_S, 3.0)
            env[other] += _burst(t, s + LAG_S, 0.3)
    if early_bump_s is not None:
        s = right_strikes[3]
        env["R"] += _burst(t, s + LAG_S - early_bump_s, 0.5)
    legs = {k: Leg(t, angle[k], env[k]) for k in ("R", "L")}
    return legs, right_strikes, left_strikes


def test_derived_strikes_known_answer_and_the_other_legs_shock_is_not_taken():
    legs, right, left = _two_legs()
    for own, other, truth in (("R", "L", right), ("L", "R", left)):
        ref = derive_strikes(legs[own], legs[other])
        # each strike of a stride with a flexion peak before it (the first may have none)
        matched = [np.min(np.abs(ref.strikes_s - s)) for s in truth[1:]]
        assert max(matched) <= 1.0 / RATE_HZ + 1e-9
        # the other leg's shock (0.1 of this leg's, half a stride later) is not a strike
        assert ref.strikes_s.size <= truth.size
        assert np.all(np.diff(ref.strikes_s) > 0.8 * stride_time_s(1.2))
        assert not np.any(ref.ambiguous_s)
        assert ref.uncertainty_s == pytest.approx(math.hypot(0.006, 0.01 / math.sqrt(12)))


def test_flipped_inclination_sense_gives_the_same_strikes():
    legs, _, _ = _two_legs()
    flipped = Leg(legs["R"].t_s, -legs["R"].inclination_rad + 0.3, legs["R"].envelope)
    a = derive_strikes(legs["R"], legs["L"]).strikes_s
    b = derive_strikes(flipped, legs["L"]).strikes_s
    np.testing.assert_allclose(a, b)


def test_an_earlier_smaller_burst_makes_the_strike_ambiguous_by_its_gap():
    legs, right, _ = _two_legs(early_bump_s=0.1)
    ref = derive_strikes(legs["R"], legs["L"])
    k = int(np.argmin(np.abs(ref.strikes_s - right[3])))
    assert ref.ambiguous_s[k] == pytest.approx(0.1, abs=0.011)
    assert np.count_nonzero(ref.ambiguous_s) == 1
    # a strike at the earlier burst scores 0, one 50 ms before that scores -50 ms
    at_bump = ref.strikes_s.copy()
    at_bump[k] -= 0.1
    assert np.all(np.abs(score_against(at_bump, ref).errors_s) < 0.011)
    early = ref.strikes_s.copy()
    early[k] -= 0.15
    assert score_against(early, ref).errors_s[k] == pytest.approx(-0.05, abs=0.011)


def test_a_stride_without_a_shock_is_unreferenced_not_missed():
    legs, right, _ = _two_legs()
    # silence the burst of one right strike: its stride has no reference
    e = legs["R"].envelope.copy()
    quiet = (legs["R"].t_s > right[4] - 0.05) & (legs["R"].t_s < right[4] + 0.4)
    e[quiet] = 1e-3
    own = Leg(legs["R"].t_s, legs["R"].inclination_rad, e)
    ref = derive_strikes(own, legs["L"])
    assert not np.any(np.abs(ref.strikes_s - right[4]) < 0.1)
    spans = ref.unreferenced_s
    assert np.any((spans[:, 0] < right[4]) & (spans[:, 1] > right[4]))
    sc = score_against(right, ref)
    assert sc.missed == 0 and sc.extra == 0 and sc.unscored >= 1
    # a strike 0.2 s late is matched with its error, one 0.3 s late is missed and extra
    late = np.sort(ref.strikes_s.copy())
    late[2] += 0.2
    assert score_against(late, ref).errors_s[2] == pytest.approx(0.2)
    late[2] += 0.1
    sc = score_against(late, ref)
    assert sc.missed == 1 and sc.extra == 1


def test_physical_checks_reject_strikes_before_the_flexion_peak():
    legs, right, _ = _two_legs()
    good = physical_checks(right[1:], legs["R"], legs["L"])
    assert good.after_flexion == good.before_other_extension == right.size - 1
    # at mid-swing (0.3 stride before the strike) the thigh has not reached its peak yet:
    # the last flexion peak is a whole stride back
    early = physical_checks(right[2:] - 0.3 * stride_time_s(1.2), legs["R"], legs["L"])
    assert early.after_flexion == 0


def test_thigh_inclination_known_answer():
    # a thigh swinging ±25° about the sensor's z axis; its long axis is the sensor's x
    # (gravity along it at rest), the walk heading 40° off the global x
    t = np.arange(0.0, 6.0, 1.0 / RATE_HZ)
    theta = np.radians(25.0) * np.sin(2 * np.pi * t / 1.2)
    heading = Rotation.from_euler("z", np.radians(40.0))
    global_R_sensor = np.stack(
        [
            (
                heading
                * Rotation.from_euler("x", np.pi / 2)
                * Rotation.from_euler("y", -np.pi / 2)
                * Rotation.from_euler("z", th)
            ).as_matrix()
            for th in theta
        ]
    )
    up_sensor = global_R_sensor[:, 2, :]
    accel = 9.81 * up_sensor  # specific force at rest: up
    rate = 2 * np.pi / 1.2 * np.radians(25.0) * np.cos(2 * np.pi * t / 1.2)
    gyro = np.column_stack([np.zeros_like(t), np.zeros_like(t), rate])
    got = thigh_inclination_rad(global_R_sensor, accel, gyro)
    got -= np.mean(got)
    sign = np.sign(np.dot(got, theta))
    np.testing.assert_allclose(sign * got, theta - theta.mean(), atol=np.radians(0.5))


def test_offline_onset_found_past_a_template_strike_placed_before_the_shock():
    t = np.arange(0.0, 12.0, 1.0 / RATE_HZ)
    truth = np.arange(1.0, 11.0, 1.2)
    env = np.full_like(t, 1e-3)
    for s in truth:
        env += _burst(t, s + LAG_S, 3.0)
    # the template places each strike 0.25-0.35 s before the contact
    rng = np.random.default_rng(7)
    model = truth - rng.uniform(0.25, 0.35, truth.size)
    out = refine_strikes(t, env, model)
    assert out.from_impact == truth.size
    np.testing.assert_allclose(out.strikes_s, truth, atol=1.0 / RATE_HZ + 1e-9)
    # a template strike after its contact (within the usual window) is unchanged in rule
    late = refine_strikes(t, env, truth + 0.05)
    np.testing.assert_allclose(late.strikes_s, truth, atol=1.0 / RATE_HZ + 1e-9)


@pytest.mark.skipif(not (DATA / "00B4227C.txt").exists(), reason="shared real walks absent")
def test_offline_strikes_on_the_femur_walks_against_the_derived_reference():
    from kinematics.gait_events import detect_from_thigh_imu
    from kinematics.gait_impact import envelope
    from kinematics.gait_real import read_xsens_orientation, read_xsens_txt

    legs, imus = {}, {}
    for name in ("00B4227C.txt", "00B421EE.txt"):
        imu = read_xsens_txt(DATA / name)
        t, global_R_sensor = read_xsens_orientation(DATA / name)
        np.testing.assert_allclose(t, imu.t_s)
        incl = thigh_inclination_rad(global_R_sensor, imu.accel_m_s2, imu.gyro_rad_s)
        legs[name], imus[name] = Leg(t, incl, envelope(t, imu.accel_m_s2)), imu
    names = list(legs)
    for own, other in (names, names[::-1]):
        ref = derive_strikes(legs[own], legs[other], TwoLegConfig())
        assert ref.strikes_s.size >= 9  # of 12 strides with a flexion peak
        strikes = detect_from_thigh_imu(imus[own]).foot_strikes_s
        sc = score_against(strikes, ref)
        assert sc.missed == 0 and sc.extra == 0
        assert np.median(np.abs(sc.errors_s)) <= 0.03
        assert np.max(np.abs(sc.errors_s)) <= 0.06
        checks = physical_checks(strikes, legs[own], legs[other])
        assert checks.after_flexion >= checks.strikes - 1  # the walk's first: no peak before

"""The heel-contact burst of the simulated thigh IMU: its size and timing, zero net velocity and
displacement, and the online strike detector placing strikes on it."""

from __future__ import annotations

import numpy as np

from graph_slam.sim.config import MotionConfig, SimConfig
from graph_slam.sim.heel_shock import SPAN_S, heel_shock_accel, heel_shock_displacement_m
from graph_slam.sim.motion import GaitMotion
from graph_slam.sim.recording import prepare
from graph_slam.sim.sensors import simulate_imu
from kinematics.gait_events import match_events
from kinematics.gait_online import estimate_online
from kinematics.leg_model import LegModel


def test_the_burst_peaks_at_its_amplitude_and_integrates_to_nothing():
    t = np.arange(-0.05, 0.5, 1e-4)
    a = heel_shock_accel(t, np.array([0.0]), 15.0)
    assert abs(np.abs(a).max() - 15.0) < 0.05
    assert 0.02 < t[np.argmax(a)] < 0.045  # peaks 20-45 ms after contact, upward
    assert np.all(a[t < 0] == 0) and np.all(a[t > SPAN_S] == 0)
    v = np.cumsum(a) * 1e-4
    d = np.cumsum(v) * 1e-4
    assert abs(v[-1]) < 1e-5 and abs(d[-1]) < 1e-6  # m/s, m: nothing left after it
    disp = heel_shock_displacement_m(t, 15.0)
    assert np.abs(d - disp).max() < 2e-5  # the accelerations are those of that displacement
    assert np.abs(disp).max() < 1e-3  # the mount moves by under a millimetre
    assert not heel_shock_accel(t, np.array([0.0]), 0.0).any()


def test_the_imu_sees_it_along_the_thigh_at_each_heel_contact():
    thigh_T_imu = LegModel().thigh_T_frame("imu")
    with_shock = GaitMotion(1.1, 2, 3, cfg=MotionConfig(heel_shock_m_s2=15.0))
    without = GaitMotion(1.1, 2, 3, cfg=MotionConfig(heel_shock_m_s2=0.0))
    t = np.arange(0.0, with_shock.duration_s, 1e-3)
    g1, a1 = with_shock.imu_ideal(t, thigh_T_imu)
    g0, a0 = without.imu_ideal(t, thigh_T_imu)
    np.testing.assert_array_equal(g1, g0)  # a translation of the mount: no rotation
    diff = a1 - a0
    limb = thigh_T_imu[:3, :3].T @ np.array([0.0, 0.0, 1.0])
    assert np.abs(diff - np.outer(diff @ limb, limb)).max() < 1e-9
    for ts in with_shock.foot_strikes_s:
        near = (t >= ts) & (t < ts + 0.1)
        assert abs(np.abs(diff[near] @ limb).max() - 15.0) < 0.5


def test_online_strikes_on_a_simulated_session_sit_on_the_heel_contact():
    sim = prepare(SimConfig(speed_m_s=1.1, strides=4, seed=2))
    imu, _ = simulate_imu(sim.motion, sim.thigh_T_imu, sim.imu, np.random.default_rng([2, 3]))
    res = estimate_online(imu)
    err, missed, extra = match_events(res.times("foot_strike"), sim.motion.foot_strikes_s)
    assert (missed, extra) == (0, 0) and res.counts["impact_strikes"] >= 3
    assert abs(np.median(err)) <= 0.010 and np.abs(err).max() <= 0.030

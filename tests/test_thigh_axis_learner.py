"""The sagittal-axis learner (:class:`kinematics.thigh_attitude.SagittalAxisLearner`): when it
gives up waiting for a whole cycle does not depend on how long the wearer stood first."""

from __future__ import annotations

import numpy as np
import pytest

from kinematics.thigh_attitude import SagittalAxisLearner, ThighAttitudeConfig

RATE_HZ = 100.0
G = np.array([0.0, 0.0, 9.81])


def _feed(gyro_x: np.ndarray, stand_s: float, seed: int = 0):
    """``stand_s`` of quiet standing, then the given rate about the sensor's x axis; returns
    (time the axis was fixed, or None; time the motion started)."""
    rng = np.random.default_rng(seed)
    n0 = int(stand_s * RATE_HZ)
    wx = np.concatenate([np.zeros(n0), gyro_x])
    learner = SagittalAxisLearner()
    for k, w in enumerate(wx):
        gyro = np.array([w, 0.0, 0.0]) + rng.normal(0.0, 0.02, 3)
        axis = learner.add(k / RATE_HZ, gyro, G + rng.normal(0.0, 0.05, 3))
        if axis is not None:
            return axis, k / RATE_HZ, n0 / RATE_HZ
    return None, None, n0 / RATE_HZ


@pytest.mark.parametrize("stand_s", [1.0, 11.0])
def test_one_swing_after_a_long_stand_does_not_fix_the_axis(stand_s):
    """A single forward swing (2 rad/s peak) then standing again: no whole cycle, so no axis,
    however long the stand before it filled the 8 s buffer (it used to be fixed at once)."""
    t = np.arange(int(0.6 * RATE_HZ)) / RATE_HZ
    swing = np.concatenate([2.0 * np.sin(np.pi * t / 0.6), np.zeros(int(2.0 * RATE_HZ))])
    axis, _, _ = _feed(swing, stand_s)
    assert axis is None


@pytest.mark.parametrize("stand_s", [1.0, 3.0, 11.0])
def test_without_a_whole_cycle_the_axis_is_fixed_after_the_wait_of_motion(stand_s):
    """A symmetric oscillation (no flexion/extension asymmetry: never a whole gait cycle) is
    fixed once the buffer spans ``max_learn_s`` and the motion ``min_wait_moving_s``, however
    long the stand before it; the axis is the oscillation's."""
    cfg = ThighAttitudeConfig()
    t = np.arange(int(9.0 * RATE_HZ)) / RATE_HZ
    axis, fixed_s, start_s = _feed(2.0 * np.sin(2 * np.pi * t + 0.3), stand_s)
    assert axis is not None
    wait_s = max(0.99 * cfg.max_learn_s - stand_s, cfg.min_wait_moving_s)
    assert fixed_s - start_s == pytest.approx(wait_s, abs=0.05)
    assert abs(axis.axis[0]) > 0.99

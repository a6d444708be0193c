"""Stride start priors on hand-made states: carried covariances and their inflations, the
anchor's rotation of the velocity, the first stride's gravity alignment."""

from __future__ import annotations

import gtsam
import numpy as np

from graph_slam.backend import KinematicMeasurement
from graph_slam.backend.config import PriorConfig
from graph_slam.backend.stride_chain import carried_priors, first_stride_priors

PC = PriorConfig(carry_inflation=2.0, missed_strike_inflation=4.0, first_carry_inflation=10.0)
ROT = gtsam.Rot3.Rz(0.3)
PRED = gtsam.NavState(gtsam.Pose3(ROT, np.array([1.0, 2.0, 0.5])), np.array([1.0, 0.0, 0.0]))
COV_X = np.eye(6) * 1e-4
COV_V = np.diag([1.0, 2.0, 3.0]) * 1e-3
COV_B = np.eye(6) * 1e-6
BIAS = gtsam.imuBias.ConstantBias(np.array([0.1, 0, 0]), np.zeros(3))
ANCHOR = KinematicMeasurement(np.eye(4), np.eye(6) * 1e-5)  # camera = IMU here


def carried(reason, anchor=ANCHOR, unloaded_first=False):
    return carried_priors(
        PC, np.eye(4), reason, PRED, COV_X, COV_V, BIAS, COV_B, anchor, unloaded_first
    )


def test_foot_strike_with_anchor_rotates_velocity_into_the_new_frame():
    p = carried("foot_strike")
    new_R_old = ROT.matrix().T  # anchor orientation identity
    np.testing.assert_allclose(p.velocity_m_s, new_R_old @ [1.0, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(p.cov_velocity, new_R_old @ COV_V @ new_R_old.T * 2.0)
    np.testing.assert_allclose(p.cov_bias, COV_B * 2.0)
    np.testing.assert_allclose(p.cov_pose, ANCHOR.covariance)
    np.testing.assert_allclose(p.old_stride_T_imu, PRED.pose().matrix())  # world chains
    assert p.flags == []
    np.testing.assert_allclose(p.bias.vector(), BIAS.vector())


def test_inflations_first_unloaded_missed_and_no_anchor():
    p = carried("foot_strike", unloaded_first=True)  # out of a first stride begun in the air
    np.testing.assert_allclose(p.cov_bias, COV_B * 20.0)
    p = carried("missed_foot_strike")  # continue in the old frame
    assert p.old_stride_T_imu is None and p.flags == []
    np.testing.assert_allclose(p.stride_T_imu.matrix(), PRED.pose().matrix())
    np.testing.assert_allclose(p.cov_pose, COV_X * 4.0)
    np.testing.assert_allclose(p.cov_velocity, COV_V * 4.0)
    p = carried("missed_foot_strike", unloaded_first=True)
    np.testing.assert_allclose(p.cov_pose, COV_X * 40.0)
    p = carried("foot_strike", anchor=None, unloaded_first=True)  # strike without anchor
    assert p.flags == ["no_anchor"] and p.old_stride_T_imu is None
    np.testing.assert_allclose(p.cov_pose, COV_X * 4.0)  # missed-strike inflation only
    np.testing.assert_allclose(p.cov_bias, COV_B * 4.0)


def test_first_stride_priors_gravity_aligned_or_anchor():
    pc = PriorConfig()
    tilt = gtsam.Rot3.Rx(0.2).matrix()
    p = first_stride_priors(pc, np.eye(4), None, tilt.T @ [0.0, 0.0, 9.81])
    assert p.flags == ["no_anchor"]
    np.testing.assert_allclose(
        p.stride_T_imu.rotation().matrix() @ tilt.T @ [0, 0, 1], [0, 0, 1], atol=1e-12
    )
    assert np.isclose(p.cov_velocity[0, 0], pc.first_velocity_sigma_m_s**2)
    assert np.isclose(p.cov_bias[0, 0], pc.first_accel_bias_sigma_m_s2**2)
    assert np.isclose(p.cov_bias[5, 5], pc.first_gyro_bias_sigma_rad_s**2)
    assert first_stride_priors(pc, np.eye(4), None, None).flags == ["no_anchor_no_gravity"]
    p = first_stride_priors(pc, np.eye(4), ANCHOR, None)
    assert p.flags == [] and np.allclose(p.cov_pose, ANCHOR.covariance)


def test_out_of_a_loose_tilt_stride_only_the_bias_is_loosened():
    """Out of a stride anchored without a known up σ (a session's first strike) the carried
    bias covariance is × ``loose_tilt_bias_inflation``; pose and velocity are not."""
    pc = PriorConfig(carry_inflation=2.0, loose_tilt_bias_inflation=10.0)
    args = (pc, np.eye(4), "foot_strike", PRED, COV_X, COV_V, BIAS, COV_B, ANCHOR, False)
    plain, loose = carried_priors(*args), carried_priors(*args, True)
    np.testing.assert_allclose(loose.cov_bias, COV_B * 20.0)
    np.testing.assert_allclose(loose.cov_velocity, plain.cov_velocity)
    np.testing.assert_allclose(loose.cov_pose, plain.cov_pose)
    np.testing.assert_allclose(loose.bias.vector(), BIAS.vector())


def test_out_of_a_loose_tilt_stride_the_accel_bias_can_restart_from_the_first_prior():
    pc = PriorConfig(loose_tilt_bias_reset=True, first_accel_bias_sigma_m_s2=0.2)
    bias = gtsam.imuBias.ConstantBias(np.array([4.0, 0.5, 0.8]), np.array([0.01, 0.02, 0.03]))
    cov_b = np.full((6, 6), 1e-6) + np.eye(6) * 1e-5
    args = (pc, np.eye(4), "foot_strike", PRED, COV_X, COV_V, bias, cov_b, ANCHOR, False)
    p = carried_priors(*args, True)
    np.testing.assert_allclose(p.bias.accelerometer(), 0.0)
    np.testing.assert_allclose(p.bias.gyroscope(), [0.01, 0.02, 0.03])
    np.testing.assert_allclose(p.cov_bias[:3, :3], np.eye(3) * 0.04)
    np.testing.assert_allclose(p.cov_bias[:3, 3:], 0.0)
    np.testing.assert_allclose(p.cov_bias[3:, 3:], cov_b[3:, 3:])
    kept = carried_priors(*args)  # out of a stride with a known up: carried as it is
    np.testing.assert_allclose(kept.bias.vector(), bias.vector())


def test_lateral_bias_moves_with_the_anchors_roll_the_sagittal_bias_stays():
    """Known answer: a stride ending rolled by 2° with a lateral bias of g·sin 2° reads, at
    rest, the same accelerometer lateral component as a level anchor with no lateral bias;
    a pitch correction leaves the bias alone (the stride separates it from gravity)."""
    from graph_slam.backend.priors import bias_with_tilt

    g = 9.81
    roll = np.radians(2.0)
    old_R = gtsam.Rot3.Rx(roll).matrix()  # stride_R_imu; the IMU's y is the stride's lateral
    bias = gtsam.imuBias.ConstantBias(np.array([0.05, 0.3, -0.02]), np.array([0.01, 0, 0]))
    new = bias_with_tilt(bias, old_R, np.eye(3), g)
    reading_old = g * old_R[2] + bias.accelerometer()
    reading_new = g * np.eye(3)[2] + new.accelerometer()
    assert abs(reading_new[1] - reading_old[1]) < 1e-12  # the lateral reading kept
    np.testing.assert_allclose(new.accelerometer()[[0, 2]], [0.05, -0.02], atol=1e-15)
    np.testing.assert_allclose(new.gyroscope(), [0.01, 0, 0])
    assert abs(new.accelerometer()[1] - (0.3 + g * np.sin(roll))) < 1e-12
    pitched = bias_with_tilt(bias, gtsam.Rot3.Ry(0.03).matrix(), np.eye(3), g)
    np.testing.assert_allclose(pitched.accelerometer(), bias.accelerometer(), atol=1e-15)


def test_carried_priors_move_the_bias_only_when_asked_and_given_gravity():
    tilted = gtsam.NavState(gtsam.Pose3(gtsam.Rot3.Rx(0.02), np.zeros(3)), np.zeros(3))
    bias = gtsam.imuBias.ConstantBias(np.array([0.0, 0.4, 0.0]), np.zeros(3))
    args = (np.eye(4), "foot_strike", tilted, COV_X, COV_V, bias, COV_B, ANCHOR, False, False)
    on = PriorConfig(carry_bias_with_tilt=True)
    moved = carried_priors(on, *args, 9.81).bias.accelerometer()
    assert abs(moved[1] - (0.4 + 9.81 * np.sin(0.02))) < 1e-12
    for pc, gravity in ((on, None), (PriorConfig(), 9.81)):  # no known up σ / off
        kept = carried_priors(pc, *args, gravity).bias.accelerometer()
        np.testing.assert_allclose(kept, [0.0, 0.4, 0.0])

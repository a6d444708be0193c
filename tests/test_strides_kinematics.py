"""LegKinematics: the estimator's kinematic measurements from the encoders and the leg model."""

from __future__ import annotations

import numpy as np
import pytest

from graph_slam.strides.kinematics import (
    anchor_covariance,
    imu_up_in_model,
    make_leg_kinematics,
)


@pytest.fixture(scope="module")
def model():
    from kinematics.leg_model import LegModel

    return LegModel()


def camera_T_imu_of(model):
    return np.linalg.inv(model.thigh_T_frame("camera_optical")) @ model.thigh_T_frame("imu")


def test_anchor_foot_pose_and_contact_geometry_from_the_encoders(model):
    from kinematics.stride_frame import DEFAULT_ENCODER_VAR_RAD2, stride_T_camera

    cam_T_imu = camera_T_imu_of(model)
    leg = make_leg_kinematics(model, cam_T_imu, 2e-3, 3e-3)
    t = np.arange(0.0, 0.5, 0.01)
    leg.add_joints(t, 0.2 + 0.5 * t, np.full(t.size, 0.05))
    assert leg.foot_pose(0.1) is None  # no struck foot yet
    up = np.array([1.0, -2.0, 9.5])
    a = leg.anchor(0.1, up)
    q = np.array([0.25, 0.05])
    want = stride_T_camera(model, q, up_in_imu=imu_up_in_model(model, cam_T_imu, up))
    np.testing.assert_allclose(a.stride_T_camera, want.stride_T_camera, atol=1e-12)
    np.testing.assert_allclose(a.covariance, want.covariance, atol=1e-15)
    # with an up sigma: the encoders' FK error + tilt + the configured floors, no contact noise
    b = leg.anchor(0.1, up, up_sigma_rad=0.004)
    enc = model.camera_covariance(q, DEFAULT_ENCODER_VAR_RAD2)
    want_cov = anchor_covariance(want.stride_T_camera, enc, 0.004, 2e-3, 3e-3)
    np.testing.assert_allclose(b.covariance, want_cov, atol=1e-15)
    # foot_pose holds the struck foot: the camera moves with the encoders only
    q2 = np.array([0.3, 0.05])
    fp = leg.foot_pose(0.2)
    np.testing.assert_allclose(
        fp.stride_T_camera, want.stride_T_foot @ model.foot_T_camera(q2), atol=1e-12
    )
    geo = leg.contact_geometry(0.2)
    np.testing.assert_allclose(geo.imu_T_foot, np.linalg.inv(model.foot_T_imu(q2)), atol=1e-12)
    np.testing.assert_allclose(geo.foot_p_toe, model.frame_T_frame("heel", "toe", q2)[:3, 3])
    assert leg.anchor(0.6, up) is None and leg.contact_geometry(-0.1) is None  # outside


def test_without_a_model_joints_are_buffered_but_nothing_is_measured():
    leg = make_leg_kinematics(None, np.eye(4))
    assert leg.add_joints([0.0, 0.1], [0.1, 0.2], [0.0, 0.0]) == 2
    assert leg.q_at(0.05) is None
    assert leg.anchor(0.05, None) is None and leg.contact_geometry(0.05) is None


def test_out_of_limit_joint_gives_no_measurement(model):
    leg = make_leg_kinematics(model, camera_T_imu_of(model))
    leg.add_joints([0.0, 0.1], [0.3, 0.3], [0.0, 0.0])
    leg.joints._q[1, 0] = 10.0  # bypass the buffer's checks: FK must refuse, not crash
    assert leg.anchor(0.09, None) is None
    assert leg.contact_geometry(0.09) is None


def test_the_heel_strike_up_is_the_nominal_pitch_anchors_up(model):
    """The encoders' up at a strike: the anchor with the nominal heel-strike pitch has its
    stride z along it (to 1e-9), and an anchor built from that up reproduces the pose."""
    from kinematics.stride_frame import stride_T_camera

    cam_T_imu = camera_T_imu_of(model)
    leg = make_leg_kinematics(model, cam_T_imu)
    t = np.arange(0.0, 0.5, 0.01)
    leg.add_joints(t, np.full(t.size, 1.0), np.full(t.size, 0.3))  # a stair-ascent strike
    up = leg.heel_strike_up(0.2)
    nominal = stride_T_camera(model, np.array([1.0, 0.3])).stride_T_camera
    want = cam_T_imu[:3, :3].T @ nominal[2, :3]  # stride z in the camera, then the IMU frame
    np.testing.assert_allclose(up, want, atol=1e-9)
    again = leg.anchor(0.2, 9.81 * up)
    np.testing.assert_allclose(again.stride_T_camera[:3, :3], nominal[:3, :3], atol=1e-9)
    assert leg.heel_strike_up(0.6) is None  # outside the samples
    assert make_leg_kinematics(None, np.eye(4)).heel_strike_up(0.2) is None

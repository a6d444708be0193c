"""stride_T_camera at foot strike: from IMU gravity (any attitude) and from the foot pitch."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from kinematics.errors import KinematicsError
from kinematics.leg_model import LegModel
from kinematics.stride_frame import (
    nominal_heel_strike_pitch_rad,
    stride_T_camera,
    stride_T_foot_from_pitch,
)


@pytest.fixture(scope="module")
def model() -> LegModel:
    return LegModel()


def expected_stride_T_camera(model: LegModel, q, world_R_thigh: np.ndarray) -> np.ndarray:
    """Independent construction: place the leg in a world frame, build the stride frame there."""
    world_T_thigh = np.eye(4)
    world_T_thigh[:3, :3] = world_R_thigh
    world_T_heel = world_T_thigh @ model.frame_T_frame("thigh", "heel", q)
    world_T_cam = world_T_thigh @ model.frame_T_frame("thigh", "camera_optical", q)
    x_foot = world_T_heel[:3, 0]
    x_h = np.array([x_foot[0], x_foot[1], 0.0])
    x_h /= np.linalg.norm(x_h)
    world_T_stride = np.eye(4)
    world_T_stride[:3, :3] = np.column_stack([x_h, np.cross([0, 0, 1.0], x_h), [0, 0, 1.0]])
    world_T_stride[:3, 3] = world_T_heel[:3, 3]
    return np.linalg.inv(world_T_stride) @ world_T_cam


@pytest.mark.parametrize(
    ("q", "euler_deg"),
    [((0.05, 0.0), (0, 20, 0)), ((0.1, -0.1), (4, 25, 10)), ((0.3, 0.2), (-6, 5, -30))],
)
def test_from_imu_gravity_matches_world_construction(model, q, euler_deg) -> None:
    world_R_thigh = Rotation.from_euler("xyz", euler_deg, degrees=True).as_matrix()
    world_R_imu = world_R_thigh @ model.thigh_T_frame("imu")[:3, :3]
    accel_imu = world_R_imu.T @ np.array([0.0, 0.0, 9.81])  # at rest: +g up
    anchor = stride_T_camera(model, q, up_in_imu=accel_imu)
    np.testing.assert_allclose(
        anchor.stride_T_camera, expected_stride_T_camera(model, q, world_R_thigh), atol=1e-9
    )
    assert anchor.source == "imu_gravity"
    # origin at the heel contact: the heel is at the stride origin
    heel_in_stride = anchor.stride_T_camera @ np.linalg.inv(model.foot_T_camera(q))
    np.testing.assert_allclose(heel_in_stride[:3, 3], 0.0, atol=1e-12)


def test_flat_foot_level_ground_is_identity_rotation(model: LegModel) -> None:
    # Thigh vertical, leg straight: the sole is level, the stride frame is the foot frame.
    anchor = stride_T_camera(model, [0.0, 0.0], up_in_imu=[0.0, 0.0, 9.81], contact="foot_flat")
    np.testing.assert_allclose(anchor.stride_T_foot, np.eye(4), atol=1e-12)
    np.testing.assert_allclose(anchor.stride_T_camera[:3, 3], [0.14, 0.0, 0.72], atol=1e-12)
    assert anchor.foot_pitch_rad == pytest.approx(0.0, abs=1e-12)


def test_foot_pitch_hand_computed(model: LegModel) -> None:
    a = math.radians(20.0)
    anchor = stride_T_camera(model, [0.0, 0.0], foot_pitch_rad=a)
    # Leg straight, foot (and whole leg) rotated toe-up by a about the heel.
    x, z = 0.14, 0.72
    expected = [x * math.cos(a) - z * math.sin(a), 0.0, x * math.sin(a) + z * math.cos(a)]
    np.testing.assert_allclose(anchor.stride_T_camera[:3, 3], expected, atol=1e-12)
    assert anchor.foot_pitch_rad == pytest.approx(a)
    toe_in_stride = stride_T_foot_from_pitch(a) @ model.frame_T_frame("heel", "toe", [0.0, 0.0])
    assert toe_in_stride[2, 3] > 0.08  # toe up


def test_imu_and_pitch_agree_for_a_sagittal_pose(model: LegModel) -> None:
    q = (0.08, 0.02)
    thigh_pitch = -0.4  # rotation about +y; negative = thigh flexed (knee forward)
    world_R_thigh = Rotation.from_euler("y", thigh_pitch).as_matrix()
    accel = (world_R_thigh @ model.thigh_T_frame("imu")[:3, :3]).T @ np.array([0, 0, 9.81])
    by_imu = stride_T_camera(model, q, up_in_imu=accel)
    # The foot's rotation about +y in the world is thigh + knee - ankle; +y lowers the toe.
    foot_pitch = -(thigh_pitch + q[0] - q[1])
    by_pitch = stride_T_camera(model, q, foot_pitch_rad=foot_pitch)
    np.testing.assert_allclose(by_imu.stride_T_camera, by_pitch.stride_T_camera, atol=1e-12)


def test_nominal_heel_strike_pitch_is_plausible() -> None:
    assert math.radians(10) < nominal_heel_strike_pitch_rad(1.2) < math.radians(30)


def test_covariance_depends_on_contact(model: LegModel) -> None:
    strike = stride_T_camera(model, [0.1, 0.0], contact="heel_strike")
    flat = stride_T_camera(model, [0.1, 0.0], contact="foot_flat")
    assert np.trace(strike.covariance) > np.trace(flat.covariance)
    assert flat.foot_pitch_rad == 0.0


def test_bad_inputs(model: LegModel) -> None:
    with pytest.raises(KinematicsError, match="up_in_imu"):
        stride_T_camera(model, [0.1, 0.0], up_in_imu=[0.0, np.nan, 1.0])
    with pytest.raises(KinematicsError, match="foot_pitch_rad"):
        stride_T_camera(model, [0.1, 0.0], foot_pitch_rad=2.0)
    with pytest.raises(KinematicsError, match="vertical"):
        stride_T_camera(model, [0.0, 0.0], up_in_imu=[1.0, 0.0, 0.0])

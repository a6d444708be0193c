"""Records refuse malformed data with the record, field and rule in the message."""

from __future__ import annotations

import numpy as np
import pytest

from graph_slam.errors import RecordError
from graph_slam.session.records import (
    Calibration,
    CameraIntrinsics,
    GaitEvents,
    ImuSeries,
    PoseTrajectory,
    RgbdFrame,
)


def test_arrays_are_read_only() -> None:
    imu = ImuSeries(np.arange(3.0), np.zeros((3, 3)), np.zeros((3, 3)))
    with pytest.raises(ValueError, match="read-only"):
        imu.gyro_rad_s[0, 0] = 1.0


def test_imu_shape_and_nan() -> None:
    with pytest.raises(
        RecordError, match=r"ImuSeries\.gyro_rad_s: shape \(3, 2\) does not match 3×3"
    ):
        ImuSeries(np.arange(3.0), np.zeros((3, 2)), np.zeros((3, 3)))
    accel = np.zeros((4, 3))
    accel[2, 1] = np.nan
    with pytest.raises(
        RecordError, match=r"accel_m_s2: 1 row\(s\) hold NaN or inf, first at row 2"
    ):
        ImuSeries(np.arange(4.0), np.zeros((4, 3)), accel)


def test_duplicate_time_is_refused() -> None:
    with pytest.raises(
        RecordError, match=r"1 timestamp\(s\) not strictly increasing, first at row 2 \(duplicate"
    ):
        ImuSeries(np.array([0.0, 1.0, 1.0]), np.zeros((3, 3)), np.zeros((3, 3)))


def test_frame_dtype_and_colour_shape() -> None:
    with pytest.raises(RecordError, match="dtype must be float32"):
        RgbdFrame(0.0, np.zeros((4, 5)))
    with pytest.raises(RecordError, match="color_rgb: must be uint8 4×5×3"):
        RgbdFrame(0.0, np.zeros((4, 5), np.float32), np.zeros((4, 5), np.uint8))
    with pytest.raises(RecordError, match=">= 0"):
        RgbdFrame(0.0, -np.ones((4, 5), np.float32))


def test_non_rigid_pose_is_refused() -> None:
    pose = np.eye(4)
    pose[0, 0] = 2.0
    with pytest.raises(RecordError, match=r"thigh_T_camera: 1 transform\(s\) are not rigid"):
        Calibration(thigh_T_camera=pose)
    with pytest.raises(RecordError, match="world_T_camera"):
        PoseTrajectory(np.array([0.0]), pose[None])


def test_intrinsics_and_events() -> None:
    with pytest.raises(RecordError, match="fx_px: must be finite and > 0"):
        CameraIntrinsics(64, 48, 0.0, 50.0, 32.0, 24.0)
    events = GaitEvents(
        np.array([0.0, 0.6, 1.1]), ("foot_strike", "toe_off", "foot_strike"), ("a",) * 3
    )
    np.testing.assert_array_equal(events.foot_strikes_s, [0.0, 1.1])
    with pytest.raises(RecordError, match="not one of"):
        GaitEvents(np.array([0.0]), ("heel",), ("a",))


def test_time_offset_out_of_range() -> None:
    with pytest.raises(RecordError, match=r"imu_time_offset_s: must be finite and within ±1 s"):
        Calibration(imu_time_offset_s=5.0)

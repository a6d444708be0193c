"""The ``imu-online`` event source: events from the causal thigh-IMU estimator, announced only
once known (never read ahead)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from graph_slam.errors import SessionError
from graph_slam.strides.events import StrideEvents
from graph_slam.strides.online_events import ONLINE_SOURCE, online_stride_events
from graph_slam.strides.streams import session_streams
from kinematics.gait_synth import random_mounting, thigh_imu_from_reference


def test_an_event_counts_only_once_known():
    ev = StrideEvents(
        np.array([1.0, 2.0]),
        np.array([1.6]),
        ONLINE_SOURCE,
        foot_strikes_known_s=np.array([1.05, 2.04]),
        toe_offs_known_s=np.array([1.62]),
    )
    assert not ev.foot_loaded(1.02)  # happened at 1.0, known at 1.05
    assert ev.foot_loaded(1.06)
    assert ev.foot_loaded(1.61)  # the toe-off at 1.6 is not known before 1.62
    assert not ev.foot_loaded(1.63)
    known = ev.known_at(2.0)
    np.testing.assert_array_equal(known.foot_strikes_s, [1.0])
    # without known-at times an event is known at its time (the load cell)
    plain = StrideEvents(np.array([1.0]), np.zeros(0), "load_cell")
    assert plain.foot_loaded(1.0) and not plain.foot_loaded(0.99)


@pytest.fixture(scope="module")
def walk():
    return thigh_imu_from_reference(
        1.1, n_strides=5, rate_hz=100.0, thigh_R_sensor=random_mounting(11), seed=11
    )


def test_online_stride_events_match_the_truth_and_are_known_after_they_happen(walk):
    imu = walk.imu
    ev = online_stride_events(imu.t_s, imu.gyro_rad_s, imu.accel_m_s2, "<walk>")
    assert ev.source == ONLINE_SOURCE
    assert ev.foot_strikes_s.size == walk.foot_strikes_s.size
    assert np.abs(ev.foot_strikes_s - walk.foot_strikes_s).max() < 0.04
    assert np.all(ev.strikes_known_s >= ev.foot_strikes_s - 1e-9)
    assert np.all(np.diff(ev.strikes_known_s) >= 0)


def _session(imu, offset_s=0.0):
    return SimpleNamespace(
        path="<session>",
        calibration=SimpleNamespace(imu_time_offset_s=offset_s, joints_time_offset_s=0.0),
        imu=imu,
        joints=None,
        events=None,
    )


def test_session_streams_with_imu_online_needs_no_events_file(walk):
    streams = session_streams(_session(walk.imu, offset_s=0.5), ONLINE_SOURCE)
    assert streams.events.source == ONLINE_SOURCE
    # on the camera clock: the IMU offset applied
    assert np.abs(streams.foot_strikes_s - (walk.foot_strikes_s + 0.5)).max() < 0.04
    with pytest.raises(SessionError, match="imu-online"):
        session_streams(_session(None), ONLINE_SOURCE)

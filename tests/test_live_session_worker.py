"""The live session written by a process of its own: the same session as the writer in the
estimator's process, nothing that looks whole when it was cut off, and the child's priority."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np
import pytest

from graph_slam.errors import SessionError
from graph_slam.live.session_worker import SessionProcess
from graph_slam.session import SessionWriter, open_session
from graph_slam.session.manifest import Provenance
from graph_slam.session.records import (
    Calibration,
    CameraIntrinsics,
    GaitEvents,
    ImuSeries,
    JointSeries,
    RgbdFrame,
)

K = CameraIntrinsics(32, 24, 30.0, 29.0, 15.5, 11.5)
UNIT = 0.001
CAMERA_T_IMU = np.array([[0.0, 0.0, 1.0, 0.02], [-1.0, 0.0, 0.0, 0.0], [0.0, -1.0, 0.0, -0.01],
                         [0.0, 0.0, 0.0, 1.0]])  # fmt: skip


def _frames(n: int, seed: int) -> list[RgbdFrame]:
    """Depth in metres as the camera's decoding gives it (units × unit, float32); colour on
    every third frame (30 Hz beside 90 Hz depth), depth-only between."""
    rng = np.random.default_rng(seed)
    frames = []
    for i in range(n):
        units = rng.integers(0, 6000, (K.height_px, K.width_px)).astype(np.float32)
        depth = units * np.float32(UNIT)
        color = rng.integers(0, 256, (K.height_px, K.width_px, 3), dtype=np.uint8)
        frames.append(RgbdFrame(10.0 + i / 90.0, depth, color if i % 3 == 0 else None, i))
    return frames


def _streams(seed: int):
    rng = np.random.default_rng(seed)
    t = 10.0 + np.arange(40) / 400.0
    imu = ImuSeries(t, rng.normal(size=(40, 3)), rng.normal(size=(40, 3)) + np.array([0, 0, 9.81]))
    tj = 10.0 + np.arange(20) / 200.0
    joints = JointSeries(tj, rng.normal(size=20), rng.normal(size=20))
    events = GaitEvents(np.array([10.02, 10.07]), ("foot_strike", "toe_off"), ("live", "live"))
    return imu, joints, events


def _args() -> dict:
    return dict(name="live", intrinsics=K, depth_unit_m=UNIT, camera_profile="realsense-live")


def test_the_process_writes_the_session_the_writer_in_process_writes(tmp_path: Path) -> None:
    frames, (imu, joints, events) = _frames(7, seed=3), _streams(seed=4)
    child = SessionProcess(tmp_path / "child", **_args(), camera_T_imu=CAMERA_T_IMU,
                           generator="graph_slam.live", source="rec.db3", nice=0)  # fmt: skip
    child.wait_ready()
    for frame in frames:
        child.add_frame(frame)
    assert child.close(imu, joints, events) == tmp_path / "child"
    with SessionWriter(tmp_path / "here", **_args(),
                       calibration=Calibration(camera_T_imu=CAMERA_T_IMU),
                       provenance=Provenance(generator="graph_slam.live",
                                             source="rec.db3")) as here:  # fmt: skip
        for frame in frames:
            here.add_frame(frame)
        here.write_imu(imu)
        here.write_joints(joints)
        here.write_events(events)
    a, b = open_session(tmp_path / "child"), open_session(tmp_path / "here")
    assert a.n_frames == b.n_frames == 7
    for fa, fb in zip(a.iter_frames(), b.iter_frames(), strict=True):
        assert fa.t_s == fb.t_s
        np.testing.assert_array_equal(fa.depth_m, fb.depth_m)
        assert (fa.color_rgb is None) == (fb.color_rgb is None)
        if fa.color_rgb is not None:
            np.testing.assert_array_equal(fa.color_rgb, fb.color_rgb)
    for name in ("frames.csv", "imu.csv", "joints.csv", "events.csv"):
        assert (tmp_path / "child" / name).read_text() == (tmp_path / "here" / name).read_text()
    np.testing.assert_array_equal(a.calibration.camera_T_imu, CAMERA_T_IMU)
    assert a.manifest.provenance.source == "rec.db3"
    assert a.manifest.sensors.camera.has_color and a.depth_unit_m == UNIT


def test_a_writer_cut_off_leaves_no_session(tmp_path: Path) -> None:
    child = SessionProcess(tmp_path / "cut", **_args(), nice=0)
    child.wait_ready()
    for frame in _frames(3, seed=5):
        child.add_frame(frame)
    child.abort()
    assert not (tmp_path / "cut" / "session.yaml").exists()
    with pytest.raises(SessionError):
        open_session(tmp_path / "cut")


def test_a_writer_that_fails_is_said_on_close(tmp_path: Path) -> None:
    """Frames that do not increase in time: the child stops with the writer's error, and
    close says so (no manifest)."""
    child = SessionProcess(tmp_path / "bad", **_args(), nice=0)
    child.wait_ready()
    first = _frames(2, seed=6)
    child.add_frame(first[1])
    child.add_frame(first[0])  # earlier than the one before
    with pytest.raises(SessionError, match=r"not written whole.*does not increase"):
        child.close()
    assert not (tmp_path / "bad" / "session.yaml").exists()


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="a process's nice: Linux")
def test_the_writer_process_runs_at_the_nice_it_was_given(tmp_path: Path) -> None:
    child = SessionProcess(tmp_path / "niced", **_args(), nice=7)
    child.wait_ready()
    try:
        mine = os.getpriority(os.PRIO_PROCESS, 0)
        assert os.getpriority(os.PRIO_PROCESS, child._proc.pid) == min(mine + 7, 19)
    finally:
        child.add_frame(_frames(1, seed=7)[0])
        child.close()
    assert open_session(tmp_path / "niced").n_frames == 1


def test_a_run_without_the_writer_process_writes_the_same_session_on_stop(tmp_path: Path) -> None:
    """``LiveRunner`` without ``session_path`` keeps the frames and writes them on stop, in
    its own process: the same files as the writer's process."""
    from types import SimpleNamespace

    from graph_slam.live.loop import LiveRunner, _Recorded

    frames, (imu, joints, events) = _frames(5, seed=8), _streams(seed=9)
    runner = LiveRunner.__new__(LiveRunner)  # only what writing the session reads
    runner._writer = None
    runner.setup = SimpleNamespace(intrinsics=K, depth_unit_m=UNIT, camera_T_imu=CAMERA_T_IMU,
                                   device={"serial": "123"})  # fmt: skip
    runner.source = SimpleNamespace(playback=None)
    runner.rec = _Recorded(frames=frames,
                           imu=[(imu.t_s[:15], imu.gyro_rad_s[:15], imu.accel_m_s2[:15]),
                                (imu.t_s[15:], imu.gyro_rad_s[15:], imu.accel_m_s2[15:])],
                           joints=list(zip(joints.t_s, joints.knee_rad, joints.ankle_rad,
                                           strict=True)),
                           events=list(zip(events.t_s, events.kind, strict=True)))  # fmt: skip
    here = runner.write_session(tmp_path / "here")
    child = SessionProcess(tmp_path / "child", **_args(), camera_T_imu=CAMERA_T_IMU,
                           generator="graph_slam.live", source="123", nice=0)  # fmt: skip
    for frame in frames:
        child.add_frame(frame)
    child.close(*runner._streams())
    for name in ("frames.csv", "imu.csv", "joints.csv", "events.csv"):
        assert (here / name).read_text() == (tmp_path / "child" / name).read_text(), name
    a, b = open_session(here), open_session(tmp_path / "child")
    assert a.n_frames == b.n_frames == 5 and a.manifest.provenance.source == "123"
    for fa, fb in zip(a.iter_frames(), b.iter_frames(), strict=True):
        np.testing.assert_array_equal(fa.depth_m, fb.depth_m)
    np.testing.assert_array_equal(a.imu.t_s, imu.t_s)

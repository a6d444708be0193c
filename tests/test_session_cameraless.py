"""Sessions without a camera (IMU-only, joints-only): written, read, validated, summarised."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from graph_slam.errors import SessionError
from graph_slam.session import (
    ImuSeries,
    PoseTrajectory,
    SessionWriter,
    open_session,
    session_info,
    validate_session,
)
from graph_slam.session.records import RgbdFrame


def _imu_only(path: Path) -> Path:
    t = np.arange(50) / 100.0
    imu = ImuSeries(t, np.zeros((50, 3)), np.tile([0.0, 0.0, 9.81], (50, 1)))
    poses = np.tile(np.eye(4), (5, 1, 1))
    poses[:, 0, 3] = np.arange(5) * 0.1
    with SessionWriter(path, name="imu-only", intrinsics=None) as writer:
        writer.write_imu(imu)
        writer.write_ground_truth(PoseTrajectory(t[::10], poses), high_rate=True)
    return path


def test_session_without_camera_round_trip(tmp_path: Path) -> None:
    path = _imu_only(tmp_path / "s")
    manifest = yaml.safe_load((path / "session.yaml").read_text())
    assert manifest["sensors"]["camera"] is None
    assert not (path / "depth").exists()
    session = open_session(path)
    assert session.n_frames == 0 and session.intrinsics is None and session.depth_unit_m is None
    assert len(session.imu) == 50 and len(session.ground_truth_hf) == 5
    report = validate_session(path)
    assert report.ok and report.frames_checked == 0 and report.counts["imu"] == 50
    info = session_info(session)
    assert info.image_size is None and info.camera_profile is None
    streams = {s.name: s for s in info.streams}
    assert streams["frames"].count == 0
    assert streams["imu"].mean_rate_hz == pytest.approx(100.0)


def test_camera_key_is_required_and_null_forbids_frames(tmp_path: Path) -> None:
    path = _imu_only(tmp_path / "s")
    frames = path / "frames.csv"
    frames.write_text(frames.read_text() + "0,0.0,depth/000000.png,\n")
    with pytest.raises(SessionError, match=r"'sensors\.camera' is null but frames\.csv lists 1"):
        open_session(path)
    data = yaml.safe_load((path / "session.yaml").read_text())
    del data["sensors"]["camera"]
    (path / "session.yaml").write_text(yaml.safe_dump(data))
    with pytest.raises(SessionError, match=r"sensors\.camera"):
        open_session(path)


def test_writer_without_camera_refuses_frames(tmp_path: Path) -> None:
    writer = SessionWriter(tmp_path / "s", name="x", intrinsics=None)
    frame = RgbdFrame(0.0, np.ones((2, 2), np.float32))
    with pytest.raises(SessionError, match="no camera"):
        writer.add_frame(frame)

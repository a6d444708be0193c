"""The simulator's export plays in the RealSense SDK: librealsense's own playback opens it with
the streams, intrinsics, depth units, extrinsics and frame counts that were exported."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pyrealsense2")
pytest.importorskip("rosbags")

from graph_slam.sim import SimConfig
from graph_slam.sim.export import RecordingExportConfig, export_realsense_recording


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    out = tmp_path_factory.mktemp("export") / "rec"
    cfg = SimConfig(strides=1, resolution="106x60", motion_blur=False, seed=3, quicklook=False)
    export = RecordingExportConfig(record_speed=None, color_size_px=(128, 96), serial="123")
    return export_realsense_recording(cfg, out, export)


def _play(path: Path):
    """Every frame of the recording through librealsense's playback (not in real time)."""
    import pyrealsense2 as rs

    dev = rs.context().load_device(str(path))
    playback = dev.as_playback()
    playback.pause()  # all sensors started before the first frame is read
    got: dict[str, list[float]] = {}
    profiles = {}
    sensors = dev.query_sensors()
    for sensor in sensors:
        for p in sensor.get_stream_profiles():
            profiles[p.stream_name()] = p
        sensor.open(sensor.get_stream_profiles())
    for sensor in sensors:
        sensor.start(
            lambda f: got.setdefault(f.profile.stream_name(), []).append(f.get_timestamp())
        )
    playback.set_real_time(False)
    playback.resume()
    deadline = time.monotonic() + 30
    while playback.current_status() != rs.playback_status.stopped:
        assert time.monotonic() < deadline, "playback did not finish"
        time.sleep(0.02)
    for sensor in sensors:
        sensor.stop()
        sensor.close()
    return dev, profiles, got


def test_the_sdk_plays_the_export_with_its_streams_and_calibration(exported) -> None:
    import pyrealsense2 as rs

    dev, profiles, got = _play(exported.bag)
    assert dev.get_info(rs.camera_info.serial_number) == "123"
    assert set(profiles) == {"Depth", "Color", "Accel", "Gyro"}
    depth = profiles["Depth"].as_video_stream_profile()
    color = profiles["Color"].as_video_stream_profile()
    assert (depth.format(), depth.fps(), color.format(), color.fps()) == (
        rs.format.z16, 90, rs.format.rgb8, 30
    )  # fmt: skip
    assert (profiles["Accel"].fps(), profiles["Gyro"].fps()) == (250, 400)
    for prof, k in ((depth, exported.depth_intrinsics), (color, exported.color_intrinsics)):
        i = prof.get_intrinsics()
        assert (i.width, i.height) == (k.width_px, k.height_px)
        np.testing.assert_allclose([i.fx, i.fy, i.ppx, i.ppy],
                                   [k.fx_px, k.fy_px, k.cx_px, k.cy_px], rtol=1e-6)  # fmt: skip
    assert dev.first_depth_sensor().get_depth_scale() == pytest.approx(0.001, rel=1e-6)
    ext = depth.get_extrinsics_to(color)  # p_color = R p_depth + t, R column-major
    np.testing.assert_allclose(np.reshape(ext.rotation, (3, 3)).T,
                               exported.color_T_depth[:3, :3], atol=1e-6)  # fmt: skip
    np.testing.assert_allclose(ext.translation, exported.color_T_depth[:3, 3], atol=1e-6)
    counts = {k: len(v) for k, v in got.items()}
    assert counts == {"Depth": exported.frames, "Color": exported.counts["color"],
                      "Accel": exported.counts["accel"], "Gyro": exported.counts["gyro"]}  # fmt: skip
    # the frames' own time: the simulator's stamps on the camera clock (ms)
    truth = np.loadtxt(exported.ground_truth, ndmin=2)[:, 0]
    np.testing.assert_allclose(np.array(got["Depth"]) * 1e-3, truth, rtol=0, atol=1e-6)

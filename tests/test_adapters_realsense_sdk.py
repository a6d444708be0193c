"""RealSense SDK recordings as the current SDK writes them: ROS 2 ``.db3`` files recorded by
librealsense itself (a ``software_device`` + ``rs.recorder``) from small made-up sessions,
converted with ``graph-slam convert``; plus the SDK's own ROS 1 test recording."""

from __future__ import annotations

import sqlite3
from pathlib import Path

import numpy as np
import pytest

from graph_slam.errors import BagError, MissingStreamError
from graph_slam.session import open_session, validate_session
from graph_slam.session.adapters import convert
from graph_slam.session.records import CameraIntrinsics
from tests.conftest import shared_data

pytest.importorskip("pyrealsense2")
pytest.importorskip("rosbags")

from graph_slam.sim.realsense_sdk import SdkDevice, SdkRecorder

DEPTH = CameraIntrinsics(64, 48, 52.0, 51.0, 31.0, 24.5)
COLOR = CameraIntrinsics(96, 72, 80.0, 79.0, 47.0, 35.5)
T0_S = 1_700_000_005.0  # the device clock (s)
DEPTH_HZ, COLOR_HZ, ACCEL_HZ, GYRO_HZ = 90, 30, 250, 400
DURATION_S = 0.3
PLANE_M = 1.2


def _color_T_depth() -> np.ndarray:
    from scipy.spatial.transform import Rotation

    pose = np.eye(4)
    pose[:3, :3] = Rotation.from_rotvec([0.01, -0.02, 0.015]).as_matrix()
    pose[:3, 3] = [-0.015, 0.001, 0.002]
    return pose


def _device(**kw) -> SdkDevice:
    base = dict(depth=DEPTH, depth_rate_hz=DEPTH_HZ, depth_unit_m=0.001, color=COLOR,
                color_rate_hz=COLOR_HZ, color_T_depth=_color_T_depth(), accel_rate_hz=ACCEL_HZ,
                gyro_rate_hz=GYRO_HZ, serial="912345678901", firmware="5.16.0.1",
                color_coeffs=(0.02, -0.01, 0.0, 0.0, 0.001))  # fmt: skip
    base.update(kw)
    return SdkDevice(**base)


def depth_raw(k: int) -> np.ndarray:
    """A plane at PLANE_M (mm) with a per-frame offset so frames are told apart."""
    return np.full((DEPTH.height_px, DEPTH.width_px), round(PLANE_M * 1000) + k, np.uint16)


def color_rgb() -> np.ndarray:
    """Colour that encodes its own pixel: R = 2u, G = 3v."""
    v, u = np.mgrid[0 : COLOR.height_px, 0 : COLOR.width_px]
    return np.stack([2 * u, 3 * v, np.full_like(u, 50)], -1).astype(np.uint8)


def gyro_at(t_rel: np.ndarray) -> np.ndarray:
    return np.stack([np.sin(3 * t_rel), 0.1 * t_rel, np.full_like(t_rel, -0.2)], -1)


ACCEL = np.array([0.3, -9.7, 0.4])


def _record(path: Path, device: SdkDevice | None = None, *, depth_until_s: float = DURATION_S,
            frames: bool = True) -> dict[str, np.ndarray]:  # fmt: skip
    """Record the small session in time order; returns the stamps written (s, device clock)."""
    device = device or _device()
    t = {
        "depth": T0_S + np.arange(round(depth_until_s * DEPTH_HZ)) / DEPTH_HZ,
        "color": T0_S + 0.004 + np.arange(round(DURATION_S * COLOR_HZ)) / COLOR_HZ,
        "accel": T0_S + np.arange(round(DURATION_S * ACCEL_HZ)) / ACCEL_HZ,
        "gyro": T0_S + 0.0007 + np.arange(round(DURATION_S * GYRO_HZ)) / GYRO_HZ,
    }
    if device.color is None:
        t["color"] = t["color"][:0]
    if not frames:
        t = {k: v[:0] for k, v in t.items()}
    events = sorted(
        (float(ts), kind, i) for kind, ts_all in t.items() for i, ts in enumerate(ts_all)
    )
    rgb = color_rgb()
    with SdkRecorder(path, device) as rec:
        for ts, kind, i in events:
            if kind == "depth":
                rec.depth(ts, depth_raw(i))
            elif kind == "color":
                rec.color(ts, rgb)
            elif kind == "accel":
                rec.accel(ts, ACCEL)
            else:
                rec.gyro(ts, gyro_at(np.array([ts - T0_S]))[0])
    return t


@pytest.fixture(scope="module")
def recorded(tmp_path_factory) -> tuple[Path, dict[str, np.ndarray], Path]:
    base = tmp_path_factory.mktemp("sdk")
    stamps = _record(base / "walk.db3")
    result = convert(base / "walk.db3", base / "s")
    return base / "walk.db3", stamps, result.path


def test_every_depth_frame_is_kept_beside_slower_colour(recorded) -> None:
    _, stamps, path = recorded
    session = open_session(path)
    n_depth = stamps["depth"].size
    assert session.n_frames == n_depth  # 27 depth frames at 90 Hz, 9 colour at 30 Hz
    assert session.n_color_frames == stamps["color"].size
    np.testing.assert_allclose(session.frame_times_s, stamps["depth"], rtol=0, atol=1e-6)
    for k, frame in enumerate(session):
        np.testing.assert_allclose(frame.depth_m, depth_raw(k) * 1e-3, rtol=1e-6)
    assert validate_session(path).ok


def test_report_counts_device_intrinsics_units_and_extrinsics(recorded) -> None:
    import yaml

    _, stamps, path = recorded
    report = yaml.safe_load((path / "conversion_report.yaml").read_text())
    assert report["device"] == {"product": "Intel RealSense D435I", "serial": "912345678901",
                                "firmware": "5.16.0.1"}  # fmt: skip
    frames = next(s for s in report["streams"] if s["stream"] == "frames")
    assert frames["used"] == stamps["depth"].size and not frames["dropped"]
    assert frames["depth_only"] == stamps["depth"].size - stamps["color"].size
    c_T_d = np.array(report["calibration"]["color_T_depth"]["value"])
    np.testing.assert_allclose(c_T_d, _color_T_depth(), atol=2e-6)  # 6 decimals in the text
    assert "tf/ref_1" in report["calibration"]["color_T_depth"]["source"]
    assert any("0.001 m per value" in n and "Depth_Units" in n for n in report["notes"])
    session = open_session(path)
    k = session.intrinsics
    assert (k.width_px, k.height_px, k.fx_px, k.fy_px, k.cx_px, k.cy_px) == (
        DEPTH.width_px, DEPTH.height_px, DEPTH.fx_px, DEPTH.fy_px, DEPTH.cx_px, DEPTH.cy_px,
    )  # fmt: skip
    assert any("plumb_bob colour camera" in n for n in report["notes"])


def test_colour_at_its_own_size_is_registered_to_depth(recorded) -> None:
    """Each depth pixel's colour names the colour pixel it projects to (plane at 1.2 m)."""
    _, _, path = recorded
    session = open_session(path)
    frame = next(f for f in session if f.color_rgb is not None)
    v, u = np.mgrid[0 : DEPTH.height_px, 0 : DEPTH.width_px]
    z = frame.depth_m
    pts = np.stack(
        [(u - DEPTH.cx_px) / DEPTH.fx_px * z, (v - DEPTH.cy_px) / DEPTH.fy_px * z, z], -1
    )
    pc = pts @ _color_T_depth()[:3, :3].T + _color_T_depth()[:3, 3]
    xn, yn = pc[..., 0] / pc[..., 2], pc[..., 1] / pc[..., 2]
    k1, k2, k3 = 0.02, -0.01, 0.001  # p1 = p2 = 0
    r2 = xn**2 + yn**2
    radial = 1 + k1 * r2 + k2 * r2**2 + k3 * r2**3
    uc = COLOR.fx_px * xn * radial + COLOR.cx_px
    vc = COLOR.fy_px * yn * radial + COLOR.cy_px
    has = frame.color_rgb.any(-1)
    assert has.mean() > 0.9
    assert np.abs(frame.color_rgb[..., 0][has] / 2.0 - uc[has]).max() <= 1.0
    assert np.abs(frame.color_rgb[..., 1][has] / 3.0 - vc[has]).max() <= 1.0


def test_accel_and_gyro_become_one_imu_stream_counted(recorded) -> None:
    import yaml

    _, stamps, path = recorded
    session = open_session(path)
    report = yaml.safe_load((path / "conversion_report.yaml").read_text())
    streams = {s["stream"]: s for s in report["streams"]}
    gyro, accel = streams["gyro"], streams["accel"]
    assert gyro["found"] == stamps["gyro"].size and accel["found"] == stamps["accel"].size
    assert gyro["found"] == gyro["used"] + sum(gyro["dropped"].values())
    # gyro stamps outside the accel's span are dropped, counted
    inside = (stamps["gyro"] >= stamps["accel"][0]) & (stamps["gyro"] <= stamps["accel"][-1])
    assert len(session.imu) == gyro["used"] == int(inside.sum())
    np.testing.assert_allclose(session.imu.t_s, stamps["gyro"][inside], rtol=0, atol=1e-6)
    np.testing.assert_allclose(session.imu.accel_m_s2, np.tile(ACCEL, (len(session.imu), 1)),
                               atol=1e-5)  # fmt: skip
    np.testing.assert_allclose(
        session.imu.gyro_rad_s, gyro_at(stamps["gyro"][inside] - T0_S), atol=1e-6
    )
    assert any("no depth→IMU extrinsics" in n for n in report["notes"])


def test_imu_extrinsics_from_the_conversion_config(recorded, tmp_path: Path) -> None:
    """The SDK writes no extrinsics for motion streams: a rotated, offset IMU comes from the
    conversion config's calibration."""
    from graph_slam.config import config_from_dict
    from graph_slam.session.adapters import ConvertConfig

    bag, _, _ = recorded
    camera_T_imu = np.array(
        [[0, -1, 0, 0.02], [0, 0, -1, -0.005], [1, 0, 0, 0.011], [0, 0, 0, 1.0]]
    )
    cfg = config_from_dict(ConvertConfig, {"calibration": {"camera_T_imu": camera_T_imu.tolist()}})
    session = open_session(convert(bag, tmp_path / "s", cfg).path)
    np.testing.assert_allclose(session.calibration.camera_T_imu, camera_T_imu)


def test_recording_cut_short_keeps_what_was_recorded(tmp_path: Path) -> None:
    """Depth stops early (the camera stopped, the IMU went on): every depth frame recorded is
    kept, IMU samples after the last frame too."""
    stamps = _record(tmp_path / "short.db3", depth_until_s=0.1)
    session = open_session(convert(tmp_path / "short.db3", tmp_path / "s").path)
    assert session.n_frames == stamps["depth"].size == 9
    assert session.imu.t_s[-1] > session.frame_times_s[-1] + 0.15


def test_truncated_file_is_a_clear_error(recorded, tmp_path: Path) -> None:
    bag, _, _ = recorded
    cut = tmp_path / "cut.db3"
    cut.write_bytes(bag.read_bytes()[: bag.stat().st_size // 3])
    with pytest.raises(BagError, match=r"cut\.db3: cannot read the bag"):
        convert(cut, tmp_path / "s")
    assert not (tmp_path / "s").exists()


def test_empty_recording_is_refused_naming_the_depth_topic(tmp_path: Path) -> None:
    _record(tmp_path / "empty.db3", frames=False)
    with sqlite3.connect(tmp_path / "empty.db3") as db:  # the SDK wrote its header only
        assert db.execute("select count(*) from messages").fetchone()[0] > 0
    with pytest.raises(
        MissingStreamError, match=r"empty\.db3: no depth topic found.*without frames"
    ):
        convert(tmp_path / "empty.db3", tmp_path / "s")


def test_depth_only_recording_converts_without_colour(tmp_path: Path) -> None:
    stamps = _record(tmp_path / "d.db3", _device(color=None))
    session = open_session(convert(tmp_path / "d.db3", tmp_path / "s").path)
    assert session.n_frames == stamps["depth"].size and session.n_color_frames == 0
    assert not session.manifest.sensors.camera.has_color


def test_sdk_test_recording_ros1_converts_to_its_two_depth_frames(tmp_path: Path) -> None:
    """librealsense's own test recording: 2 depth frames, 1 colour frame 268 ms away."""
    bag = shared_data("realsense_sdk/single_depth_color_640x480.bag")
    result = convert(bag, tmp_path / "s")
    session = open_session(result.path)
    assert session.n_frames == 2 and session.n_color_frames == 0
    assert result.report.stream("frames").depth_only == 2
    assert validate_session(result.path).ok

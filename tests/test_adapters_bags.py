"""ROS 1 and ROS 2 bags written by rosbags' own writers → sessions; presets; every bad input."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from adapter_helpers import tree_digest
from bagfactory import (
    CX,
    CY,
    EVENT_TOPIC,
    FRAME_NS,
    FX,
    FY,
    T0_NS,
    BagSpec,
    accel_at,
    ankle_at,
    color_rgb,
    depth_raw,
    gyro_at,
    knee_at,
    write_bag,
)

from graph_slam.cli import main
from graph_slam.config import config_from_dict, load_config
from graph_slam.errors import BagError, ConversionError, DepthUnitsError, MissingStreamError
from graph_slam.session import open_session, session_info, validate_session
from graph_slam.session.adapters import ConvertConfig, convert
from graph_slam.session.adapters.config import BagConfig
from graph_slam.session.adapters.rosbag import resolve_topics

pytest.importorskip("rosbags")

T0_S = T0_NS * 1e-9


def _cfg(**bag) -> ConvertConfig:
    return config_from_dict(ConvertConfig, {"bag": bag})


@pytest.fixture(scope="module")
def sdk_bag(tmp_path_factory) -> tuple[Path, object]:
    path = tmp_path_factory.mktemp("bags") / "sdk.bag"
    return path, write_bag(path, BagSpec(depth_units_option=1e-4, motion_sensor=3, depth_scale=10))


@pytest.fixture(scope="module")
def ros2_bag(tmp_path_factory) -> tuple[Path, object]:
    path = tmp_path_factory.mktemp("bags") / "wrapper_db3"
    spec = BagSpec(ros2=True, layout="ros", imu="combined", color_encoding="bgr8")
    return path, write_bag(path, spec)


def _streams(path: Path) -> dict:
    return {s.name: s for s in session_info(open_session(path)).streams}


# --------------------------------------------------------------------------- ROS 1, SDK preset
def test_ros1_realsense_sdk_bag_converts_with_known_answers(sdk_bag, tmp_path: Path) -> None:
    bag, truth = sdk_bag
    before = tree_digest(bag)
    cfg = _cfg(joint_states_topic="/prosthesis/joint_states", gait_events_topic=EVENT_TOPIC)
    result = convert(bag, tmp_path / "s", cfg)
    assert tree_digest(bag) == before  # the source is never modified
    assert validate_session(result.path).ok
    session = open_session(result.path)
    # Depth units from the bag's 'Depth Units' option (1e-4): raw × 1e-4, lossless in the session.
    assert session.depth_unit_m == pytest.approx(1e-4)
    assert session.intrinsics.fx_px == FX and session.intrinsics.cy_px == CY
    assert session.n_frames == 8
    for k, frame in enumerate(session):
        # float64 seconds near 1.7e9 s resolve 0.24 µs
        assert frame.t_s == pytest.approx((T0_NS + k * FRAME_NS) * 1e-9, abs=5e-7)
        np.testing.assert_allclose(frame.depth_m, depth_raw(k) * 10 * 1e-4, rtol=1e-6)
        assert frame.color_rgb is None  # SDK colour is not registered to depth
    # Separate streams, accel at 62.5 Hz on sensor_3 found by pattern, interpolated at the gyro
    # stamps (linear in time, so exactly); gyro samples outside the accel span dropped, counted.
    imu = session.imu
    inside = (truth.gyro_ns >= truth.accel_ns[0]) & (truth.gyro_ns <= truth.accel_ns[-1])
    assert len(imu) == int(inside.sum()) == 61
    t_rel = (truth.gyro_ns[inside] - T0_NS) * 1e-9  # exact relative times of the kept samples
    np.testing.assert_allclose(imu.t_s, truth.gyro_ns[inside] * 1e-9, rtol=0, atol=5e-7)
    np.testing.assert_allclose(imu.accel_m_s2, accel_at(t_rel), atol=1e-12)
    np.testing.assert_allclose(imu.gyro_rad_s, gyro_at(t_rel), atol=1e-12)
    gyro = result.report.stream("gyro")
    assert (gyro.found, gyro.used) == (69, 61)
    assert gyro.dropped["before the other stream starts"] == 2
    assert gyro.dropped["after the other stream ends"] == 6
    color = result.report.stream("color")
    assert (color.found, color.used) == (7, 0)
    # Joints by name (the message order is ankle, knee, hip), radians.
    joints = session.joints
    t_rel = (truth.joint_ns - T0_NS) * 1e-9
    np.testing.assert_allclose(joints.knee_rad, knee_at(t_rel), atol=1e-12)
    np.testing.assert_allclose(joints.ankle_rad, ankle_at(t_rel), atol=1e-12)
    # Events: 'heel_strike' maps to foot_strike, 'mid_stance' is dropped and counted.
    assert session.events.kind == ("foot_strike", "toe_off", "foot_strike")
    np.testing.assert_allclose(
        session.events.t_s, T0_S + np.array([0.05, 0.15, 0.25]), rtol=0, atol=5e-7
    )
    assert result.report.stream("events").dropped == {
        "unmapped value 'mid_stance'": 1,
        "duplicate stamp": 0,
    }
    assert all(s.balanced for s in result.report.streams)


def test_resolved_config_reproduces_the_conversion(sdk_bag, tmp_path: Path) -> None:
    bag, _ = sdk_bag
    first = convert(bag, tmp_path / "a", _cfg(joint_states_topic="/prosthesis/joint_states"))
    resolved = load_config(ConvertConfig, first.config_path)
    assert resolved.bag.preset == "realsense-sdk"
    assert resolved.bag.gyro_topic == "/device_0/sensor_3/Gyro_0/imu/data"
    assert resolved.bag.depth_unit_m == pytest.approx(1e-4)
    assert yaml.safe_load(first.report_path.read_text())["adapter"] == "rosbag"
    again = convert(bag, tmp_path / "b", resolved)
    for name in ("frames.csv", "imu.csv", "joints.csv"):
        assert (first.path / name).read_text() == (again.path / name).read_text()


# --------------------------------------------------------------------------- ROS 2, wrapper preset
def test_ros2_wrapper_bag_registered_colour_and_combined_imu(ros2_bag, tmp_path: Path) -> None:
    bag, truth = ros2_bag
    before = tree_digest(bag)
    result = convert(bag, tmp_path / "s")
    assert tree_digest(bag) == before
    session = open_session(result.path)
    assert validate_session(result.path).ok
    # Frame 3 has no colour image → kept depth-only and counted; colour bgr8 → RGB.
    assert session.n_frames == 8 and session.n_color_frames == 7
    for k, frame in enumerate(session):
        if k == 3:
            assert frame.color_rgb is None
        else:
            assert np.array_equal(frame.color_rgb, color_rgb(k))
        np.testing.assert_allclose(frame.depth_m, depth_raw(k) * 1e-3, rtol=1e-6)
    frames_report = result.report.stream("frames")
    assert frames_report.depth_only == 1 and not frames_report.dropped.get(
        "no colour image within 0.02 s"
    )
    assert session.intrinsics.cx_px == CX and session.intrinsics.fy_px == FY
    np.testing.assert_allclose(session.imu.t_s, truth.imu_ns * 1e-9, rtol=0, atol=5e-7)
    t_rel = (truth.imu_ns - T0_NS) * 1e-9
    np.testing.assert_allclose(session.imu.accel_m_s2, accel_at(t_rel), atol=1e-12)
    assert len(session.joints) == 26  # /joint_states found by the preset
    assert session.events is None  # the gait-event topic is opt-in


def test_ros2_mcap_with_separate_accel_gyro(tmp_path: Path) -> None:
    bag = tmp_path / "wrapper_mcap"
    spec = BagSpec(ros2=True, storage="mcap", layout="ros", imu="separate", joints=False)
    truth = write_bag(bag, spec)
    result = convert(bag / "wrapper_mcap.mcap", tmp_path / "s", _cfg(imu={"time_base": "accel"}))
    imu = open_session(result.path).imu
    # On the accel time base every accel sample lies inside the gyro span: all 20 kept.
    np.testing.assert_allclose(imu.t_s, truth.accel_ns * 1e-9, rtol=0, atol=5e-7)
    np.testing.assert_allclose(imu.gyro_rad_s, gyro_at((truth.accel_ns - T0_NS) * 1e-9), atol=1e-12)
    gyro = result.report.stream("gyro")
    assert gyro.found == 69 and gyro.balanced and result.report.stream("accel").used == 20


def test_cli_convert_then_info_numbers(ros2_bag, tmp_path: Path, capsys) -> None:
    bag, _ = ros2_bag
    overrides = tmp_path / "overrides.yaml"
    overrides.write_text(f"bag:\n  gait_events_topic: {EVENT_TOPIC}\n")
    with pytest.raises(SystemExit) as exc:
        main(["convert", str(bag), str(tmp_path / "s"), "--preset", "realsense-ros",
              "--config", str(overrides)])  # fmt: skip
    assert exc.value.code == 0
    capsys.readouterr()
    with pytest.raises(SystemExit) as exc:
        main(["info", str(tmp_path / "s")])
    out = capsys.readouterr().out
    rows = {line.split("│")[1].strip(): line for line in out.splitlines() if line.count("│") > 5}
    assert "│ 8 " in rows["frames"] and "30.00" in rows["frames"]  # median rate 30 Hz
    assert "│ 51 " in rows["imu"] and "200.00" in rows["imu"]
    assert "│ 26 " in rows["joints"] and "100.00" in rows["joints"]
    assert "0 complete (2 foot strikes, 1 toe-offs)" not in out  # 2 strikes → 1 stride
    assert "1 complete (2 foot strikes, 1 toe-offs)" in out
    assert (tmp_path / "s" / "conversion.yaml").is_file()


# --------------------------------------------------------------------------- topic resolution
SDK_TOPICS = {
    "/device_0/sensor_0/Depth_0/image/data": "sensor_msgs/msg/Image",
    "/device_0/sensor_0/Depth_0/info/camera_info": "sensor_msgs/msg/CameraInfo",
    "/device_0/sensor_1/Color_0/image/data": "sensor_msgs/msg/Image",
    "/device_0/sensor_4/Accel_0/imu/data": "sensor_msgs/msg/Imu",
    "/device_0/sensor_5/Gyro_0/imu/data": "sensor_msgs/msg/Imu",
}


def test_sdk_preset_finds_motion_topics_at_any_sensor_index() -> None:
    choice = resolve_topics(SDK_TOPICS, BagConfig())
    assert choice.preset == "realsense-sdk"
    assert choice.accel == "/device_0/sensor_4/Accel_0/imu/data"
    assert choice.gyro == "/device_0/sensor_5/Gyro_0/imu/data"
    assert not choice.color_registered


def test_two_devices_need_an_explicit_topic() -> None:
    topics = dict(SDK_TOPICS)
    topics["/device_1/sensor_0/Depth_0/image/data"] = "sensor_msgs/msg/Image"
    with pytest.raises(ConversionError, match=r"several depth topics.*bag\.depth_topic"):
        resolve_topics(topics, BagConfig())
    choice = resolve_topics(topics, BagConfig(depth_topic="/device_0/sensor_0/Depth_0/image/data"))
    assert choice.accel == "/device_0/sensor_4/Accel_0/imu/data"


def test_wrapper_raw_depth_is_not_registered_to_colour() -> None:
    topics = {
        "/camera/depth/image_rect_raw": "sensor_msgs/msg/Image",
        "/camera/depth/camera_info": "sensor_msgs/msg/CameraInfo",
        "/camera/color/image_raw": "sensor_msgs/msg/Image",
        "/camera/imu": "sensor_msgs/msg/Imu",
    }
    choice = resolve_topics(topics, BagConfig())
    assert (choice.preset, choice.camera_info, choice.imu) == (
        "realsense-ros",
        "/camera/depth/camera_info",
        "/camera/imu",
    )
    assert choice.color == "/camera/color/image_raw" and not choice.color_registered


def test_wrong_message_type_is_named() -> None:
    topics = dict(SDK_TOPICS)
    topics["/device_0/sensor_1/Color_0/image/data"] = "sensor_msgs/msg/PointCloud2"
    with pytest.raises(ConversionError, match=r"Color_0/image/data \(color\) has message type"):
        resolve_topics(topics, BagConfig())


# --------------------------------------------------------------------------- bad input
def test_missing_topic_lists_the_topics_found(sdk_bag, tmp_path: Path) -> None:
    bag, _ = sdk_bag
    with pytest.raises(
        MissingStreamError, match=r"'/nope' is not in the bag; topics found: .*Depth_0"
    ):
        convert(bag, tmp_path / "s", _cfg(imu_topic="/nope"))
    with pytest.raises(MissingStreamError, match=r"no depth topic found .*Gyro_0/imu/data"):
        convert(bag, tmp_path / "s", _cfg(preset="realsense-ros"))
    assert not (tmp_path / "s").exists()


def test_truncated_ros1_bag_is_a_clear_error_with_hint(sdk_bag, tmp_path: Path) -> None:
    bag, _ = sdk_bag
    cut = tmp_path / "cut.bag"
    data = bag.read_bytes()
    cut.write_bytes(data[: len(data) // 2])
    with pytest.raises(BagError, match=r"cut\.bag: cannot read the bag .*rosbag reindex"):
        convert(cut, tmp_path / "s")


def test_unindexed_ros1_bag_is_a_clear_error_with_hint(sdk_bag, tmp_path: Path) -> None:
    bag, _ = sdk_bag
    data = bytearray(bag.read_bytes())
    at = data.index(b"index_pos=") + len(b"index_pos=")
    data[at : at + 8] = bytes(8)  # an interrupted recording never writes its index position
    unindexed = tmp_path / "unindexed.bag"
    unindexed.write_bytes(bytes(data))
    with pytest.raises(BagError, match=r"no index .*rosbag reindex unindexed\.bag"):
        convert(unindexed, tmp_path / "s")
    active = tmp_path / "walk.bag.active"
    active.write_bytes(bytes(data))
    with pytest.raises(BagError, match=r"unfinished recording .*rosbag reindex walk\.bag\.active"):
        convert(active, tmp_path / "s")


def test_truncated_db3_is_a_clear_error_with_hint(tmp_path: Path) -> None:
    bag = tmp_path / "d"
    write_bag(bag, BagSpec(ros2=True, layout="ros", n_frames=2, imu="none"))
    data = (bag / "d.db3").read_bytes()
    (bag / "d.db3").write_bytes(data[: len(data) // 2])
    with pytest.raises(BagError, match=r"database disk image is malformed.*\.recover"):
        convert(bag, tmp_path / "s")


def test_truncated_mcap_and_missing_metadata(tmp_path: Path) -> None:
    bag = tmp_path / "m"
    write_bag(bag, BagSpec(ros2=True, storage="mcap", layout="ros", n_frames=2, imu="none"))
    data = (bag / "m.mcap").read_bytes()
    (bag / "m.mcap").write_bytes(data[: len(data) // 2])
    with pytest.raises(BagError, match=r"mcap recover"):
        convert(bag, tmp_path / "s")
    (bag / "metadata.yaml").unlink()
    with pytest.raises(BagError, match=r"without metadata\.yaml; `ros2 bag reindex"):
        convert(bag, tmp_path / "s", _cfg())


def test_float_depth_in_millimetres_is_detected(tmp_path: Path) -> None:
    bag = tmp_path / "mm.bag"
    # 32FC1 must be metres (REP 118); these values are millimetres (×1000).
    write_bag(bag, BagSpec(depth_encoding="32FC1", depth_scale=1000.0, imu="none", joints=False))
    with pytest.raises(
        DepthUnitsError, match=r"median valid depth .* is 13\d\d m.*millimetres.*float_depth_unit_m"
    ):
        convert(bag, tmp_path / "s")
    # Saying so converts it: the values are then metres × 1e-3.
    result = convert(bag, tmp_path / "s", _cfg(float_depth_unit_m=1e-3))
    np.testing.assert_allclose(
        open_session(result.path).frame(0).depth_m[2:], depth_raw(0)[2:] * 1e-3, atol=1.1e-4
    )


def test_float_depth_metres_nan_becomes_no_reading(tmp_path: Path) -> None:
    bag = tmp_path / "m.bag"
    write_bag(bag, BagSpec(depth_encoding="32FC1", imu="none", joints=False, n_frames=3))
    result = convert(bag, tmp_path / "s")
    session = open_session(result.path)
    assert session.depth_unit_m == pytest.approx(2e-4)
    frame = session.frame(1)
    assert np.all(frame.depth_m[:2, :2] == 0)
    np.testing.assert_allclose(frame.depth_m[2:], depth_raw(1)[2:] * 1e-3, atol=1e-4 + 1e-6)
    notes = result.report.stream("frames").notes
    assert any(n.startswith("12 depth pixel(s) NaN") for n in notes)  # 3 frames × 2×2 NaN  # fmt: skip


def test_implausible_explicit_depth_unit(sdk_bag, tmp_path: Path) -> None:
    bag, _ = sdk_bag
    with pytest.raises(DepthUnitsError, match=r"bag\.depth_unit_m.*0\.1 mm \(1e-4 m\)"):
        convert(bag, tmp_path / "s", _cfg(depth_unit_m=1e-6))


def test_missing_rosbags_says_how_to_install(sdk_bag, tmp_path: Path, monkeypatch) -> None:
    bag, _ = sdk_bag
    monkeypatch.setitem(sys.modules, "rosbags.highlevel", None)
    with pytest.raises(ConversionError, match=r"pip install graph_slam\[bags\]"):
        convert(bag, tmp_path / "s")


def test_cli_bag_error_is_one_line_exit_2(tmp_path: Path, capsys) -> None:
    bad = tmp_path / "empty.bag"
    bad.write_bytes(b"")
    with pytest.raises(SystemExit) as exc:
        main(["convert", str(bad), str(tmp_path / "s")])
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and "empty.bag" in err[0]


# --------------------------------------------------------------------------- image decoding
def test_image_array_handles_row_padding_byte_order_and_bgr() -> None:
    from types import SimpleNamespace

    from graph_slam.session.adapters.rosbag import image_array

    depth = (np.arange(12, dtype=np.uint16) * 1000 + 7).reshape(3, 4)
    padded = np.zeros((3, 10), dtype=np.uint8)  # step 10 bytes for 8 bytes of data per row
    padded[:, :8] = np.frombuffer(depth.astype(">u2").tobytes(), np.uint8).reshape(3, 8)
    msg = SimpleNamespace(encoding="mono16", is_bigendian=1, height=3, width=4, step=10,
                          data=padded.ravel())  # fmt: skip
    np.testing.assert_array_equal(image_array(msg, "/d", 0), depth)
    bgr = np.arange(2 * 2 * 3, dtype=np.uint8).reshape(2, 2, 3)
    msg = SimpleNamespace(encoding="bgr8", is_bigendian=0, height=2, width=2, step=6,
                          data=bgr.ravel())  # fmt: skip
    np.testing.assert_array_equal(image_array(msg, "/c", 0), bgr[:, :, ::-1])
    msg = SimpleNamespace(encoding="16UC1", is_bigendian=0, height=3, width=4, step=8,
                          data=np.zeros(20, np.uint8))  # fmt: skip
    with pytest.raises(
        ConversionError, match=r"/d, message 5: 4×3 16UC1 image with step 8 needs 24"
    ):
        image_array(msg, "/d", 5)
    msg = SimpleNamespace(encoding="yuv422", is_bigendian=0, height=1, width=1, step=2, data=b"ab")
    with pytest.raises(ConversionError, match=r"encoding 'yuv422' is not supported"):
        image_array(msg, "/c", 0)

"""Unaligned colour registered to depth, extrinsics and IMU intrinsics from the bag, compressed
image topics: SDK and ROS-wrapper layouts written by rosbags, with analytic truth."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from bagfactory import (
    CCX,
    CCY,
    CFX,
    CFY,
    CH,
    CW,
    CX,
    CY,
    FX,
    FY,
    IMU_INTRINSIC,
    BagSpec,
    H,
    W,
    camera_T_imu,
    color_rgb,
    color_T_depth,
    depth_raw,
    write_bag,
)

from graph_slam.config import config_from_dict, load_config
from graph_slam.errors import CompressedImageError, ConversionError
from graph_slam.session import open_session
from graph_slam.session.adapters import ConvertConfig, convert
from graph_slam.session.adapters.align import CameraModel, align_color_to_depth

pytest.importorskip("rosbags")

DISTORTION = (0.05, -0.02, 0.001, -0.001, 0.0)
CASES = {
    "sdk": BagSpec(color_mode="unaligned", extrinsics=True, missing_color=(3,)),
    "ros1": BagSpec(layout="ros", color_mode="unaligned", extrinsics=True,
                    color_distortion=DISTORTION),
    "ros2": BagSpec(ros2=True, layout="ros", color_mode="unaligned", extrinsics=True,
                    imu="combined", compressed_color="png"),
}  # fmt: skip


def _bag(tmp_path: Path, name: str) -> Path:
    path = tmp_path / (name + (".bag" if not CASES[name].ros2 else ""))
    write_bag(path, CASES[name])
    return path


def _decoded_pixel_error(color: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """|decoded depth pixel − actual pixel| in u and v, where the pixel has colour."""
    has = color.any(-1)
    v, u = np.mgrid[0:H, 0:W]
    return np.abs(color[..., 0] / 7.0 - u)[has], np.abs(color[..., 1] / 9.0 - v)[has]


@pytest.mark.parametrize("name", sorted(CASES))
def test_unaligned_colour_lands_on_the_right_depth_pixels(name: str, tmp_path: Path) -> None:
    result = convert(_bag(tmp_path, name), tmp_path / "s")
    session = open_session(result.path)
    assert session.n_frames == 8  # frame 3 has no colour image: kept depth-only, counted
    assert result.report.stream("frames").depth_only == 1
    color = result.report.stream("color")
    assert (color.found, color.used) == (7, 7) and color.balanced
    for frame in session:
        if frame.color_rgb is None:
            assert frame.index == 3
            continue
        assert frame.color_rgb.shape == (H, W, 3)
        du, dv = _decoded_pixel_error(frame.color_rgb)
        assert du.size == H * W  # the colour camera sees the whole plane
        assert du.max() <= 1.0 and dv.max() <= 1.0  # within 1 px (measured: 0.43, 0.44)
    assert any("colour registered to depth" in n for n in result.report.notes)


@pytest.mark.parametrize("name", sorted(CASES))
def test_extrinsics_read_from_the_bag_equal_the_written_ones(name: str, tmp_path: Path) -> None:
    result = convert(_bag(tmp_path, name), tmp_path / "s")
    cal = result.report.calibration
    np.testing.assert_allclose(cal["color_T_depth"]["value"], color_T_depth(), atol=1e-9)
    np.testing.assert_allclose(cal["camera_T_imu"]["value"], camera_T_imu(), atol=1e-9)
    session = open_session(result.path)
    np.testing.assert_allclose(session.calibration.camera_T_imu, camera_T_imu(), atol=1e-9)
    assert cal["camera_T_imu"]["source"].startswith("bag (")
    assert cal["thigh_T_camera"]["source"] == "default"
    if name == "sdk":
        assert "/tf/0" in cal["camera_T_imu"]["source"]
        for role in ("accel", "gyro"):
            np.testing.assert_allclose(cal[f"camera_T_{role}"]["value"], camera_T_imu(), atol=1e-9)
            intr = cal[f"{role}_intrinsics"]
            np.testing.assert_allclose(intr["scale_misalignment"], IMU_INTRINSIC[:, :3], atol=1e-7)
            np.testing.assert_allclose(intr["bias"], IMU_INTRINSIC[:, 3], atol=1e-7)
            assert intr["applied"] is False
    else:
        assert "/tf_static" in cal["camera_T_imu"]["source"]


def test_config_overrides_the_bag_and_the_report_says_so(tmp_path: Path) -> None:
    mine = np.eye(4)
    mine[:3, 3] = [0.1, 0.2, 0.3]
    cfg = config_from_dict(ConvertConfig, {"calibration": {"camera_T_imu": mine.tolist()}})
    result = convert(_bag(tmp_path, "sdk"), tmp_path / "s", cfg)
    entry = result.report.calibration["camera_T_imu"]
    assert entry["source"] == "config" and entry["overrides"].startswith("bag (")
    np.testing.assert_allclose(open_session(result.path).calibration.camera_T_imu, mine)


def test_colour_without_extrinsics_is_dropped_and_counted(tmp_path: Path) -> None:
    bag = tmp_path / "noext.bag"
    write_bag(bag, BagSpec(color_mode="unaligned", extrinsics=False, imu="none", joints=False))
    result = convert(bag, tmp_path / "s")
    color = result.report.stream("color")
    assert color.used == 0 and color.balanced
    (reason,) = color.dropped
    assert "no depth→colour extrinsics" in reason
    assert open_session(result.path).frame(0).color_rgb is None
    assert result.report.calibration["camera_T_imu"]["source"] == "default"


def test_resolved_config_repeats_colour_registration_with_depth_distortion(
    tmp_path: Path,
) -> None:
    """conversion.yaml keeps the depth camera's distortion (by not freezing pinhole intrinsics):
    converting again from it registers colour exactly as the first run did."""
    bag = tmp_path / "dist.bag"
    write_bag(bag, BagSpec(layout="ros", color_mode="unaligned", extrinsics=True,
                           depth_distortion=(0.08, -0.03, 0.002, -0.001, 0.0)))  # fmt: skip
    first = convert(bag, tmp_path / "a")
    resolved = load_config(ConvertConfig, tmp_path / "a" / "conversion.yaml")
    assert resolved.bag.intrinsics is None
    assert resolved.bag.camera_info_topic.endswith("/depth/camera_info")
    again = convert(bag, tmp_path / "b", resolved)
    intr = dict(width_px=W, height_px=H, fx_px=FX, fy_px=FY, cx_px=CX, cy_px=CY)
    pinhole = config_from_dict(ConvertConfig, {"bag": {"intrinsics": intr}})
    undistorted = convert(bag, tmp_path / "c", pinhole)
    differs = 0
    for a, b, c in zip(open_session(first.path), open_session(again.path),
                       open_session(undistorted.path), strict=True):  # fmt: skip
        np.testing.assert_array_equal(a.color_rgb, b.color_rgb)
        if a.color_rgb is None:  # frame 3 has no colour image: depth-only
            continue
        differs += int((a.color_rgb != c.color_rgb).any(-1).sum())
    assert differs > 0  # the pinhole model (the old conversion.yaml) registers differently


def test_colour_registration_counts_are_in_the_manifest(tmp_path: Path) -> None:
    result = convert(_bag(tmp_path, "sdk"), tmp_path / "s")
    (note,) = [n for n in result.report.stream("frames").notes if "colour registered" in n]
    assert "depth pixel(s) with a reading project outside" in note
    notes = open_session(result.path).manifest.provenance.notes
    assert f"frames: {note}" in notes


# --------------------------------------------------------------------------- compressed
@pytest.mark.parametrize("kind", ["png", "jpeg"])
def test_compressed_colour_and_depth_round_trip(kind: str, tmp_path: Path) -> None:
    bag = tmp_path / "c.bag"
    write_bag(bag, BagSpec(layout="ros", compressed_color=kind, compressed_depth=True))
    result = convert(bag, tmp_path / "s")
    session = open_session(result.path)
    for k, frame in enumerate(session):
        np.testing.assert_allclose(frame.depth_m, depth_raw(k) * 1e-3, rtol=1e-6)  # PNG: exact
        if k == 3:  # no colour image: depth-only
            assert frame.color_rgb is None
            continue
        err = np.abs(frame.color_rgb.astype(int) - color_rgb(k))
        if kind == "png":
            assert err.max() == 0
        else:
            assert err.mean() < 4.0  # JPEG quality 95, 4:4:4 (measured mean below 1.5)


def test_corrupt_compressed_message_is_an_error_naming_topic_and_index(tmp_path: Path) -> None:
    bag = tmp_path / "bad.bag"
    write_bag(bag, BagSpec(layout="ros", compressed_color="png", corrupt_color_message=2))
    with pytest.raises(
        CompressedImageError, match=r"color/image_raw/compressed, message 2 .*corrupt or truncated"
    ):
        convert(bag, tmp_path / "s")
    assert not (tmp_path / "s").exists()


def test_compressed_colour_of_another_size_is_an_error_naming_topic_and_index(
    tmp_path: Path,
) -> None:
    bag = tmp_path / "odd.bag"
    write_bag(bag, BagSpec(layout="ros", compressed_color="png", odd_size_color_message=2))
    with pytest.raises(
        ConversionError, match=r"color/image_raw/compressed, message 2: .*\(22, 32, 3\)"
    ):
        convert(bag, tmp_path / "s")
    assert not (tmp_path / "s").exists()


def test_rvl_compressed_depth_is_refused_by_name() -> None:
    from types import SimpleNamespace

    from graph_slam.session.adapters.bag_images import compressed_array

    msg = SimpleNamespace(format="16UC1; compressedDepth rvl", data=np.zeros(20, np.uint8))
    with pytest.raises(CompressedImageError, match=r"/d, message 4 .*RVL compressedDepth"):
        compressed_array(msg, "/d", 4, "depth")


# --------------------------------------------------------------------------- the pure function
def test_align_counts_pixels_outside_and_without_depth() -> None:
    depth = np.full((H, W), 1.0, dtype=np.float32)
    depth[:2, :3] = 0.0  # 6 pixels without a reading
    dcam = CameraModel(W, H, FX, FY, CX, CY)
    ccam = CameraModel(CW, CH, CFX, CFY, CCX, CCY)
    c_T_d = np.eye(4)
    c_T_d[0, 3] = 0.3  # 0.3 m sideways at 1 m: the colour image misses part of the depth image
    color = np.zeros((CH, CW, 3), np.uint8)
    color[..., 0] = np.arange(CW)[None, :]
    out = align_color_to_depth(depth, color, dcam, ccam, c_T_d)
    # Independent pinhole arithmetic: column u lands at CFX (x + 0.3) + CCX.
    u = np.arange(W)
    cu = np.floor(CFX * ((u - CX) / FX + 0.3) + CCX + 0.5)
    inside_cols = (cu >= 0) & (cu < CW)
    assert out.no_depth == 6
    assert out.outside == int((~inside_cols).sum()) * H - int((~inside_cols[:3]).sum()) * 2
    np.testing.assert_array_equal(out.color_rgb[5, inside_cols, 0], cu[inside_cols])
    assert not out.has_color[:2, :3].any() and not out.has_color[:, ~inside_cols].any()


def test_unsupported_distortion_model_is_named() -> None:
    cam = CameraModel(4, 3, 1.0, 1.0, 1.5, 1.0, "kannala_brandt4", (0.1, 0, 0, 0))
    with pytest.raises(ConversionError, match=r"'kannala_brandt4' .* not supported"):
        cam.project(np.array([[0.0, 0.0, 1.0]]))


def test_distortion_project_and_deproject_are_inverse() -> None:
    for model in ("plumb_bob", "inverse_brown_conrady"):
        cam = CameraModel(CW, CH, CFX, CFY, CCX, CCY, model, DISTORTION)
        rng = np.random.default_rng(0)
        uv = rng.uniform([0, 0], [CW - 1, CH - 1], size=(50, 2))
        back = cam.project(cam.rays(uv[:, 0], uv[:, 1]) * 1.7)
        np.testing.assert_allclose(back, uv, atol=1e-9)

"""TUM RGB-D folders: the real fr1/xyz frames (4 in tests/data, 10 in ../shared/data)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from adapter_helpers import FR1_XYZ_DEPTH_STAMPS, FR1_XYZ_RGB_STAMPS, tree_digest
from conftest import TEST_DATA, shared_data
from PIL import Image

from graph_slam.config import config_from_dict
from graph_slam.errors import ConversionError, DepthUnitsError, ImageError, MissingStreamError
from graph_slam.session import io, open_session, session_info, validate_session
from graph_slam.session.adapters import ConvertConfig, convert
from graph_slam.session.adapters.tum import camera_from_folder_name

MINI = TEST_DATA / "tum_fr1_xyz_mini"
FR1 = (517.3, 516.5, 318.6, 255.3)


def _cfg(**sections) -> ConvertConfig:
    return config_from_dict(ConvertConfig, sections)


def test_mini_folder_converts_with_tum_association(tmp_path: Path) -> None:
    before = tree_digest(MINI)
    result = convert(MINI, tmp_path / "s")
    assert tree_digest(MINI) == before  # the source is never modified
    assert validate_session(result.path).ok
    session = open_session(result.path)
    k = session.intrinsics
    assert (k.width_px, k.height_px, k.fx_px, k.fy_px, k.cx_px, k.cy_px) == (640, 480, *FR1)
    assert session.depth_unit_m == pytest.approx(1 / 5000)
    # One-to-one nearest pairing within 20 ms, smallest difference first (associate.py):
    # depth 0↔rgb 0 (14.9 ms), depth 2↔rgb 1 (15.5 ms), depth 3↔rgb 3 (12.4 ms); depth 1 and
    # rgb 2 lose their only candidates to closer pairs and are dropped, counted.
    pairs = [(0, 0), (2, 1), (3, 3)]
    assert session.n_frames == 3
    for frame, (d, c) in zip(session, pairs, strict=True):
        assert frame.t_s == pytest.approx(float(FR1_XYZ_DEPTH_STAMPS[d]), abs=1e-6)
        raw = np.array(Image.open(MINI / "depth" / f"{FR1_XYZ_DEPTH_STAMPS[d]}.png"))
        np.testing.assert_array_equal(np.rint(frame.depth_m * 5000).astype(np.uint16), raw)
        rgb = np.array(Image.open(MINI / "rgb" / f"{FR1_XYZ_RGB_STAMPS[c]}.png"))
        np.testing.assert_array_equal(frame.color_rgb, rgb)
    report = result.report
    assert report.stream("frames").dropped == {"no colour image within 0.02 s": 1}
    assert report.stream("color").dropped == {"no depth frame within 0.02 s": 1}
    # Depth PNG values survive the session unchanged (same 1/5000 m unit).
    raw0 = io.read_png(result.path / "depth" / "000000.png", expect_mode="depth16")
    np.testing.assert_array_equal(
        raw0, np.array(Image.open(MINI / "depth" / f"{FR1_XYZ_DEPTH_STAMPS[0]}.png"))
    )
    # Ground truth: the 4 poses at their own times, and at the frame times where bracketed.
    t_gt, poses_gt = io.read_tum(MINI / "groundtruth.txt")
    np.testing.assert_allclose(session.ground_truth_hf.parent_T_child, poses_gt, atol=1e-8)
    gt = session.ground_truth
    assert len(gt) == 2  # frame 0 (depth 0) is 14.9 ms before the first ground-truth sample
    assert report.stream("ground_truth").dropped["frame outside the ground-truth span"] == 1
    for t, pose in zip(gt.t_s, gt.parent_T_child, strict=True):
        i = int(np.searchsorted(t_gt, t))
        lo, hi = poses_gt[i - 1, :3, 3], poses_gt[i, :3, 3]
        alpha = (t - t_gt[i - 1]) / (t_gt[i] - t_gt[i - 1])
        np.testing.assert_allclose(pose[:3, 3], lo + alpha * (hi - lo), atol=1e-8)
    assert all(s.balanced for s in report.streams)
    info = {s.name: s for s in session_info(session).streams}
    assert info["frames"].count == 3 and info["ground_truth_hf"].count == 4


def _layout_full_tum(src: Path, dst: Path) -> None:
    """The shared 10 frames as a TUM folder: stamped names, rgb.txt, depth.txt, groundtruth.txt."""
    from scipy.spatial.transform import Rotation

    (dst / "rgb").mkdir(parents=True)
    (dst / "depth").mkdir()
    truth = json.loads((src / "ground_truth.json").read_text())
    rgb, depth, gt = (
        ["# timestamp filename"],
        ["# timestamp filename"],
        ["# t tx ty tz qx qy qz qw"],
    )
    for n in range(1, 11):
        r, d = FR1_XYZ_RGB_STAMPS[n - 1], FR1_XYZ_DEPTH_STAMPS[n - 1]
        shutil.copyfile(src / "rgb" / f"{n}.png", dst / "rgb" / f"{r}.png")
        shutil.copyfile(src / "depth" / f"{n}.png", dst / "depth" / f"{d}.png")
        rgb.append(f"{r} rgb/{r}.png")
        depth.append(f"{d} depth/{d}.png")
        pose = np.array(truth[str(n)]["transformation"])
        q = Rotation.from_matrix(pose[:3, :3]).as_quat()
        gt.append(f"{r} " + " ".join(f"{v:.9f}" for v in (*pose[:3, 3], *q)))
    for name, lines in (("rgb.txt", rgb), ("depth.txt", depth), ("groundtruth.txt", gt)):
        (dst / name).write_text("\n".join(lines) + "\n")


def test_shared_ten_frames_as_tum_folder(tmp_path: Path) -> None:
    src = shared_data("tum_fr1_xyz_10")
    folder = tmp_path / "rgbd_dataset_freiburg1_xyz"
    _layout_full_tum(src, folder)
    result = convert(folder, tmp_path / "s")
    session = open_session(result.path)
    assert session.n_frames == 9  # rgb 3 (frame 3 of the copy) has no free depth within 20 ms
    assert result.report.stream("color").used == 9
    truth = json.loads((src / "ground_truth.json").read_text())
    expected = np.array([truth[str(n)]["transformation"] for n in range(1, 11)])
    np.testing.assert_allclose(session.ground_truth_hf.parent_T_child, expected, atol=1e-8)
    assert len(session.ground_truth) == 8  # the first depth frame precedes the ground truth
    info = {s.name: s for s in session_info(session).streams}
    assert info["ground_truth_hf"].median_rate_hz == pytest.approx(31.2, abs=0.1)


def test_accelerometer_is_counted_not_converted(tmp_path: Path) -> None:
    folder = tmp_path / "fr1_copy"
    shutil.copytree(MINI, folder)
    (folder / "accelerometer.txt").write_text(
        "# accelerometer data\n# timestamp ax ay az\n"
        "1305031102.17 -0.05 -9.79 0.46\n1305031102.18 -0.06 -9.80 0.45\n"
    )
    result = convert(folder, tmp_path / "s")
    acc = result.report.stream("accelerometer")
    assert (acc.found, acc.used) == (2, 0) and acc.balanced
    assert open_session(result.path).imu is None


def test_intrinsics_by_name_or_given(tmp_path: Path) -> None:
    assert camera_from_folder_name(Path("rgbd_dataset_freiburg3_long_office")) == "fr3"
    assert camera_from_folder_name(Path("tum_fr1_xyz_10")) == "fr1"
    assert camera_from_folder_name(Path("kitchen")) is None
    folder = tmp_path / "kitchen"
    shutil.copytree(MINI, folder)
    with pytest.raises(ConversionError, match=r"cannot tell the TUM camera .*tum\.camera"):
        convert(folder, tmp_path / "s")
    result = convert(folder, tmp_path / "s", _cfg(tum={"camera": "fr2"}))
    assert open_session(result.path).intrinsics.fx_px == 520.9
    given = {
        "width_px": 640,
        "height_px": 480,
        "fx_px": 500,
        "fy_px": 501,
        "cx_px": 320,
        "cy_px": 240,
    }
    result = convert(folder, tmp_path / "g", _cfg(tum={"intrinsics": given}))
    assert open_session(result.path).intrinsics.fy_px == 501
    assert result.config.tum.intrinsics.fy_px == 501


def test_implausible_depth_scale_is_detected(tmp_path: Path) -> None:
    with pytest.raises(
        DepthUnitsError,
        match=r"median valid depth .* is 1144 m.*TUM \(1/5000 m\) → 1\.14 m",
    ):
        convert(MINI, tmp_path / "s", _cfg(tum={"depth_units_per_m": 5}))
    assert not (tmp_path / "s").exists()


@pytest.mark.parametrize(
    ("line", "error", "match"),
    [
        (
            "1305031102.3 depth/x.png extra",
            ConversionError,
            r"depth\.txt: line 4: expected 2 fields",
        ),
        ("abc depth/x.png", ConversionError, r"line 4: timestamp 'abc' is not a number"),
        ("1305031102.3 depth/x.png", ConversionError, r"line 5: timestamps must strictly increase"),
        ("1305031102.160407 ../../etc/passwd", ConversionError, r"escapes the source folder"),
        ("1305031102.160407 depth/missing.png", ImageError, r"missing\.png: image file is missing"),
    ],
)
def test_bad_tum_lists(tmp_path: Path, line: str, error: type, match: str) -> None:
    folder = tmp_path / "fr1"
    shutil.copytree(MINI, folder)
    lines = (folder / "depth.txt").read_text().splitlines()
    lines[3] = line  # replaces the first data row (line 4)
    (folder / "depth.txt").write_text("\n".join(lines) + "\n")
    with pytest.raises(error, match=match):
        convert(folder, tmp_path / "s")


def test_missing_depth_list_names_what_is_there(tmp_path: Path) -> None:
    folder = tmp_path / "fr1"
    shutil.copytree(MINI, folder)
    (folder / "depth.txt").unlink()
    with pytest.raises(MissingStreamError, match=r"no depth\.txt.*found: .*rgb\.txt"):
        convert(folder, tmp_path / "s", _cfg(format="tum"))

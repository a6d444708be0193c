"""The adapter machinery: registry and detection, time association and interpolation, the
native sources (session, synthetic) with known answers, destination rules, calibration."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from adapter_helpers import tree_digest
from conftest import TEST_DATA
from scipy.spatial.transform import Rotation

from graph_slam.cli import main
from graph_slam.commands.convert import FORMATS, PRESETS
from graph_slam.config import config_from_dict
from graph_slam.errors import ConversionError, DepthUnitsError
from graph_slam.session import open_session
from graph_slam.session.adapters import ADAPTERS, ConvertConfig, convert, select_adapter
from graph_slam.session.adapters.config import BagPreset
from graph_slam.session.adapters.registry import format_names
from graph_slam.session.adapters.timing import (
    associate,
    check_depth_units,
    interpolate_poses,
    merge_accel_gyro,
    order_stamps,
)
from graph_slam.session.synthetic import (
    SyntheticConfig,
    iter_synthetic_frames,
    synthetic_streams,
)

MINI_TUM = TEST_DATA / "tum_fr1_xyz_mini"
EUROC = TEST_DATA / "euroc_v101_2s"


def _cfg(**sections) -> ConvertConfig:
    return config_from_dict(ConvertConfig, sections)


# --------------------------------------------------------------------------- registry
def test_registry_formats_and_cli_choices_agree() -> None:
    from typing import get_args

    assert set(format_names()) == {"auto", *ADAPTERS}
    assert set(FORMATS) == set(format_names())
    assert set(PRESETS) == set(get_args(BagPreset))
    for name, adapter in ADAPTERS.items():
        assert adapter.name == name and adapter.summary


def test_detection_picks_exactly_one_adapter(tmp_path: Path, synthetic_session: Path) -> None:
    assert select_adapter(MINI_TUM).name == "tum"
    assert select_adapter(EUROC).name == "euroc"
    assert select_adapter(synthetic_session).name == "session"
    log = tmp_path / "log.csv"
    log.write_text("t_s,knee_rad,ankle_rad\n0,0,0\n")
    assert select_adapter(log).name == "prosthesis-log"
    assert select_adapter(EUROC / "imu0_data.csv", "euroc").name == "euroc"
    (tmp_path / "x.bag").write_bytes(b"")
    assert select_adapter(tmp_path / "x.bag").name == "rosbag"
    unknown = tmp_path / "notes.txt"
    unknown.write_text("hello")
    with pytest.raises(ConversionError, match=r"not a recognised source; give --format"):
        select_adapter(unknown)
    both = tmp_path / "both"
    shutil.copytree(MINI_TUM, both)
    shutil.copyfile(EUROC / "imu0_data.csv", both / "imu0_data.csv")
    with pytest.raises(ConversionError, match=r"could be any of \['tum', 'euroc'\]"):
        select_adapter(both)
    with pytest.raises(ConversionError, match=r"unknown source format 'kitti'"):
        select_adapter(MINI_TUM, "kitti")


# --------------------------------------------------------------------------- timing
def test_associate_is_one_to_one_smallest_difference_first() -> None:
    depth = np.array([0.00, 0.030, 0.062, 0.100])
    color = np.array([0.012, 0.045, 0.050, 0.300])
    i_d, i_c = associate(depth, color, 0.02)
    # Pairs by increasing |dt|: 0.000↔0.012 and 0.062↔0.050 (12 ms), then 0.030↔0.045 (15 ms);
    # 0.100 and 0.300 have no partner within 20 ms.
    assert list(zip(i_d, i_c, strict=True)) == [(0, 0), (1, 1), (2, 2)]
    i_d, i_c = associate(np.array([0.0, 0.016]), np.array([0.010]), 0.02)
    assert list(zip(i_d, i_c, strict=True)) == [(1, 0)]  # the nearer depth frame wins
    assert associate(np.zeros(0), color, 0.02)[0].size == 0


def test_order_stamps_counts_reordered_and_duplicates() -> None:
    order = order_stamps(np.array([1, 3, 2, 3, 4, 4, 0]))
    assert order.duplicates == 2 and order.reordered == 2  # 2 after a 3, 0 after a 4
    np.testing.assert_array_equal(np.array([1, 3, 2, 3, 4, 4, 0])[order.keep], [0, 1, 2, 3, 4])


def test_merge_accel_gyro_counts_ends_and_gaps() -> None:
    t_gyro = np.arange(0, 1.0, 0.005)
    t_acc = np.r_[np.arange(0.1, 0.5, 0.016), np.arange(0.6, 0.9, 0.016)]  # a 100 ms gap
    accel = np.column_stack([t_acc, 2 * t_acc, np.ones_like(t_acc)])
    gyro = np.column_stack([t_gyro, t_gyro, t_gyro])
    imu, counts = merge_accel_gyro(t_gyro, gyro, t_acc, accel, max_gap_s=0.05)
    assert counts.base_found == 200
    assert counts.base_dropped_start == int(np.sum(t_gyro < t_acc[0]))
    assert counts.base_dropped_end == int(np.sum(t_gyro > t_acc[-1]))
    in_gap = (t_gyro > t_acc[t_acc < 0.5][-1]) & (t_gyro < 0.6)
    assert counts.base_dropped_gap == int(in_gap.sum()) > 0
    assert (
        counts.base_used
        + counts.base_dropped_start
        + counts.base_dropped_end
        + (counts.base_dropped_gap)
        == 200
    )
    assert counts.other_used + counts.other_unused_start + counts.other_unused_end == t_acc.size
    np.testing.assert_allclose(imu.accel_m_s2[:, 0], imu.t_s, atol=1e-12)  # linear: exact


def test_interpolate_poses_known_answer() -> None:
    t = np.array([0.0, 1.0, 3.0])
    rotvec = np.array([[0, 0, 0], [0, 0, 1.0], [0, 0, 2.0]])
    poses = np.tile(np.eye(4), (3, 1, 1))
    poses[:, :3, :3] = Rotation.from_rotvec(rotvec).as_matrix()
    poses[:, :3, 3] = [[0, 0, 0], [1, 0, 0], [1, 2, 0]]
    mask, out = interpolate_poses(t, poses, np.array([-0.1, 0.25, 1.0, 2.0, 3.5]), max_gap_s=1.5)
    np.testing.assert_array_equal(mask, [False, True, True, False, False])  # 1→3 s gap > 1.5 s
    np.testing.assert_allclose(Rotation.from_matrix(out[0, :3, :3]).as_rotvec(), [0, 0, 0.25])
    np.testing.assert_allclose(out[0, :3, 3], [0.25, 0, 0])
    np.testing.assert_allclose(out[1], poses[1], atol=1e-12)


def test_depth_units_check() -> None:
    raw = [np.full((4, 4), 1500.0)]
    assert check_depth_units(raw, 1e-3, where="x", unit_source="s") == pytest.approx(1.5)
    assert check_depth_units([np.zeros((2, 2))], 1.0, where="x", unit_source="s") is None
    with pytest.raises(DepthUnitsError, match=r"x: with 1 m per depth value .* is 1500 m"):
        check_depth_units(raw, 1.0, where="x", unit_source="s")


# --------------------------------------------------------------------------- native sources
def test_synthetic_source_matches_the_synthetic_truth(tmp_path: Path) -> None:
    yaml_path = tmp_path / "synthetic.yaml"
    yaml_path.write_text("duration_s: 0.5\nseed: 4\n")
    result = convert(yaml_path, tmp_path / "s", _cfg(format="synthetic"))
    cfg = SyntheticConfig(duration_s=0.5, seed=4)
    truth = synthetic_streams(cfg)
    session = open_session(result.path)
    np.testing.assert_array_equal(session.imu.gyro_rad_s, truth.imu.gyro_rad_s)
    np.testing.assert_allclose(
        session.ground_truth.parent_T_child, truth.ground_truth.parent_T_child, atol=1e-8
    )
    for read, original in zip(session, iter_synthetic_frames(cfg), strict=True):
        assert np.abs(read.depth_m - original.depth_m).max() <= 0.5 * cfg.depth_unit_m + 1e-6
        assert np.array_equal(read.color_rgb, original.color_rgb)


def test_session_source_reencodes_depth(tmp_path: Path, synthetic_session: Path) -> None:
    before = tree_digest(synthetic_session)
    result = convert(synthetic_session, tmp_path / "s", _cfg(output={"depth_unit_m": 1e-3}))
    assert tree_digest(synthetic_session) == before
    src, dst = open_session(synthetic_session), open_session(result.path)
    assert dst.depth_unit_m == 1e-3 and dst.n_frames == src.n_frames
    np.testing.assert_array_equal(dst.joints.knee_rad, src.joints.knee_rad)
    assert dst.events.kind == src.events.kind
    np.testing.assert_allclose(dst.calibration.camera_T_imu, src.calibration.camera_T_imu)
    diff = np.abs(dst.frame(5).depth_m - src.frame(5).depth_m)
    assert diff.max() <= 0.5e-3 + 1e-6


# --------------------------------------------------------------------------- destinations
def test_destination_rules(tmp_path: Path, synthetic_session: Path) -> None:
    with pytest.raises(ConversionError, match=r"overlaps the source"):
        convert(synthetic_session, synthetic_session / "inside")
    other = tmp_path / "taken"
    other.mkdir()
    (other / "notes.txt").write_text("mine")
    with pytest.raises(ConversionError, match=r"already exists \(pass --overwrite"):
        convert(EUROC, other)
    with pytest.raises(ConversionError, match=r"is not a session; refusing to overwrite"):
        convert(EUROC, other, overwrite=True)
    first = convert(EUROC, tmp_path / "s")
    again = convert(EUROC, tmp_path / "s", overwrite=True)
    assert again.path == first.path and (again.path / "session.yaml").is_file()


def test_failed_conversion_leaves_nothing_behind(tmp_path: Path) -> None:
    with pytest.raises(DepthUnitsError):
        convert(MINI_TUM, tmp_path / "s", _cfg(tum={"depth_units_per_m": 5}))
    assert list(tmp_path.iterdir()) == []


def test_calibration_overrides(tmp_path: Path) -> None:
    camera_T_imu = np.eye(4)
    camera_T_imu[:3, :3] = Rotation.from_euler("x", 90, degrees=True).as_matrix()
    camera_T_imu[:3, 3] = [0.01, 0.02, 0.03]
    cfg = _cfg(calibration={"camera_T_imu": camera_T_imu.tolist(), "imu_time_offset_s": 0.004})
    result = convert(EUROC, tmp_path / "s", cfg)
    calibration = open_session(result.path).calibration
    np.testing.assert_allclose(calibration.camera_T_imu, camera_T_imu, atol=1e-15)
    assert calibration.imu_time_offset_s == 0.004
    assert result.config.calibration.thigh_T_camera == tuple(map(tuple, np.eye(4).tolist()))
    bad = np.eye(4)
    bad[0, 0] = 2.0
    with pytest.raises(ConversionError, match=r"config section 'calibration'.*camera_T_imu"):
        convert(EUROC, tmp_path / "t", _cfg(calibration={"camera_T_imu": bad.tolist()}))


def test_cli_option_errors_exit_2(tmp_path: Path, capsys) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["convert", str(EUROC), str(tmp_path / "s"), "--format", "kitti"])
    assert exc.value.code == 2
    overrides = tmp_path / "o.yaml"
    overrides.write_text("format: tum\n")
    with pytest.raises(SystemExit) as exc:
        main(["convert", str(EUROC), str(tmp_path / "s"), "--format", "euroc",
              "--config", str(overrides)])  # fmt: skip
    assert exc.value.code == 2
    assert "contradicts 'format: tum'" in capsys.readouterr().err
    overrides.write_text("bag: {presset: x}\n")
    with pytest.raises(SystemExit) as exc:
        main(["convert", str(EUROC), str(tmp_path / "s"), "--config", str(overrides)])
    assert exc.value.code == 2
    assert "field 'bag.presset'" in capsys.readouterr().err

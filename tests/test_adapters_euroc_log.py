"""EuRoC IMU + ground truth (real, 2 s in tests/data; 145 s in ../shared/data) and prosthesis
controller logs with a YAML column mapping."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from adapter_helpers import tree_digest
from conftest import TEST_DATA, shared_data

from graph_slam.cli import main
from graph_slam.config import config_from_dict, load_config
from graph_slam.errors import ConversionError, MissingStreamError
from graph_slam.session import io, open_session, session_info, validate_session
from graph_slam.session.adapters import ConvertConfig, convert
from graph_slam.session.adapters.config import LoadColumn
from graph_slam.session.adapters.prosthesis_log import load_cell_events

EUROC = TEST_DATA / "euroc_v101_2s"
MINI_TUM = TEST_DATA / "tum_fr1_xyz_mini"


def _source_imu(path: Path) -> np.ndarray:
    return np.loadtxt(path, delimiter=",", comments="#", dtype=np.float64)


# --------------------------------------------------------------------------- EuRoC
def test_euroc_sample_converts_into_an_imu_session(tmp_path: Path) -> None:
    before = tree_digest(EUROC)
    result = convert(EUROC, tmp_path / "s")
    assert tree_digest(EUROC) == before
    assert validate_session(result.path).ok
    session = open_session(result.path)
    assert session.intrinsics is None and session.n_frames == 0
    source = _source_imu(EUROC / "imu0_data.csv")
    np.testing.assert_array_equal(session.imu.gyro_rad_s, source[:, 1:4])
    np.testing.assert_array_equal(session.imu.accel_m_s2, source[:, 4:7])
    t_gt, poses = io.read_tum(EUROC / "V101_gt.txt")
    np.testing.assert_allclose(session.ground_truth_hf.t_s, t_gt, rtol=0, atol=5e-7)
    np.testing.assert_allclose(session.ground_truth_hf.parent_T_child, poses, atol=1e-8)
    np.testing.assert_array_equal(session.calibration.camera_T_imu, np.eye(4))
    streams = {s.name: s for s in session_info(session).streams}
    assert streams["imu"].count == 400 and streams["imu"].median_rate_hz == pytest.approx(
        200, rel=1e-3
    )
    assert streams["ground_truth_hf"].count == 40
    assert streams["ground_truth_hf"].mean_rate_hz == pytest.approx(20.0, rel=1e-3)
    assert "ground_truth" not in streams


def test_euroc_cli_info_says_no_camera(tmp_path: Path, capsys) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["convert", str(EUROC), str(tmp_path / "s")])
    assert exc.value.code == 0
    capsys.readouterr()
    with pytest.raises(SystemExit):
        main(["info", str(tmp_path / "s")])
    out = capsys.readouterr().out
    assert "schema v1, no camera" in " ".join(out.split())  # rich may wrap the line
    rows = {line.split("│")[1].strip(): line for line in out.splitlines() if line.count("│") > 5}
    assert "│ 400 " in rows["imu"] and "200.00" in rows["imu"] and "│ 0 " in rows["frames"]


def test_asl_layout_with_csv_ground_truth(tmp_path: Path) -> None:
    folder = tmp_path / "V1_01_easy"
    (folder / "mav0" / "imu0").mkdir(parents=True)
    (folder / "mav0" / "state_groundtruth_estimate0").mkdir()
    shutil.copyfile(EUROC / "imu0_data.csv", folder / "mav0" / "imu0" / "data.csv")
    t_gt, poses = io.read_tum(EUROC / "V101_gt.txt")
    from scipy.spatial.transform import Rotation

    q = Rotation.from_matrix(poses[:, :3, :3]).as_quat()  # x y z w
    lines = ["#timestamp, p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], "
             "q_RS_y [], q_RS_z [], v_RS_R_x [m s^-1], v_RS_R_y [m s^-1], v_RS_R_z [m s^-1]"]  # fmt: skip
    for t, pose, quat in zip(t_gt, poses, q, strict=True):
        values = [*pose[:3, 3], quat[3], *quat[:3], 0.0, 0.0, 0.0]
        lines.append(f"{round(t * 1e9)}," + ",".join(f"{v:.12f}" for v in values))
    (folder / "mav0" / "state_groundtruth_estimate0" / "data.csv").write_text(
        "\n".join(lines) + "\n"
    )
    result = convert(folder, tmp_path / "s")
    session = open_session(result.path)
    np.testing.assert_allclose(session.ground_truth_hf.parent_T_child, poses, atol=1e-8)
    assert result.config.euroc.ground_truth == "mav0/state_groundtruth_estimate0/data.csv"
    assert len(session.imu) == 400


def test_euroc_nan_rows_are_dropped_and_counted(tmp_path: Path) -> None:
    folder = tmp_path / "e"
    shutil.copytree(EUROC, folder)
    lines = (folder / "imu0_data.csv").read_text().splitlines()
    fields = lines[10].split(",")
    fields[4] = "nan"
    lines[10] = ",".join(fields)
    lines[11] = lines[12]  # a duplicate stamp
    (folder / "imu0_data.csv").write_text("\n".join(lines) + "\n")
    result = convert(folder, tmp_path / "s")
    imu = result.report.stream("imu")
    assert (imu.found, imu.used) == (400, 398)
    assert imu.dropped == {"NaN or inf": 1, "duplicate stamp": 1}


def test_euroc_bad_input(tmp_path: Path) -> None:
    empty = tmp_path / "empty"
    empty.mkdir()
    (empty / "readme.txt").write_text("x")
    with pytest.raises(MissingStreamError, match=r"no EuRoC IMU file .*found: readme\.txt"):
        convert(empty, tmp_path / "s", config_from_dict(ConvertConfig, {"format": "euroc"}))
    folder = tmp_path / "e"
    shutil.copytree(EUROC, folder)
    lines = (folder / "imu0_data.csv").read_text().splitlines()
    lines[5] = lines[5].rsplit(",", 2)[0]
    (folder / "imu0_data.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(ConversionError, match=r"imu0_data\.csv: line 6: IMU rows have at least 7"):
        convert(folder, tmp_path / "s")


def test_shared_euroc_sequence_converts(tmp_path: Path) -> None:
    src = shared_data("euroc_v101")
    result = convert(src, tmp_path / "s")
    session = open_session(result.path)
    assert len(session.imu) == 29120 and len(session.ground_truth_hf) == 2895
    streams = {s.name: s for s in session_info(session).streams}
    assert streams["imu"].gaps == 0 and streams["imu"].duration_s == pytest.approx(
        145.595, abs=1e-3
    )


# --------------------------------------------------------------------------- prosthesis logs
MAPPING = """
prosthesis_log:
  time: {column: time_ms, unit: ms}
  knee: {column: knee_deg, unit: deg, scale: 1.0, offset: 2.0}
  ankle: {column: ankle_deg, unit: deg, scale: -1.0}
  events: {column: event, values: {HS: foot_strike, TO: toe_off}, ignore: [MS]}
"""


def _write_log(path: Path, *, duration_s: float = 2.0, rate_hz: float = 100.0) -> np.ndarray:
    t = np.arange(round(duration_s * rate_hz)) / rate_hz
    load = 400.0 * np.sin(2 * np.pi * t)  # one stride per second; stance while positive
    rows = ["time_ms,knee_deg,ankle_deg,load_n,event"]
    marks = {10: "HS", 30: "MS", 60: "TO", 110: "HS", 150: "XX"}
    for i, ti in enumerate(t):
        knee, ankle = 20 + 40 * np.sin(2 * np.pi * ti), 5 * np.cos(2 * np.pi * ti)
        rows.append(f"{ti * 1000:.3f},{knee:.6f},{ankle:.6f},{load[i]:.6f},{marks.get(i, '')}")
    path.write_text("\n".join(rows) + "\n")
    return t


def test_prosthesis_log_with_yaml_mapping(tmp_path: Path) -> None:
    log = tmp_path / "controller.csv"
    t = _write_log(log)
    mapping = tmp_path / "mapping.yaml"
    mapping.write_text(MAPPING)
    cfg = load_config(ConvertConfig, mapping)
    result = convert(log, tmp_path / "s", cfg)
    session = open_session(result.path)
    assert session.intrinsics is None and validate_session(result.path).ok
    joints = session.joints
    np.testing.assert_allclose(joints.t_s, t, atol=1e-12)
    knee_deg = np.round(20 + 40 * np.sin(2 * np.pi * t), 6)
    np.testing.assert_allclose(joints.knee_rad, np.deg2rad(knee_deg + 2.0), atol=1e-12)
    ankle_deg = np.round(5 * np.cos(2 * np.pi * t), 6)
    np.testing.assert_allclose(joints.ankle_rad, np.deg2rad(-ankle_deg), atol=1e-12)
    assert session.events.kind == ("foot_strike", "toe_off", "foot_strike")
    np.testing.assert_allclose(session.events.t_s, [0.10, 0.60, 1.10], atol=1e-12)
    assert session.events.source == ("log",) * 3
    events = result.report.stream("events")
    assert events.found == 5 and events.used == 3
    assert events.dropped == {"ignored value": 1, "unmapped value 'XX'": 1}
    assert session_info(session).strides.strides == 1


def test_load_cell_events_known_crossings() -> None:
    t = np.arange(300) / 100.0
    load = 400.0 * np.sin(2 * np.pi * t)
    spec = LoadColumn(column="load", foot_strike_above_n=50.0, toe_off_below_n=20.0)
    times, kinds = load_cell_events(t, load, spec)
    # Rising through 50 N at asin(50/400)/2π (+k s); falling through 20 N at
    # (π − asin(20/400))/2π (+k s). Linear interpolation between 10 ms samples of a
    # 400 N sine: within 0.1 ms.
    strike = np.arcsin(50 / 400) / (2 * np.pi)
    toe_off = (np.pi - np.arcsin(20 / 400)) / (2 * np.pi)
    expected = np.sort(np.r_[strike + np.arange(3), toe_off + np.arange(3)])
    assert kinds == ("foot_strike", "toe_off") * 3
    np.testing.assert_allclose(times, expected, atol=1e-4)


def test_log_merged_into_a_tum_conversion(tmp_path: Path) -> None:
    log = tmp_path / "controller.csv"
    _write_log(log, duration_s=0.2, rate_hz=500.0)
    cfg = config_from_dict(
        ConvertConfig,
        {
            "prosthesis_log": {
                "path": str(log),
                "time": {"column": "time_ms", "unit": "ms"},
                "time_offset_s": 1305031102.1,
                "knee": {"column": "knee_deg", "unit": "deg"},
                "ankle": {"column": "ankle_deg", "unit": "deg"},
                "load": {"column": "load_n", "foot_strike_above_n": 50, "toe_off_below_n": 20},
            }
        },
    )
    result = convert(MINI_TUM, tmp_path / "s", cfg)
    session = open_session(result.path)
    assert session.n_frames == 3 and len(session.joints) == 100
    assert session.joints.t_s[0] == pytest.approx(1305031102.1)
    assert session.events.kind == ("foot_strike",) and session.events.source == ("load_cell",)
    assert any("merged from" in n for n in result.report.notes)


def test_prosthesis_log_bad_input(tmp_path: Path) -> None:
    log = tmp_path / "controller.csv"
    _write_log(log, duration_s=0.1)
    with pytest.raises(
        MissingStreamError, match=r"column 't_s' .* columns: \['time_ms', 'knee_deg'"
    ):
        convert(log, tmp_path / "s")
    lines = log.read_text().splitlines()
    lines[3] = lines[3].replace(lines[3].split(",")[1], "oops", 1)
    log.write_text("\n".join(lines) + "\n")
    mapping = tmp_path / "mapping.yaml"
    mapping.write_text(MAPPING)
    with pytest.raises(ConversionError, match=r"data row 2 \(line 4\), column 'knee_deg': 'oops'"):
        convert(log, tmp_path / "s", load_config(ConvertConfig, mapping))

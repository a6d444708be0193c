"""`graph-slam gait-events`: events CSV out, bad input -> one line and exit code 2."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from graph_slam.cli import main
from graph_slam.session.files import IMU_COLUMNS
from graph_slam.session.io import write_numeric_csv
from kinematics.gait_events import read_events_csv, write_imu_csv
from kinematics.gait_synth import random_mounting, thigh_imu_from_reference
from kinematics.imu import LEGACY_IMU_COLUMNS


def run(argv: list[str]) -> int:
    with pytest.raises(SystemExit) as info:
        main(argv)
    return int(info.value.code or 0)


def test_gait_events_command_writes_events(tmp_path: Path, capsys) -> None:
    sim = thigh_imu_from_reference(1.1, n_strides=4, thigh_R_sensor=random_mounting(8), seed=8)
    imu_csv = write_imu_csv(tmp_path / "imu.csv", sim.imu)
    out = tmp_path / "events.csv"
    assert run(["gait-events", str(imu_csv), "--out", str(out)]) == 0
    events = read_events_csv(out)
    assert events["foot_strike"].size == 4
    assert np.abs(events["foot_strike"] - sim.foot_strikes_s).max() < 0.06
    assert "4 foot strikes" in capsys.readouterr().err


def test_gait_events_to_stdout(tmp_path: Path, capsys) -> None:
    sim = thigh_imu_from_reference(1.4, n_strides=3, seed=3)
    imu_csv = write_imu_csv(tmp_path / "imu.csv", sim.imu)
    assert run(["gait-events", str(imu_csv)]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[0] == "t_s,kind"
    assert sum(line.endswith("foot_strike") for line in lines) == 3


def test_gait_events_reads_a_session_imu_csv_and_the_legacy_header(tmp_path: Path, capsys) -> None:
    """One IMU CSV schema: the session format's imu.csv is the command's input; the old
    unit-less header is still read."""
    sim = thigh_imu_from_reference(1.1, n_strides=4, seed=8)
    data = np.column_stack([sim.imu.t_s, sim.imu.gyro_rad_s, sim.imu.accel_m_s2])
    session_csv = tmp_path / "imu.csv"
    write_numeric_csv(session_csv, IMU_COLUMNS, data)  # as SessionWriter.write_imu does
    legacy_csv = tmp_path / "legacy.csv"
    legacy_csv.write_text(
        ",".join(LEGACY_IMU_COLUMNS)
        + "\n"
        + "".join(",".join(f"{x:.9g}" for x in row) + "\n" for row in data)
    )
    for path in (session_csv, legacy_csv):
        out = tmp_path / f"{path.stem}_events.csv"
        assert run(["gait-events", str(path), "--out", str(out)]) == 0
        events = read_events_csv(out)
        assert events["foot_strike"].size == 4
        assert np.abs(events["foot_strike"] - sim.foot_strikes_s).max() < 0.06
    assert "4 foot strikes" in capsys.readouterr().err


def test_bad_csv_exits_2_with_a_clear_message(tmp_path: Path, capsys) -> None:
    bad = tmp_path / "bad.csv"
    bad.write_text(
        "t_s,gyro_x,gyro_y,gyro_z,accel_x,accel_y,accel_z\n0,0,0,0,0,0,9.8\n0.01,0,0,x,0,0,9.8\n"
    )
    assert run(["gait-events", str(bad)]) == 2
    err = capsys.readouterr().err
    assert f"error: {bad}: line 3, column gyro_z: 'x' is not a number" in err
    assert "Traceback" not in err

"""`graph-slam gait-events`: events CSV out, bad input -> one line and exit code 2."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from graph_slam.cli import main
from kinematics.gait_events import read_events_csv, write_imu_csv
from kinematics.gait_synth import random_mounting, thigh_imu_from_reference


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


def test_bad_csv_exits_2_with_a_clear_message(tmp_path: Path, capsys) -> None:
    bad = tmp_path / "bad.csv"
    bad.write_text(
        "t_s,gyro_x,gyro_y,gyro_z,accel_x,accel_y,accel_z\n0,0,0,0,0,0,9.8\n0.01,0,0,x,0,0,9.8\n"
    )
    assert run(["gait-events", str(bad)]) == 2
    err = capsys.readouterr().err
    assert f"error: {bad}: line 3, column gyro_z: 'x' is not a number" in err
    assert "Traceback" not in err

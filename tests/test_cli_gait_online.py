"""`graph-slam gait-events --online`: both times per event, causal estimator."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from graph_slam.cli import main
from kinematics.gait_events import write_imu_csv
from kinematics.gait_synth import random_mounting, thigh_imu_from_reference


def run(argv: list[str]) -> int:
    with pytest.raises(SystemExit) as info:
        main(argv)
    return int(info.value.code or 0)


def test_gait_events_online_writes_estimated_and_detection_times(tmp_path: Path, capsys) -> None:
    sim = thigh_imu_from_reference(
        1.2, n_strides=4, rate_hz=100.0, thigh_R_sensor=random_mounting(8), seed=8
    )
    imu_csv = write_imu_csv(tmp_path / "imu.csv", sim.imu)
    out = tmp_path / "events.csv"
    assert run(["gait-events", str(imu_csv), "--online", "--out", str(out)]) == 0
    with out.open() as fh:
        rows = list(csv.DictReader(fh))
    assert list(rows[0]) == ["t_s", "kind", "detected_t_s"]
    strikes = np.array([float(r["t_s"]) for r in rows if r["kind"] == "foot_strike"])
    detected = np.array([float(r["detected_t_s"]) for r in rows if r["kind"] == "foot_strike"])
    assert strikes.size == 4
    assert np.abs(strikes - sim.foot_strikes_s).max() < 0.04
    assert np.all(detected >= strikes - 1e-9)  # an event is never emitted before its time
    assert "online: 4 foot strikes" in capsys.readouterr().err

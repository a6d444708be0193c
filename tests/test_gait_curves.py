"""Gait reference curves: periodic, smooth, speed trends as in the source, clear range errors."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from kinematics import gait_curves as gc
from kinematics.errors import GaitCurveError, KinematicsError
from kinematics.gait_tables import BIN_SPEEDS_M_S, SPEED_BINS, build_gait_tables, read_schwartz

REPO = Path(__file__).resolve().parents[1]
SHARED_SCHWARTZ = REPO.parent / "shared" / "data" / "gait" / "Schwartz2008.json"
SPEEDS = np.linspace(0.6, 1.8, 13)


def test_curves_are_periodic_in_value_and_slope() -> None:
    for v in SPEEDS:
        start, end = gc.joint_angles(0.0, v), gc.joint_angles(1.0, v)
        d0, d1 = gc.joint_angles(0.0, v, derivative=1), gc.joint_angles(1.0, v, derivative=1)
        for key in gc.JOINTS:
            assert start[key] == pytest.approx(end[key], abs=1e-12)
            assert d0[key] == pytest.approx(d1[key], abs=1e-9)


def test_curves_are_smooth_bounded_derivatives_match_differences() -> None:
    phase = np.linspace(0, 1, 2001)
    h = phase[1] - phase[0]
    for v in (0.6, 1.13, 1.8):
        q = gc.joint_angles(phase, v)
        dq = gc.joint_angles(phase, v, derivative=1)
        for key in gc.JOINTS:
            numeric = np.gradient(q[key], h)
            assert np.abs(numeric[1:-1] - dq[key][1:-1]).max() < 1e-3
            # No kinks or spikes: |dq/dphase| < 12 rad/cycle (< 690 deg/s at 1 s strides).
            assert np.abs(dq[key]).max() < 12.0


def test_shapes_scalar_and_array() -> None:
    scalar = gc.joint_angles(0.25, 1.2)
    assert set(scalar) == {"hip", "knee", "ankle"}
    assert all(np.ndim(x) == 0 for x in scalar.values())
    grid = gc.joint_angles(np.zeros((3, 4)), 1.2)
    assert all(x.shape == (3, 4) for x in grid.values())


def test_peak_knee_flexion_grows_with_speed_as_in_source() -> None:
    peaks = [np.degrees(gc.joint_angles(np.linspace(0, 1, 501), v)["knee"].max()) for v in SPEEDS]
    assert np.all(np.diff(peaks) > 0), peaks
    # Source bins (Schwartz 2008 mean curves): VerySlow 44.7 deg ... VeryFast 61.9 deg.
    assert peaks[0] == pytest.approx(44.7, abs=1.0)
    assert peaks[-1] == pytest.approx(61.9, abs=1.0)


def test_curves_reproduce_the_shipped_mean_table() -> None:
    from graph_slam_models import model_path

    table = np.genfromtxt(
        model_path("gait/schwartz2008_sagittal.csv"),
        delimiter=",",
        names=True,
        dtype=None,
        encoding="utf-8",
    )
    for name, speed in zip(SPEED_BINS, BIN_SPEEDS_M_S, strict=True):
        rows = table[table["speed_bin"] == name]
        q = gc.joint_angles(rows["cycle_pct"] / 100.0, speed)
        for key in gc.JOINTS:
            err = np.abs(np.degrees(q[key]) - rows[f"{key}_mean_deg"]).max()
            assert err < 0.7, (name, key, err)  # Fourier fit residual (documented 0.58 deg)


def test_known_gait_features() -> None:
    q = gc.joint_angles(np.linspace(0, 1, 501), 1.2)
    phase = np.linspace(0, 1, 501)
    # Peak knee flexion in swing (60-85 % of the cycle), hip max flexion near terminal swing.
    assert 0.6 < phase[np.argmax(q["knee"])] < 0.85
    assert phase[np.argmin(q["hip"])] == pytest.approx(gc.stance_fraction(1.2) - 0.1, abs=0.1)
    thigh = gc.thigh_angle(phase, 1.2)
    assert np.ptp(np.degrees(thigh)) == pytest.approx(42.0, abs=5.0)


def test_spatiotemporal_relations() -> None:
    assert gc.stride_time_s(0.6) > gc.stride_time_s(1.2) > gc.stride_time_s(1.8)
    assert 1.0 < gc.stride_time_s(1.3) < 1.2  # adult cadence ~105-115 steps/min at 1.3 m/s
    for v in SPEEDS:
        assert gc.stride_length_m(v) == pytest.approx(v * gc.stride_time_s(v))
    assert gc.stance_fraction(1.5) == pytest.approx(0.5895)  # Kirtley et al. 1985 at 1.5 m/s


@pytest.mark.parametrize("speed", [0.59, 1.81, float("nan"), -1.0])
def test_speed_outside_range_is_a_clear_error(speed: float) -> None:
    with pytest.raises(GaitCurveError, match=r"outside the range .*0\.6, 1\.8"):
        gc.joint_angles(0.1, speed)
    with pytest.raises(KinematicsError):
        gc.stride_time_s(speed)


def test_nan_phase_and_bad_derivative_rejected() -> None:
    with pytest.raises(GaitCurveError, match="phase must be finite"):
        gc.joint_angles(np.array([0.1, np.nan]), 1.0)
    with pytest.raises(GaitCurveError, match="derivative"):
        gc.joint_angles(0.1, 1.0, derivative=3)


def test_shipped_tables_match_a_rebuild_from_the_source(tmp_path: Path) -> None:
    if not SHARED_SCHWARTZ.exists():
        pytest.skip("real data gait/Schwartz2008.json not available (../shared/data is absent)")
    from graph_slam_models import model_path

    _, json_path = build_gait_tables(SHARED_SCHWARTZ, tmp_path)
    rebuilt = json.loads(json_path.read_text())
    shipped = json.loads(model_path("gait/gait_reference.json").read_text())
    assert rebuilt == shipped
    assert (tmp_path / "schwartz2008_sagittal.csv").read_text() == model_path(
        "gait/schwartz2008_sagittal.csv"
    ).read_text()
    assert set(read_schwartz(SHARED_SCHWARTZ)) == set(SPEED_BINS)

"""Gait events from a thigh IMU (real OpenSim kinematics and reference-curve walking, unknown
mounting, noise, bias) and from a load cell; gait phase; merging; strict CSV input."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import pytest

from kinematics.errors import GaitInputError
from kinematics.gait_events import (
    DetectedEvents,
    detect_from_load_cell,
    detect_from_thigh_imu,
    gait_phase,
    match_events,
    merge_close_strikes,
    read_events_csv,
    read_imu_csv,
    write_events_csv,
    write_imu_csv,
)
from kinematics.gait_synth import (
    ImuNoise,
    ImuSeries,
    opensim_true_events,
    random_mounting,
    read_opensim_mot,
    thigh_imu_from_opensim,
    thigh_imu_from_reference,
)

MOT = Path(__file__).resolve().parent / "data" / "opensim_subject01_walk1_ik.mot"
TOL_S = 0.060  # the bar: foot strikes within ±60 ms


@pytest.fixture(scope="module")
def motion():
    return read_opensim_mot(MOT)


def test_true_events_of_the_real_trial(motion) -> None:
    for side in ("r", "l"):
        ev = opensim_true_events(motion, side)
        strikes, toe_offs = ev["foot_strike"], ev["toe_off"]
        assert strikes.size == 3 and toe_offs.size == 3
        # Steady treadmill walking: strides ~1.22 s; toe-off at ~60 % of the stride.
        assert np.all(np.abs(np.diff(strikes) - 1.22) < 0.03)
        first_to = toe_offs[toe_offs > strikes[0]][0]
        assert 0.55 < (first_to - strikes[0]) / 1.22 < 0.68
        # The heel is near its lowest within 0.1 s after each strike.
        heel = ev["heel_height_m"]
        for t in strikes:
            window = (motion.t_s > t) & (motion.t_s < t + 0.1)
            assert heel[window].min() < 0.025


@pytest.mark.parametrize("side", ["r", "l"])
@pytest.mark.parametrize(("seed", "rate_hz"), [(0, 50.0), (1, 200.0), (2, 1000.0), (3, 100.0)])
def test_real_trial_thigh_imu_meets_the_60ms_bar(motion, side, seed, rate_hz) -> None:
    truth = opensim_true_events(motion, side)["foot_strike"]
    imu = thigh_imu_from_opensim(
        motion, side, rate_hz=rate_hz, thigh_R_sensor=random_mounting(seed), seed=seed
    )
    events = detect_from_thigh_imu(imu)
    errors, missed, extra = match_events(events.foot_strikes_s, truth)
    assert missed == 0 and extra == 0
    assert np.abs(errors).max() < TOL_S, errors


@pytest.mark.parametrize("speed", [0.6, 0.9, 1.2, 1.5, 1.8])
def test_reference_walking_with_standing_before_and_after(speed) -> None:
    sim = thigh_imu_from_reference(
        speed, n_strides=5, rate_hz=200.0, thigh_R_sensor=random_mounting(int(speed * 10)),
        seed=int(speed * 10),
    )  # fmt: skip
    events = detect_from_thigh_imu(sim.imu)
    errors, missed, extra = match_events(events.foot_strikes_s, sim.foot_strikes_s)
    assert missed == 0 and extra == 0
    assert np.abs(errors).max() < 0.02  # the template is the truth here: much tighter than 60 ms
    to_errors, to_missed, to_extra = match_events(events.toe_offs_s, sim.toe_offs_s)
    assert to_missed == 0 and to_extra == 0
    assert np.abs(to_errors).max() < TOL_S
    # no events while standing (first 3 s and last 3 s)
    all_events = np.concatenate([events.foot_strikes_s, events.toe_offs_s])
    assert np.all((all_events > 3.0) & (all_events < sim.imu.t_s[-1] - 3.0))


def test_sagittal_axis_and_sign_are_recovered() -> None:
    mount = random_mounting(11)
    sim = thigh_imu_from_reference(1.2, n_strides=4, thigh_R_sensor=mount, seed=5)
    events = detect_from_thigh_imu(sim.imu)
    # In the simulated world (x forward, y left, z up) thigh flexion is rotation about -y.
    true_axis = mount.T @ np.array([0.0, -1.0, 0.0])
    assert events.sagittal_axis @ true_axis > 0.97


def test_heavy_noise_and_bias_still_detected() -> None:
    noise = ImuNoise(gyro_sigma_rad_s=0.15, gyro_bias_max_rad_s=0.3)
    sim = thigh_imu_from_reference(
        1.0, n_strides=5, rate_hz=100.0, thigh_R_sensor=random_mounting(4), noise=noise, seed=4,
        stride_time_jitter=0.05,
    )  # fmt: skip
    errors, missed, extra = match_events(
        detect_from_thigh_imu(sim.imu).foot_strikes_s, sim.foot_strikes_s
    )
    assert missed == 0 and extra == 0 and np.abs(errors).max() < TOL_S


def test_standing_still_gives_no_events() -> None:
    rng = np.random.default_rng(9)
    t = np.arange(0, 20, 0.005)
    sway = 0.02 * np.sin(2 * np.pi * 0.3 * t)[:, None] * np.array([0.2, 1.0, 0.1])
    gyro = sway + rng.normal(0, 0.03, (t.size, 3)) + np.array([0.02, -0.04, 0.01])
    accel = np.array([0.5, 1.0, 9.7]) + rng.normal(0, 0.1, (t.size, 3))
    events = detect_from_thigh_imu(ImuSeries(t, gyro, accel, "standing"))
    assert events.foot_strikes_s.size == 0 and events.toe_offs_s.size == 0


def test_gait_phase() -> None:
    strikes = np.array([1.0, 2.0, 3.1, 7.0])  # a 3.9 s gap: not walking
    t = np.array([0.5, 1.0, 1.5, 2.55, 3.0, 5.0, 7.5])
    phase = gait_phase(t, strikes)
    np.testing.assert_allclose(phase[1:5], [0.0, 0.5, 0.5, 1.0 / 1.1 * 1.0], rtol=1e-12)
    assert np.isnan(phase[[0, 5, 6]]).all()
    sim = thigh_imu_from_reference(1.3, n_strides=6, seed=2)
    events = detect_from_thigh_imu(sim.imu)
    tt = np.linspace(sim.foot_strikes_s[0], sim.foot_strikes_s[-1], 400)
    err = gait_phase(tt, events.foot_strikes_s) - gait_phase(tt, sim.foot_strikes_s)
    err = (err + 0.5) % 1.0 - 0.5
    assert np.nanmax(np.abs(err)) < 0.03


def test_close_strikes_are_merged_with_a_warning(caplog) -> None:
    with caplog.at_level(logging.WARNING, logger="kinematics.gait_events"):
        kept, merged = merge_close_strikes(np.array([1.0, 1.3, 2.4, 2.5, 3.6]), 0.7, "test")
    np.testing.assert_allclose(kept, [1.0, 2.4, 3.6])
    assert merged == 2
    assert "merged" in caplog.text and "minimum plausible stride time" in caplog.text


def _load(t: np.ndarray, contacts: list[tuple[float, float]], rng) -> np.ndarray:
    f = np.zeros_like(t)
    for start, end in contacts:
        ramp_up = np.clip((t - start) / 0.05, 0, 1) if start > t[0] else np.ones_like(t)
        ramp_down = np.clip((end - t) / 0.05, 0, 1)
        f += 750.0 * np.minimum(ramp_up, ramp_down) * ((t >= start) & (t < end))
    return f + rng.normal(0, 8.0, t.size)


def test_load_cell_hysteresis_standing_before_and_after() -> None:
    rng = np.random.default_rng(3)
    t = np.arange(0, 12, 0.002)
    # standing loaded 0-3 s, then 5 strides (stance 0.7 s, swing 0.45 s), standing from 9.3 s
    contacts = [(0.0, 3.0)]
    strikes = 3.45 + 1.15 * np.arange(5)
    contacts += [(s, s + 0.7) for s in strikes[:-1]] + [(strikes[-1], 12.5)]
    f = _load(t, contacts, rng)
    events = detect_from_load_cell(t, f, on_threshold_n=150.0, off_threshold_n=60.0)
    # the only toe-offs are real lift-offs; standing gives no events
    errors, missed, extra = match_events(events.foot_strikes_s, strikes)
    assert missed == 0 and extra == 0 and np.abs(errors).max() < 0.02
    true_to = np.array([3.0] + [s + 0.7 for s in strikes[:-1]])
    to_err, to_missed, to_extra = match_events(events.toe_offs_s, true_to)
    assert to_missed == 0 and to_extra == 0 and np.abs(to_err).max() < 0.02
    # default thresholds (relative to the load range) agree
    auto = detect_from_load_cell(t, f)
    assert match_events(auto.foot_strikes_s, strikes)[1:] == (0, 0)


def test_load_cell_standing_only_and_chatter_and_merge(caplog) -> None:
    rng = np.random.default_rng(4)
    t = np.arange(0, 10, 0.002)
    standing = 700.0 + rng.normal(0, 10.0, t.size)
    assert detect_from_load_cell(t, standing).rows() == []
    # a heel bounce: 0.2 s contact, 0.2 s lift, contact again - two strikes 0.4 s apart
    f = _load(t, [(1.0, 1.2), (1.4, 2.0), (3.0, 3.7)], rng)
    with caplog.at_level(logging.WARNING, logger="kinematics.gait_events"):
        events = detect_from_load_cell(t, f, on_threshold_n=150.0, off_threshold_n=60.0)
    assert events.merged_strikes == 1
    np.testing.assert_allclose(events.foot_strikes_s, [1.0, 3.0], atol=0.03)
    np.testing.assert_allclose(events.toe_offs_s, [2.0, 3.7], atol=0.03)  # bounce lift dropped
    assert "merged" in caplog.text
    # chatter shorter than min_contact_s is dropped and counted
    g = _load(t, [(1.0, 1.05), (3.0, 3.7)], rng)
    chatter = detect_from_load_cell(t, g, on_threshold_n=150.0, off_threshold_n=60.0)
    assert chatter.rejected == 2
    np.testing.assert_allclose(chatter.foot_strikes_s, [3.0], atol=0.03)
    with pytest.raises(GaitInputError, match="below on_threshold_n"):
        detect_from_load_cell(t, g, on_threshold_n=50.0, off_threshold_n=60.0)
    bad = g.copy()
    bad[7] = np.nan
    with pytest.raises(GaitInputError, match="sample 7"):
        detect_from_load_cell(t, bad)


def test_imu_csv_round_trip(tmp_path: Path) -> None:
    sim = thigh_imu_from_reference(1.2, n_strides=2, rate_hz=100.0, seed=1)
    path = write_imu_csv(tmp_path / "imu.csv", sim.imu)
    back = read_imu_csv(path)
    np.testing.assert_allclose(back.t_s, sim.imu.t_s, atol=1e-6)
    np.testing.assert_allclose(back.gyro_rad_s, sim.imu.gyro_rad_s, rtol=1e-5, atol=1e-9)
    events = DetectedEvents(np.array([1.5, 2.7]), np.array([2.1]), method="test")
    out = read_events_csv(write_events_csv(tmp_path / "ev.csv", events))
    np.testing.assert_allclose(out["foot_strike"], [1.5, 2.7])
    np.testing.assert_allclose(out["toe_off"], [2.1])


HEADER = "t_s,gyro_x,gyro_y,gyro_z,accel_x,accel_y,accel_z\n"


def _rows(n: int = 400, rate: float = 100.0, gyro_scale: float = 0.1) -> list[str]:
    return [f"{k / rate:.4f},{gyro_scale},0,0,0,0,9.81\n" for k in range(n)]


@pytest.mark.parametrize(
    ("text", "pattern"),
    [
        ("", "empty file"),
        (
            "t_s,gx,gyro_y,gyro_z,accel_x,accel_y,accel_z\n0,0,0,0,0,0,0\n",
            r"line 1: header.*missing \['gyro_x'\]",
        ),
        (
            HEADER + "".join(_rows(5)) + "0.05,0.1,abc,0,0,0,9.81\n",
            r"line 7, column gyro_y: 'abc' is not a number",
        ),
        (
            HEADER + "".join(_rows(5)) + "0.05,0.1,nan,0,0,0,9.81\n",
            r"line 7, column gyro_y: 'nan' is not finite",
        ),
        (
            HEADER + "".join(_rows(5)) + "0.03,0.1,0,0,0,0,9.81\n",
            r"line 7, column t_s: time must increase",
        ),
        (HEADER + "".join(_rows(50, rate=10.0)), r"column t_s: median sample rate 10\.0 Hz"),
        (
            HEADER + "".join(_rows(50, gyro_scale=120.0)),
            r"line 2, column gyro_x: 120 exceeds .* rad/s",
        ),
        (HEADER + "0,1,2\n", r"line 2: has 3 fields"),
    ],
)
def test_bad_imu_csv_names_file_line_column_rule(tmp_path: Path, text: str, pattern: str) -> None:
    path = tmp_path / "imu.csv"
    path.write_text(text)
    with pytest.raises(GaitInputError, match=pattern) as info:
        read_imu_csv(path)
    assert str(path) in str(info.value)


def test_match_events_known_answer() -> None:
    errors, missed, extra = match_events(np.array([1.02, 2.5, 3.0]), np.array([1.0, 2.0, 3.1]))
    # 1.0 ↔ 1.02 and 3.1 ↔ 3.0 match; 2.0 has no detection within 0.25 s; 2.5 is extra.
    np.testing.assert_allclose(errors, [0.02, -0.1])
    assert (missed, extra) == (1, 1)

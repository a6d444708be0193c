"""The prosthesis log's clock offset, estimated from foot strikes (graph_slam.session.adapters.
clock_offset): a simulated walk gives both the camera's thigh IMU (the simulator's IMU model,
its own stamps) and a controller log (encoders and a load cell) written on another clock."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
import yaml

from graph_slam.config import config_from_dict
from graph_slam.errors import ClockOffsetError
from graph_slam.session import open_session
from graph_slam.session.adapters import ConvertConfig, convert
from graph_slam.session.adapters.base import ConversionReport, Recording
from graph_slam.session.adapters.clock_offset import estimate_clock_offset
from graph_slam.session.adapters.config import ClockOffsetConfig
from graph_slam.session.adapters.convert import merge_prosthesis_log
from graph_slam.session.records import ImuSeries
from graph_slam.sim.config import SimConfig
from graph_slam.sim.recording import prepare
from graph_slam.sim.sensors import simulate_encoders, simulate_imu

#: The camera's clock reads the simulator's time + this (a bag's stamps are large numbers).
CAMERA_EPOCH_S = 1000.0
LOAD_N, RAMP_S, THRESHOLD_N = 800.0, 0.04, 50.0
#: The synthetic load cell crosses its threshold this late after contact (a linear ramp).
LOAD_LAG_S = THRESHOLD_N / LOAD_N * RAMP_S


@dataclass
class Walk:
    imu: ImuSeries  # camera clock, as a recording gives it
    t_s: np.ndarray  # encoder/load samples, simulator time
    knee_rad: np.ndarray
    ankle_rad: np.ndarray
    strikes_s: np.ndarray  # true, simulator time
    toe_offs_s: np.ndarray


def _walk(strides: int, seed: int, speed_m_s: float = 1.1) -> Walk:
    sim = prepare(SimConfig(strides=strides, seed=seed, speed_m_s=speed_m_s, drops="none"))
    imu, _ = simulate_imu(sim.motion, sim.thigh_T_imu, sim.imu, np.random.default_rng([seed, 3]))
    joints, _ = simulate_encoders(sim.motion, sim.prosthesis, np.random.default_rng([seed, 4]))
    camera_imu = ImuSeries(imu.t_s + CAMERA_EPOCH_S, imu.gyro_rad_s, imu.accel_m_s2, "sim imu")
    return Walk(
        camera_imu,
        joints.t_s,
        joints.knee_rad,
        joints.ankle_rad,
        sim.motion.foot_strikes_s,
        sim.motion.toe_offs_s,
    )


@pytest.fixture(scope="module")
def walk() -> Walk:
    return _walk(strides=12, seed=5)


def _load(walk: Walk, jitter_s: np.ndarray | None = None) -> np.ndarray:
    """Stance load: a 40 ms linear ramp up at each strike (shifted by ``jitter_s``) and down
    at the next toe-off."""
    load = np.zeros_like(walk.t_s)
    shift = np.zeros(walk.strikes_s.size) if jitter_s is None else jitter_s
    for strike, dt in zip(walk.strikes_s, shift, strict=True):
        later = walk.toe_offs_s[walk.toe_offs_s > strike]
        toe_off = later[0] if later.size else walk.t_s[-1] + 1.0
        up = np.clip((walk.t_s - strike - dt) / RAMP_S, 0.0, 1.0)
        down = np.clip((toe_off - walk.t_s) / RAMP_S, 0.0, 1.0)
        load = np.maximum(load, LOAD_N * up * down)
    return load


def _write_log(path: Path, walk: Walk, offset_s: float, **load_kw) -> Path:
    """The controller's CSV on its own clock: log time = camera time − ``offset_s``."""
    t_log_ms = (walk.t_s + CAMERA_EPOCH_S - offset_s) * 1e3
    table = np.column_stack(
        [t_log_ms, np.rad2deg(walk.knee_rad), np.rad2deg(walk.ankle_rad), _load(walk, **load_kw)]
    )
    np.savetxt(
        path,
        table,
        delimiter=",",
        fmt="%.6f",
        header="time_ms,knee_deg,ankle_deg,load_n",
        comments="",
    )
    return path


def _config(log: Path, **prosthesis) -> ConvertConfig:
    section = {
        "path": str(log),
        "time": {"column": "time_ms", "unit": "ms"},
        "knee": {"column": "knee_deg", "unit": "deg"},
        "ankle": {"column": "ankle_deg", "unit": "deg"},
        "load": {"column": "load_n", "foot_strike_above_n": THRESHOLD_N, "toe_off_below_n": 20},
        "clock": {"log_strike_lag_s": LOAD_LAG_S},
    }
    section.update(prosthesis)
    return config_from_dict(ConvertConfig, {"prosthesis_log": section})


def _recording(imu: ImuSeries, config: ConvertConfig) -> Recording:
    """What an adapter gives convert: the IMU and nothing else (no events, no ground truth)."""
    report = ConversionReport(adapter="test", source="<memory>")
    return Recording(name="walk", report=report, resolved=config, imu=imu)


def _crop(imu: ImuSeries, start_s: float, end_s: float) -> ImuSeries:
    keep = (imu.t_s >= start_s) & (imu.t_s <= end_s)
    return ImuSeries(imu.t_s[keep], imu.gyro_rad_s[keep], imu.accel_m_s2[keep], imu.source)


def test_known_offset_recovered_within_10_ms(walk: Walk, tmp_path: Path) -> None:
    true_offset_s = 3.217
    cfg = _config(_write_log(tmp_path / "log.csv", walk, true_offset_s))
    merged = merge_prosthesis_log(_recording(walk.imu, cfg), cfg)
    est = merged.report.clock_offset
    assert est.source == "estimated"
    assert est.offset_s == pytest.approx(true_offset_s, abs=0.010)
    assert est.n_matched >= 12 and est.sigma_s < 0.005
    # The log is on the camera clock now: its strikes land on the true ones (+ the lag).
    strikes = merged.events.foot_strikes_s - CAMERA_EPOCH_S
    np.testing.assert_allclose(strikes, walk.strikes_s + LOAD_LAG_S, atol=0.010)
    np.testing.assert_allclose(merged.joints.t_s, walk.t_s + CAMERA_EPOCH_S, atol=0.010)
    assert merged.resolved.prosthesis_log.time_offset_s == est.offset_s
    assert any(
        "clock offset log → camera +3.21" in n and "estimated" in n for n in merged.report.notes
    )


def test_large_negative_offset_and_a_shorter_camera_recording(tmp_path: Path) -> None:
    walk = _walk(strides=20, seed=11, speed_m_s=0.9)
    true_offset_s = -125.4
    cfg = _config(_write_log(tmp_path / "log.csv", walk, true_offset_s))
    # The camera starts 3 s into the log's walk and stops 2.5 s before its end.
    imu = _crop(walk.imu, walk.imu.t_s[0] + 3.0, walk.imu.t_s[-1] - 2.5)
    est = merge_prosthesis_log(_recording(imu, cfg), cfg).report.clock_offset
    assert est.offset_s == pytest.approx(true_offset_s, abs=0.010)
    assert est.n_matched >= 14 and est.n_log_strikes > est.n_matched
    # A stride-shifted offset matches fewer strikes (or spreads more): the margin is reported.
    assert est.runner_up_offset_s is not None
    assert abs(est.runner_up_offset_s - true_offset_s) > 0.5


def test_converted_through_convert_with_the_report(walk: Walk, tmp_path: Path) -> None:
    """An EuRoC-layout IMU folder (the camera IMU's stamps in ns) + the log → a session."""
    source = tmp_path / "imu_folder"
    (source / "imu0").mkdir(parents=True)
    stamps_ns = np.round(walk.imu.t_s * 1e9).astype(np.int64)
    rows = [
        f"{s},{','.join(f'{v:.9f}' for v in np.r_[g, a])}"
        for s, g, a in zip(stamps_ns, walk.imu.gyro_rad_s, walk.imu.accel_m_s2, strict=True)
    ]
    (source / "imu0" / "data.csv").write_text(
        "#timestamp [ns],w_x,w_y,w_z,a_x,a_y,a_z\n" + "\n".join(rows) + "\n"
    )
    cfg = _config(_write_log(tmp_path / "log.csv", walk, 3.217))
    result = convert(source, tmp_path / "session", cfg)
    assert result.clock_offset.offset_s == pytest.approx(3.217, abs=0.010)
    written = yaml.safe_load(result.report_path.read_text())["clock_offset"]
    assert (
        written["source"] == "estimated" and written["n_matched"] == result.clock_offset.n_matched
    )
    assert written["offset_s"] == pytest.approx(3.217, abs=0.010)
    resolved = yaml.safe_load(result.config_path.read_text())["prosthesis_log"]
    assert resolved["time_offset_s"] == pytest.approx(written["offset_s"])
    session = open_session(result.path)
    assert session.joints.t_s[0] == pytest.approx(CAMERA_EPOCH_S, abs=0.010)


def test_given_offset_is_used_as_is_and_reported_as_config(walk: Walk, tmp_path: Path) -> None:
    cfg = _config(_write_log(tmp_path / "log.csv", walk, 3.217), time_offset_s=3.0)
    merged = merge_prosthesis_log(_recording(walk.imu, cfg), cfg)
    est = merged.report.clock_offset
    assert est.source == "config" and est.offset_s == 3.0 and est.n_matched is None
    np.testing.assert_allclose(merged.joints.t_s, walk.t_s + CAMERA_EPOCH_S - 0.217, atol=1e-6)
    assert merged.report.to_dict()["clock_offset"] == {"offset_s": 3.0, "source": "config"}


def test_fewer_than_five_matched_strikes_is_an_error(tmp_path: Path) -> None:
    walk = _walk(strides=3, seed=2)
    cfg = _config(_write_log(tmp_path / "log.csv", walk, 3.217))
    with pytest.raises(ClockOffsetError, match=r"at least 5 matched strikes are needed"):
        merge_prosthesis_log(_recording(walk.imu, cfg), cfg)


def test_matches_below_the_minimum_after_the_search_is_an_error() -> None:
    """Enough strikes on both sides, but only 4 agree: the rest fall outside the tolerance."""
    rng = np.random.default_rng(3)
    camera = np.cumsum(rng.uniform(0.9, 1.3, 12))
    log_ = camera - 7.0
    log_[4:] += rng.uniform(0.2, 0.4, 8) * rng.choice([-1, 1], 8)
    with pytest.raises(ClockOffsetError, match=r"only 4 foot strike\(s\) matched within ±40 ms"):
        estimate_clock_offset(camera, log_, ClockOffsetConfig(imu_strike_bias_s=0.0))


def test_too_large_a_spread_is_an_error(walk: Walk, tmp_path: Path) -> None:
    jitter = np.random.default_rng(8).normal(0.0, 0.025, walk.strikes_s.size)
    cfg = _config(_write_log(tmp_path / "log.csv", walk, 3.217, jitter_s=jitter))
    with pytest.raises(ClockOffsetError, match=r"spread by σ .* above the bound 20.0 ms"):
        merge_prosthesis_log(_recording(walk.imu, cfg), cfg)
    wide = _config(
        cfg.prosthesis_log.path,
        clock={"log_strike_lag_s": LOAD_LAG_S, "max_spread_s": 0.05, "tolerance_s": 0.1},
    )
    est = merge_prosthesis_log(_recording(walk.imu, wide), wide).report.clock_offset
    assert est.sigma_s > 0.02 and est.offset_s == pytest.approx(3.217, abs=0.025)


def test_a_perfectly_regular_walk_is_ambiguous() -> None:
    """Identical strides and a log that covers more: one stride earlier fits as well."""
    camera = 100.0 + 1.1 * np.arange(8)
    log_ = 1.1 * np.arange(-3, 12)
    with pytest.raises(ClockOffsetError, match="ambiguous"):
        estimate_clock_offset(camera, log_, ClockOffsetConfig(imu_strike_bias_s=0.0))


def test_no_imu_or_no_log_strikes_is_an_error(walk: Walk, tmp_path: Path) -> None:
    cfg = _config(_write_log(tmp_path / "log.csv", walk, 3.217))
    no_imu = Recording(name="x", report=ConversionReport("test", "<memory>"), resolved=cfg)
    with pytest.raises(ClockOffsetError, match=r"has no IMU; set prosthesis_log.time_offset_s"):
        merge_prosthesis_log(no_imu, cfg)
    no_load = _config(cfg.prosthesis_log.path, load=None)
    with pytest.raises(ClockOffsetError, match=r"neither 'events' nor 'load'"):
        merge_prosthesis_log(_recording(walk.imu, no_load), no_load)

"""The camera's mount pitch on the thigh from the recording itself (graph_slam.strides.mount):
known answers on simulated walks (IMU, encoders and load-cell events only, nothing rendered),
the order of the sources, and the refusals."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from graph_slam.errors import ConfigError, MountPitchError
from graph_slam.session.records import Calibration
from graph_slam.sim import SimConfig
from graph_slam.sim.recording import prepare
from graph_slam.sim.sensors import load_cell_events, simulate_encoders, simulate_imu
from graph_slam.strides.events import stride_events
from graph_slam.strides.kinematics import estimate_from_streams, session_leg_model
from graph_slam.strides.mount import MountEstimateConfig, estimate_mount_pitch
from graph_slam.strides.streams import Streams

STRIDES = 6


def _walk(pitch_deg: float, seed: int):
    """(streams, calibration) of a simulated walk: the sensors a converted recording has."""
    sim = prepare(SimConfig(mount_pitch_deg=pitch_deg, strides=STRIDES, seed=seed))
    imu, _ = simulate_imu(sim.motion, sim.thigh_T_imu, sim.imu, np.random.default_rng([seed, 1]))
    joints, _ = simulate_encoders(sim.motion, sim.prosthesis, np.random.default_rng([seed, 2]))
    events = load_cell_events(sim.motion, sim.prosthesis, np.random.default_rng([seed, 3]))
    streams = Streams(
        imu.t_s, imu.gyro_rad_s, imu.accel_m_s2,
        joints.t_s, joints.knee_rad, joints.ankle_rad,
        stride_events(events, "load_cell"),
    )  # fmt: skip
    return streams, sim.calibration


@pytest.fixture(scope="module")
def walks() -> dict[float, tuple]:
    return {32.0: _walk(32.0, seed=4), 42.0: _walk(42.0, seed=5)}


def _session(calibration: Calibration, thigh_T_camera: np.ndarray | None = None):
    """The two attributes session_leg_model reads (a converted recording: identity mount)."""
    calib = Calibration(
        thigh_T_camera=np.eye(4) if thigh_T_camera is None else thigh_T_camera,
        camera_T_imu=calibration.camera_T_imu,
    )
    return SimpleNamespace(calibration=calib, path="walk")


@pytest.mark.parametrize("pitch_deg", [32.0, 42.0])
def test_estimate_is_within_1_degree(walks, pitch_deg: float) -> None:
    """Known answer: 6 simulated strides (sensor noise and IMU biases as profiled, load-cell
    events); measured error -0.04° (32°) and +0.21° (42°), spread (1.4826·MAD) 1.5-1.8°, ~300
    samples; with ideal sensors the error is below 0.04°."""
    streams, calib = walks[pitch_deg]
    est = estimate_from_streams(streams, calib.camera_T_imu)
    assert est.pitch_deg == pytest.approx(pitch_deg, abs=1.0)
    assert est.spread_deg < 3.0
    assert est.n_samples >= 200 and est.counts["used"] == est.n_samples
    assert est.counts["stances"] == STRIDES


def test_gates_reject_the_rolling_foot(walks) -> None:
    """Over the whole stance (heel and toe rocker included) the gyro-rate gate removes the
    samples where the foot is not flat and the estimate holds."""
    streams, calib = walks[32.0]
    cfg = MountEstimateConfig(stance_start=0.0, stance_end=1.0)
    est = estimate_from_streams(streams, calib.camera_T_imu, cfg)
    assert est.counts["rate"] > 0.4 * est.counts["in_window"]
    assert est.pitch_deg == pytest.approx(32.0, abs=1.0)


def test_precedence_config_then_calibration_then_estimate(walks) -> None:
    streams, calib = walks[32.0]
    # the config wins over a calibrated mount
    model, mount = session_leg_model(_session(calib, calib.thigh_T_camera), 40.0, streams=streams)
    assert mount.source == "config" and mount.pitch_deg == 40.0 and mount.estimate is None
    assert math.degrees(model.params.mount_pitch_down_rad) == pytest.approx(40.0)
    # the calibration's thigh_T_camera (not identity) wins over the estimate: an exact fit
    model, mount = session_leg_model(_session(calib, calib.thigh_T_camera), streams=streams)
    assert mount.source == "calibration" and mount.pitch_deg == pytest.approx(32.0, abs=1e-4)
    # identity: estimated from the data, and the model is built with the estimate
    model, mount = session_leg_model(_session(calib), streams=streams)
    assert mount.source == "estimated" and mount.pitch_deg == pytest.approx(32.0, abs=1.0)
    assert math.degrees(model.params.mount_pitch_down_rad) == pytest.approx(mount.pitch_deg)
    assert mount.to_dict()["n_samples"] == mount.estimate.n_samples
    assert "estimated from" in mount.describe()


def test_too_few_foot_flat_samples_is_a_clear_error(walks) -> None:
    streams, calib = walks[32.0]
    with pytest.raises(MountPitchError, match=r"walk: \d+ foot-flat IMU samples .* need >= 5000 "
                       r"\(pipeline\.mount_estimate\.min_samples"):  # fmt: skip
        session_leg_model(
            _session(calib), None, MountEstimateConfig(min_samples=5000), streams=streams
        )
    one_stride = Streams(
        *(getattr(streams, f) for f in ("imu_t_s", "gyro_rad_s", "accel_m_s2", "joints_t_s",
                                         "knee_rad", "ankle_rad")),
        events=type(streams.events)(streams.events.foot_strikes_s[:1], np.zeros(0)),
    )  # fmt: skip
    with pytest.raises(MountPitchError, match=r"0 foot-flat IMU samples .* 0 stances"):
        estimate_from_streams(one_stride, calib.camera_T_imu, where="walk")
    assert issubclass(MountPitchError, ConfigError)  # the CLI's one-line error, exit code 2


def test_spread_and_range_are_refused(walks) -> None:
    streams, calib = walks[32.0]
    with pytest.raises(MountPitchError, match=r"spreads .*mount_estimate\.max_spread_deg=0\.1"):
        estimate_from_streams(streams, calib.camera_T_imu, MountEstimateConfig(max_spread_deg=0.1))
    # the camera turned 20° more about its y axis (portrait: the thigh's pitch axis): the
    # estimate moves 20° to 12° or 52°, outside the leg model's range either way
    turn = np.eye(4)
    c, s = math.cos(math.radians(20)), math.sin(math.radians(20))
    turn[:3, :3] = [[c, 0, s], [0, 1, 0], [-s, 0, c]]
    with pytest.raises(MountPitchError, match=r"estimated at (1[12]|5[12])\.\d\d° .* outside the leg "
                       r"model's valid 30-45°"):  # fmt: skip
        estimate_from_streams(streams, turn @ calib.camera_T_imu)


def test_without_encoders_is_a_clear_error(walks) -> None:
    streams, calib = walks[32.0]
    with pytest.raises(MountPitchError, match="needs the IMU and the joint encoders"):
        estimate_mount_pitch(
            streams.imu_t_s, streams.gyro_rad_s, streams.accel_m_s2, np.zeros(0),
            np.zeros((0, 2)), streams.foot_strikes_s, streams.events.toe_offs_s,
            calib.camera_T_imu, where="walk",
        )  # fmt: skip

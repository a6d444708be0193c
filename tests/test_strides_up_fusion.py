"""The accelerometer's up fused with the estimator's attitude (graph_slam.strides.up_fusion):
known answers on a slope with a known accelerometer bias, the χ² gate, the up vector's
Jacobian against a numerical derivative."""

from __future__ import annotations

import math

import gtsam
import numpy as np
import pytest

from graph_slam.frontend.floor import FloorConfig
from graph_slam.strides.anchor import StrideAnchor
from graph_slam.strides.up_fusion import GraphUp, fuse_with_graph, up_covariance

G = 9.81
# the IMU pitched 30° down (thigh flexed) on an 8° ramp: stride x forward, y left, z up
STRIDE_R_IMU = gtsam.Rot3.Ry(math.radians(-30.0)).matrix()
UP_TRUE = STRIDE_R_IMU.T @ np.array([0.0, 0.0, 1.0])  # in the IMU frame
HEADING = STRIDE_R_IMU.T @ np.array([1.0, 0.0, 0.0])
LATERAL = STRIDE_R_IMU.T @ np.array([0.0, 1.0, 0.0])
SIGMA_ACCEL = 0.01


def deg(a: np.ndarray, b: np.ndarray) -> float:
    a, b = a / np.linalg.norm(a), b / np.linalg.norm(b)
    return math.degrees(math.acos(min(1.0, float(a @ b))))


def components_deg(up: np.ndarray) -> tuple[float, float]:
    """The error of ``up`` along the heading and the lateral axis (deg)."""
    d = up / np.linalg.norm(up) - UP_TRUE
    return math.degrees(d @ HEADING), math.degrees(d @ LATERAL)


def accel_up(bias_heading: float, bias_lateral: float) -> np.ndarray:
    """The mean specific force of a quasi-static stance with a known accelerometer bias."""
    return G * UP_TRUE + bias_heading * HEADING + bias_lateral * LATERAL


def graph_up(pitch_err_deg: float, roll_err_deg: float, sig_pitch_deg: float,
             sig_roll_deg: float, lateral: bool = True) -> GraphUp:  # fmt: skip
    """The estimator's attitude off by a known tilt, its covariance about the stride axes."""
    err = gtsam.Rot3.Ry(math.radians(pitch_err_deg)) * gtsam.Rot3.Rx(math.radians(roll_err_deg))
    est = err.matrix() @ STRIDE_R_IMU  # stride_R_imu as estimated
    cov_stride = np.diag(np.radians([sig_roll_deg, sig_pitch_deg, 5.0]) ** 2)
    cov_imu = est.T @ cov_stride @ est  # right perturbation: IMU frame
    return GraphUp(0.0, est.T @ [0.0, 0.0, 1.0], cov_imu, est.T[:, 1] if lateral else None)


def test_the_graphs_pitch_corrects_a_biased_accelerometer_and_its_roll_is_left_out():
    """Bias 0.05 m/s² along the heading (0.29° of pitch) and 0.03 laterally (0.18° of roll);
    the graph's pitch 0.02° off (σ 0.1°), its roll 1° off (σ 1°: a lateral bias is a roll to
    it). Fused: pitch within 0.05° of the truth, roll the accelerometer's."""
    ua = accel_up(0.05, 0.03)
    pitch_a, roll_a = components_deg(ua)
    assert pitch_a == pytest.approx(math.degrees(0.05 / G), abs=0.01)
    f = fuse_with_graph(ua, SIGMA_ACCEL, graph_up(0.02, 1.0, 0.1, 1.0))
    assert f.fused
    pitch, roll = components_deg(f.up_in_imu)
    assert abs(pitch) < 0.05
    assert roll == pytest.approx(roll_a, abs=0.01)
    assert f.sigma_rad == SIGMA_ACCEL  # one σ for both axes: the roll's


def test_without_a_lateral_axis_both_tilts_are_weighed_by_their_covariance():
    ua = accel_up(0.05, 0.03)
    _, roll_a = components_deg(ua)
    estimate = graph_up(0.02, 1.0, 0.1, 1.0, lateral=False)
    _, roll_g = components_deg(estimate.up_in_imu)
    assert roll_g == pytest.approx(1.0, abs=0.01)
    f = fuse_with_graph(ua, SIGMA_ACCEL, estimate)
    pitch, roll = components_deg(f.up_in_imu)
    assert abs(pitch) < 0.05
    w = 1.0 / math.radians(1.0) ** 2 / (1.0 / math.radians(1.0) ** 2 + 1.0 / SIGMA_ACCEL**2)
    assert roll == pytest.approx(roll_a + w * (roll_g - roll_a), abs=0.02)  # by its weight
    assert f.sigma_rad < SIGMA_ACCEL


def test_a_graph_far_from_the_accelerometer_is_not_used():
    ua = accel_up(0.05, 0.03)
    f = fuse_with_graph(ua, SIGMA_ACCEL, graph_up(3.0, 0.0, 0.1, 1.0))
    assert not f.fused and f.mahalanobis2 > 11.8
    assert deg(f.up_in_imu, ua) < 1e-9


def test_up_covariance_is_the_numerical_derivative_of_up():
    rng = np.random.default_rng(4)
    rot = gtsam.Rot3.RzRyRx(0.3, -0.7, 0.2)
    up = rot.matrix().T @ [0.0, 0.0, 1.0]
    jac = np.empty((3, 3))
    eps = 1e-7
    for i in range(3):
        d = np.zeros(3)
        d[i] = eps
        moved = rot.compose(gtsam.Rot3.Expmap(d)).matrix().T @ [0.0, 0.0, 1.0]
        jac[:, i] = (moved - up) / eps
    a = rng.normal(size=(3, 3))
    cov = a @ a.T
    np.testing.assert_allclose(up_covariance(up, cov), jac @ cov @ jac.T, atol=1e-5)


class StaticGravity:
    """The accelerometer's up with a known bias, for any window."""

    def window_before(self, t_s: float) -> float:
        return 1.1

    def up_at(self, t_s: float, window_s: float) -> np.ndarray:
        return accel_up(0.05, 0.03)

    def history_s(self, t_s: float) -> float:
        return 10.0


def test_the_anchor_fuses_the_graphs_up_and_says_so():
    estimate = graph_up(0.02, 1.0, 0.1, 1.0)
    anchor = StrideAnchor(StaticGravity(), FloorConfig(enabled=False), np.eye(4), SIGMA_ACCEL,
                          0.8, 0.2, graph_up=lambda t_s: estimate)  # fmt: skip
    a = anchor.at_strike(0.0, 0.05, None)
    assert a.case == "imu" and a.graph == "fused" and "up_graph:fused" in a.flags
    assert abs(components_deg(a.up_in_imu)[0]) < 0.05
    alone = StrideAnchor(StaticGravity(), FloorConfig(enabled=False), np.eye(4), SIGMA_ACCEL,
                         0.8, 0.2).at_strike(0.0, 0.05, None)  # fmt: skip
    assert alone.graph == "" and components_deg(alone.up_in_imu)[0] > 0.25


def test_the_terrain_bench_puts_overrides_under_its_own_settings():
    from graph_slam.bench.terrain_walk import _config

    over = {
        "gravity_from_graph": True,
        "variant": "icp+imu",
        "graph": {"floor": {"enabled": False}},
    }
    cfg = _config("realtime", True, over)
    assert cfg.gravity_from_graph and not cfg.graph.floor.enabled
    assert cfg.variant.value == "icp+imu+kin" and cfg.graph.floor.assume_level  # the bench's
    assert not _config("realtime", False).gravity_from_graph  # the default: accelerometer only

"""IMU prediction between frames: preintegrated, across a gap (constant velocity and bridge
factors), carried to a new stride; the strike's up vector carried by the gyro."""

from __future__ import annotations

import gtsam
import numpy as np
import pytest

from graph_slam.backend import BackendConfig
from graph_slam.backend.keys import B, V, X
from graph_slam.backend.prediction import StrikeUp, make_imu_predictor
from graph_slam.backend.stride_graph import StrideGraph
from graph_slam.errors import EstimationError

G = 9.81


def graph_at_rest(v_m_s=(0.0, 0.0, 0.0)) -> StrideGraph:
    g = StrideGraph()
    values = gtsam.Values()
    values.insert(X(0), gtsam.Pose3())
    values.insert(V(0), np.asarray(v_m_s, float))
    values.insert(B(0), gtsam.imuBias.ConstantBias())
    tagged = [
        ("prior", gtsam.PriorFactorPose3(X(0), gtsam.Pose3(), gtsam.noiseModel.Isotropic.Sigma(6, 1e-3))),
        ("prior", gtsam.PriorFactorVector(V(0), np.asarray(v_m_s, float), gtsam.noiseModel.Isotropic.Sigma(3, 1e-2))),
        ("prior", gtsam.PriorFactorConstantBias(B(0), gtsam.imuBias.ConstantBias(), gtsam.noiseModel.Isotropic.Sigma(6, 1e-2))),
    ]  # fmt: skip
    g.add_state(0.0, tagged, values, None)
    return g


def test_predict_preintegrates_or_bridges_a_gap():
    imu = make_imu_predictor(BackendConfig())
    t = np.r_[np.arange(0.0, 0.1, 0.005), np.arange(0.3, 0.4, 0.005)]  # hole 0.1-0.3 s
    imu.add(t, np.zeros((t.size, 3)), np.tile([0.0, 0.0, G], (t.size, 1)))
    g = graph_at_rest(v_m_s=(0.5, 0.0, 0.0))
    p = imu.predict(g, 0.05)
    assert [tag for tag, _ in p.tagged] == ["imu"] and p.flags == [] and p.k == 1
    np.testing.assert_allclose(p.pose.translation(), [0.025, 0.0, 0.0], atol=1e-9)
    cov = p.covariance()
    assert cov.shape == (6, 6) and np.all(np.linalg.eigvalsh(cov) > 0)
    p = imu.predict(g, 0.2)  # across the hole: constant velocity, three bridges
    assert p.flags == ["imu_gap"] and [tag for tag, _ in p.tagged] == ["bridge"] * 3
    np.testing.assert_allclose(p.pose.translation(), [0.1, 0.0, 0.0], atol=1e-12)
    assert len(p.bridge()) == 3
    assert p.values().exists(X(1)) and p.values().exists(B(1))


def test_carry_adds_preintegration_covariance_or_grows_without_imu():
    imu = make_imu_predictor(BackendConfig())
    t = np.arange(0.0, 0.2, 0.005)
    imu.add(t, np.zeros((t.size, 3)), np.tile([0.0, 0.0, G], (t.size, 1)))
    g = graph_at_rest()
    nav = g.nav(0)
    _, cov_x, cov_v, flags = imu.carry(0.0, nav, np.eye(6) * 1e-6, np.eye(3) * 1e-6, 0.1)
    assert flags == [] and np.all(np.diag(cov_x) > 1e-6) and np.all(np.diag(cov_v) > 1e-6)
    _, cov_x, cov_v, flags = imu.carry(0.0, nav, np.zeros((6, 6)), np.zeros((3, 3)), 0.5)
    assert flags == ["imu_gap"]
    np.testing.assert_allclose(np.diag(cov_x), [0.05**2] * 3 + [1.0**2] * 3)  # (2 m/s · dt)²
    np.testing.assert_allclose(np.diag(cov_v), [(G * 0.5) ** 2] * 3)


def test_up_vector_carried_by_the_gyro_and_checked():
    imu = make_imu_predictor(BackendConfig())
    t = np.arange(0.0, 0.5, 0.005)
    w = np.array([0.0, 0.0, 1.0])
    imu.add(t, np.tile(w, (t.size, 1)), np.tile([1.0, 2.0, 9.0], (t.size, 1)))
    up = StrikeUp.checked(0.1, np.array([3.0, 0.0, 9.0]), 0.01)
    rot = gtsam.Rot3.Rz(0.2).matrix()  # strike_R_now after 0.2 s at 1 rad/s
    np.testing.assert_allclose(imu.up_at(0.3, up), rot.T @ [3.0, 0.0, 9.0], atol=1e-9)
    np.testing.assert_allclose(imu.up_at(0.05, up), [3.0, 0.0, 9.0])
    np.testing.assert_allclose(imu.up_at(0.3, None), [1.0, 2.0, 9.0])  # accelerometer mean
    assert StrikeUp.checked(0.1, None, 0.01) is None
    assert StrikeUp.checked(0.1, [0, 0, 1.0], up_t_s=0.2).t_s == 0.2
    with pytest.raises(EstimationError, match="up_sigma_rad"):
        StrikeUp.checked(0.1, [0, 0, 1.0], -1.0)
    with pytest.raises(EstimationError, match="up_in_imu"):
        StrikeUp.checked(0.1, [0, 0, 0.0])

"""A closed stride's end state: the partial elimination against a refactorised iSAM2, its
pieces, the priors replaced in a started stride, and ``end_state: next_frame`` against
``at_close`` on the synthetic walk."""

from __future__ import annotations

import gtsam
import numpy as np
import pytest

from graph_slam.backend import BackendConfig, StrideSLAM
from graph_slam.backend.keys import B, V, X
from graph_slam.session.synthetic import SyntheticConfig, synthetic_streams
from graph_slam.sim.measurements import simulate_measurements
from tests.test_backend_estimator import run, stride_errors_m


@pytest.fixture(scope="module")
def open_stride():
    """The synthetic walk's second stride, open (its graph) just before the next strike."""
    st = synthetic_streams(SyntheticConfig(duration_s=4.5, seed=0))
    frames = simulate_measurements(
        st.frame_times_s,
        st.ground_truth.parent_T_child,
        st.events.foot_strikes_s,
        swing_icp_drop=0.3,
        seed=100,
    )
    slam = StrideSLAM(BackendConfig(smoothing=False), st.calibration.camera_T_imu)
    slam.add_imu(st.imu.t_s, st.imu.gyro_rad_s, st.imu.accel_m_s2)
    strikes = 0
    for f in frames:
        if f.strike_before:
            strikes += 1
            if strikes == 3:
                break
            slam.foot_strike(f.t_s)
        slam.add_frame(f.t_s, f.icp, f.foot_loaded, f.kinematics)
    g = slam.strides.graph
    assert g.n_states > 20
    return g


def _refactorised(g):
    isam = gtsam.ISAM2(g._isam_params)
    isam.update(g.graph, g.estimate)
    n = g.n_states
    return isam.calculateEstimate(), [
        np.asarray(isam.marginalCovariance(k(n - 1))) for k in (X, V, B)
    ]


def test_end_state_equals_a_refactorised_isam2(open_stride):
    """Known answer: the last state's covariances and the Gauss-Newton step from one
    partial elimination equal those of an iSAM2 refactorised at the same estimate."""
    g = open_stride
    step, end = g.end_state(g.estimate)
    want_values, want_end = _refactorised(g)
    for got, want in zip(end, want_end, strict=True):
        np.testing.assert_allclose(got, want, rtol=1e-6, atol=1e-12 * np.abs(want).max())
    got_values = g.estimate.retract(step)
    for k in range(g.n_states):
        np.testing.assert_allclose(
            got_values.atPose3(X(k)).matrix(), want_values.atPose3(X(k)).matrix(), atol=1e-9
        )
        np.testing.assert_allclose(got_values.atVector(V(k)), want_values.atVector(V(k)), atol=1e-8)


@pytest.mark.parametrize("pieces", [1, 2, 3, 4, 7])
def test_settling_in_pieces_equals_settling_at_once(open_stride, pieces):
    g = open_stride
    whole = g.settle(g.estimate, "end", step=True)
    work = g.settle_in_pieces(g.estimate, "end", step=True, pieces=pieces)
    parts = list(work)
    assert len(parts) == pieces and all(p is None for p in parts[:-1])
    last = parts[-1]
    for got, want in zip(last.end, whole.end, strict=True):
        np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-15)
    n = g.n_states
    np.testing.assert_allclose(
        last.values.atPose3(X(n - 1)).matrix(), whole.values.atPose3(X(n - 1)).matrix(), atol=1e-12
    )
    assert "marginals_failed" not in g.flags


def test_replace_priors_equals_a_graph_built_with_them():
    """A stride's first-state priors replaced after three more states: the estimate is the
    one of the same graph built with the new priors from the start."""
    from graph_slam.backend import factors
    from graph_slam.backend.stride_graph import StrideGraph

    def priors(pose):
        return [
            ("prior", factors.pose_prior(0, pose, np.eye(6) * 1e-4)),
            ("prior", factors.velocity_prior(0, np.zeros(3), np.eye(3) * 1e-2)),
            ("prior", factors.bias_prior(0, gtsam.imuBias.ConstantBias(), np.eye(6) * 1e-4)),
        ]

    def build(first):
        g = StrideGraph()
        v = gtsam.Values()
        v.insert(X(0), gtsam.Pose3())
        v.insert(V(0), np.zeros(3))
        v.insert(B(0), gtsam.imuBias.ConstantBias())
        g.add_state(0.0, priors(first), v, None)
        for k in range(1, 4):
            step = gtsam.Pose3(gtsam.Rot3.Yaw(0.05), np.array([0.1, 0.0, 0.0]))
            noise = gtsam.noiseModel.Isotropic.Sigma(6, 0.01)
            tagged = [
                ("icp", gtsam.BetweenFactorPose3(X(k - 1), X(k), step, noise)),
                ("prior", factors.velocity_prior(k, np.zeros(3), np.eye(3))),
                ("prior", factors.bias_prior(k, gtsam.imuBias.ConstantBias(), np.eye(6))),
            ]
            v = gtsam.Values()
            v.insert(X(k), gtsam.Pose3())
            v.insert(V(k), np.zeros(3))
            v.insert(B(k), gtsam.imuBias.ConstantBias())
            g.add_state(0.1 * k, tagged, v, None)
        return g

    moved = gtsam.Pose3(gtsam.Rot3.Roll(0.02), np.array([0.01, -0.02, 0.005]))
    g = build(gtsam.Pose3())
    g.replace_priors(priors(moved))
    fresh = build(moved)
    for _ in range(3):  # both settle
        g.isam.update()
        fresh.isam.update()
    a, b = g.isam.calculateEstimate(), fresh.isam.calculateEstimate()
    for k in range(4):
        np.testing.assert_allclose(a.atPose3(X(k)).matrix(), b.atPose3(X(k)).matrix(), atol=1e-9)
    assert "prior_replace_failed" not in g.flags
    with pytest.raises(Exception, match="not priors"):
        g.replace_priors(priors(moved) * 2)  # the first 6 factors are not all priors


def test_next_frame_end_state_matches_the_close():
    """``end_state: next_frame`` (the end state settled over the frames after the strike, the
    new stride's priors replaced then) ends where ``at_close`` does: the smoothed poses
    within 0.1 mm (31 µm measured), the accuracy bounds of the full-graph test held."""
    at_close, frames = run(smoothing=False)
    later, _ = run(smoothing=False, end_state="next_frame")
    assert len(later.frames) == len(frames) and len(later.strides) == len(at_close.strides)
    np.testing.assert_allclose(
        later.smoothed_stride_T_camera[:, :3, 3],
        at_close.smoothed_stride_T_camera[:, :3, 3],
        atol=1e-4,
    )
    err = stride_errors_m(later, frames)[:-1]
    assert np.median(err[:, 1]) < 0.008 and np.max(err[:, 2]) < 0.020, err
    assert not any("marginals_failed" in s.flags for s in later.strides)


def test_a_failed_piece_keeps_the_estimate_and_flags_it(open_stride, monkeypatch):
    """GTSAM failing in the middle of the pieces: the estimate stays as it was, no
    covariances are claimed, the stride is flagged ``marginals_failed``."""
    from graph_slam.backend import end_state

    def failing(graph, values, n_states, n_pieces=1):
        yield None
        raise RuntimeError("Indeterminant linear system")

    g = open_stride
    monkeypatch.setattr(end_state, "pieces", failing)
    monkeypatch.setattr(g, "flags", set())
    parts = list(g.settle_in_pieces(g.estimate, "end", step=True, pieces=3))
    assert parts[0] is None and parts[-1] is not None
    out = parts[-1]
    assert out.end is None and out.values is g.estimate
    assert "marginals_failed" in g.flags

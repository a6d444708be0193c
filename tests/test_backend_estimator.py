"""StrideSLAM on the analytic synthetic session (exact IMU, ground truth) with simulated ICP
and kinematic measurements (graph_slam.sim.measurements): known answers with stated
tolerances, bias convergence, failure handling."""

from __future__ import annotations

import gtsam
import numpy as np
import pytest

from graph_slam.backend import BackendConfig, StrideSLAM
from graph_slam.backend.stride_graph import StrideGraph
from graph_slam.errors import ConfigError, EstimationError
from graph_slam.session.synthetic import SyntheticConfig, synthetic_streams
from graph_slam.sim.measurements import simulate_measurements


def run(
    variant="icp+imu+kin",
    duration_s=4.5,
    gyro_bias=(0.0, 0.0, 0.0),
    accel_bias=(0.0, 0.0, 0.0),
    imu_mutator=None,
    swing_icp_drop=1.0,
    seed=0,
    strike_filter=None,
    **cfg_kw,
):
    syn = SyntheticConfig(duration_s=duration_s, seed=seed)
    st = synthetic_streams(syn)
    frames = simulate_measurements(
        st.frame_times_s,
        st.ground_truth.parent_T_child,
        st.events.foot_strikes_s,
        swing_icp_drop=swing_icp_drop,
        seed=seed + 100,
    )
    slam = StrideSLAM(BackendConfig(variant=variant, **cfg_kw), st.calibration.camera_T_imu)
    t, gyro, accel = st.imu.t_s.copy(), st.imu.gyro_rad_s.copy(), st.imu.accel_m_s2.copy()
    gyro += np.asarray(gyro_bias)
    accel += np.asarray(accel_bias)
    if imu_mutator is not None:
        t, gyro, accel = imu_mutator(t, gyro, accel)
    # Stream in chunks, as a device would deliver them.
    for chunk in np.array_split(np.arange(t.size), 20):
        slam.add_imu(t[chunk], gyro[chunk], accel[chunk])
    online = []
    for f in frames:
        if f.strike_before and (strike_filter is None or strike_filter(f)):
            slam.foot_strike(f.t_s)
        online.append(slam.add_frame(f.t_s, f.icp, f.foot_loaded, f.kinematics))
    return slam.finish(), frames


def stride_errors_m(res, frames):
    """Per stride: (online RMSE, smoothed RMSE, smoothed max) of camera positions, stride frame."""
    truth = np.array([f.stride_T_camera_true for f in frames])
    sm = res.smoothed_stride_T_camera
    on = res.online_stride_T_camera
    out = []
    for s in res.strides:
        i = s.frame_indices
        e_on = np.linalg.norm(on[i, :3, 3] - truth[i, :3, 3], axis=1)
        e_sm = np.linalg.norm(sm[i, :3, 3] - truth[i, :3, 3], axis=1)
        out.append((np.sqrt(np.mean(e_on**2)), np.sqrt(np.mean(e_sm**2)), e_sm.max()))
    return np.array(out)


def test_full_graph_recovers_truth_with_icp_lost_in_swing():
    """ICP (1 mm, 1 mrad per frame) only in stance, kinematics (5 mm, 0.5°) in stance, IMU
    throughout: every frame gets a pose, and the swing is bridged by the IMU."""
    res, frames = run()
    assert len(res.frames) == len(frames)
    assert np.all(np.isfinite(res.smoothed_stride_T_camera))
    err = stride_errors_m(res, frames)
    full = err[:-1]  # the last stride has 4 frames
    assert np.median(full[:, 1]) < 0.008, err
    assert np.max(full[:, 2]) < 0.020, err
    assert np.max(full[:, 0]) < 0.012, err
    # Strides 1.. start from a foot strike with an anchor; gate reasons are recorded.
    assert [s.start for s in res.strides][:2] == ["first_stride", "foot_strike"]
    # each stride's first state is marked (the pipelines' reset frames)
    assert [f.frame_index for f in res.frames if f.stride_start] == [
        s.frame_indices[0] for s in res.strides
    ]
    reasons = res.gate_reasons
    assert any(r is not None and r.startswith("registration_failed") for r in reasons)
    assert sum(r == "ok" for r in reasons) > 50
    # world poses chain the stride frames (dead reckoning across strides: each anchor's
    # 0.5° / 5 mm error turns the next stride's frame, so the drift grows with distance)
    world_truth = np.array([f.world_T_camera_true for f in frames])
    e_world = np.linalg.norm(res.smoothed_world_T_camera[:, :3, 3] - world_truth[:, :3, 3], axis=1)
    assert e_world[:33].max() < 0.02
    assert np.max(e_world) < 0.12


def test_variants_run_through_one_interface():
    for variant in ("icp+imu", "imu+kin"):
        res, frames = run(variant, duration_s=2.3)
        err = stride_errors_m(res, frames)
        assert len(res.frames) == len(frames)
        assert np.max(err[:2, 1]) < 0.03, (variant, err)
        if variant == "imu+kin":
            assert all(f.gate is None or f.gate.reason.startswith("previous") for f in res.frames)
            assert sum(s.n_icp_accepted for s in res.strides) == 0
        else:
            assert sum(s.n_kinematic for s in res.strides) == 0
    with pytest.raises(ConfigError, match="variant"):
        BackendConfig(variant="icp")


def test_bias_estimate_converges_to_known_bias():
    gyro_b = np.array([0.02, -0.015, 0.01])
    accel_b = np.array([0.15, -0.1, 0.2])
    res, frames = run(gyro_bias=gyro_b, accel_bias=accel_b, duration_s=5.6, swing_icp_drop=0.0)
    first = res.strides[0].bias_end
    last = res.strides[-2].bias_end  # the last full stride
    assert np.linalg.norm(last[3:] - gyro_b) < 0.004, last
    assert np.linalg.norm(last[:3] - accel_b) < 0.06, last
    assert np.linalg.norm(last[3:] - gyro_b) <= np.linalg.norm(first[3:] - gyro_b) + 1e-3
    err = stride_errors_m(res, frames)
    assert np.median(err[:-1, 1]) < 0.01


def test_nan_laden_imu_finishes_with_flagged_strides():
    rng = np.random.default_rng(3)

    def nans(t, g, a):
        g = g.copy()
        a = a.copy()
        g[rng.random(t.size) < 0.02] = np.nan
        a[300:330, 1] = np.nan  # 0.15 s block: a gap
        a[rng.random(t.size) < 0.01, 0] = np.inf
        return t, g, a

    res, frames = run(imu_mutator=nans, duration_s=2.3)
    assert len(res.frames) == len(frames)
    assert np.all(np.isfinite(res.smoothed_stride_T_camera))
    assert res.imu_counts["nonfinite"] > 30
    assert any("imu_gap" in s.flags for s in res.strides)
    assert any("imu_gap" in f.flags for f in res.frames)
    err = stride_errors_m(res, frames)
    assert np.max(err[:, 1]) < 0.05, err


def test_gap_laden_imu_finishes_with_flagged_strides():
    def gaps(t, g, a):
        keep = ~(((t > 0.5) & (t < 0.8)) | ((t > 1.6) & (t < 1.7)))
        t2 = t[keep].copy()
        t2[100] = t2[99]  # a duplicate timestamp: non-monotonic
        return t2, g[keep], a[keep]

    res, frames = run(imu_mutator=gaps, duration_s=2.3)
    assert res.imu_counts["non_monotonic"] == 1
    flagged = [s for s in res.strides if "imu_gap" in s.flags]
    assert len(flagged) == 2
    assert sum(s.n_imu_gaps for s in res.strides) == 8 + 2
    assert np.all(np.isfinite(res.smoothed_stride_T_camera))
    err = stride_errors_m(res, frames)
    assert np.max(err[:, 1]) < 0.05, err


def test_missed_foot_strike_continues_with_inflated_uncertainty():
    """The second strike is never reported: the stride runs past max_stride_s, a new graph
    starts from the previous end state (flagged), and the run completes."""
    res, frames = run(
        duration_s=4.5,
        strike_filter=lambda f: abs(f.t_s - 1.1) > 1e-6,
        priors={"max_stride_s": 2.0},
    )
    starts = [s.start for s in res.strides]
    assert "missed_foot_strike" in starts
    # the stance measurements taken on the un-announced new foothold are refused
    assert any("kin_inconsistent" in f.flags for f in res.frames)
    assert len(res.frames) == len(frames)
    assert np.all(np.isfinite(res.online_world_T_camera))
    world_truth = np.array([f.world_T_camera_true for f in frames])
    e = np.linalg.norm(res.online_world_T_camera[:, :3, 3] - world_truth[:, :3, 3], axis=1)
    assert np.max(e) < 0.1


def test_gtsam_failure_drops_the_offending_factor(monkeypatch):
    """An update that raises (GTSAM's bare RuntimeError) drops ICP first, rebuilds iSAM2 from
    the accepted factors, flags the stride, and goes on."""
    calls = {"n": 0}
    real_try = StrideGraph._try

    def flaky(self, tagged, new_values, k, rebuild):
        calls["n"] += 1
        if k == 5 and any(t == "icp" for t, _ in tagged):
            return None, "Indeterminant linear system (injected)"
        return real_try(self, tagged, new_values, k, rebuild)

    monkeypatch.setattr(StrideGraph, "_try", flaky)
    res, frames = run(duration_s=1.0)
    s = res.strides[0]
    assert "factor_dropped" in s.flags
    assert any(d.startswith("icp@5") for d in s.dropped_factors)
    assert "factor_dropped:icp" in res.frames[5].flags
    assert len(res.frames) == len(frames)


def test_online_covariances_on_request_and_bad_frame_time():
    res, _ = run(duration_s=1.0, covariances=True)
    cov = res.frames[10].covariance
    assert cov.shape == (6, 6) and np.all(np.linalg.eigvalsh(cov) > 0)
    sc = res.strides[0].smoothed_covariances
    assert sc.shape == (len(res.strides[0].frame_indices), 6, 6)
    # position sigma of a stance frame is a few mm
    assert 1e-4 < np.sqrt(sc[10, 3:, 3:].diagonal()).max() < 0.02
    slam = StrideSLAM()
    slam.add_imu(np.arange(0, 0.1, 0.005), np.zeros((20, 3)), np.tile([0, 0, 9.81], (20, 1)))
    slam.add_frame(0.05)
    with pytest.raises(EstimationError, match="after the previous frame"):
        slam.add_frame(0.05)


def test_isam2_gets_only_new_factors():
    """The graph holds each factor once: 3 priors + (imu [+icp] [+kin]) per frame."""
    slam = StrideSLAM(camera_T_imu=np.eye(4))
    t = np.arange(0, 0.3, 0.005)
    slam.add_imu(t, np.zeros((t.size, 3)), np.tile([0, 0, 9.81], (t.size, 1)))
    for tf in (0.0, 0.1, 0.2):
        slam.add_frame(tf)
    g = slam.strides.graph  # the open stride's graph
    assert g.graph.size() == 3 + 2
    assert g.isam.getFactorsUnsafe().size() == g.graph.size()
    p = g.estimate.atPose3(gtsam.symbol_shorthand.X(2))
    assert np.linalg.norm(p.translation()) < 1e-3  # static: stays put


def test_anchor_from_leg_model_and_joints():
    """With a LegModel, the first frame's pose is the kinematics' stride_T_camera computed
    with gravity from the IMU (camera_T_imu taken from the same model)."""
    from kinematics.leg_model import LegModel
    from kinematics.stride_frame import stride_T_camera

    model = LegModel()
    camera_T_imu = np.linalg.inv(model.thigh_T_frame("camera_optical")) @ model.thigh_T_frame("imu")
    q = np.array([0.3, 0.05])
    anchor = stride_T_camera(model, q, foot_pitch_rad=0.0, contact="foot_flat")
    stride_R_imu = (anchor.stride_T_camera @ camera_T_imu)[:3, :3]
    t = np.arange(0.0, 0.3, 0.005)
    up_imu = stride_R_imu.T @ np.array([0.0, 0.0, 9.81])  # static, foot flat on level ground
    slam = StrideSLAM(camera_T_imu=camera_T_imu, leg_model=model)
    slam.add_imu(t, np.zeros((t.size, 3)), np.tile(up_imu, (t.size, 1)))
    slam.add_joints(t, np.full(t.size, q[0]), np.full(t.size, q[1]))
    est = slam.add_frame(0.2)
    np.testing.assert_allclose(est.stride_T_camera, anchor.stride_T_camera, atol=1e-6)
    est = slam.add_frame(0.25, foot_loaded=True)
    assert est.kinematic_factor
    np.testing.assert_allclose(est.stride_T_camera, anchor.stride_T_camera, atol=1e-4)


def test_foot_strike_up_in_imu_sets_the_anchor_gravity():
    """``foot_strike(t, up_in_imu=...)``: the anchor's roll/pitch come from the caller's up
    vector, carried from the strike to the first frame by the gyro, not from the accelerometer
    mean (here deliberately wrong, like a decelerating swing leg)."""
    from scipy.spatial.transform import Rotation

    from kinematics.leg_model import LegModel
    from kinematics.stride_frame import stride_T_camera

    model = LegModel()
    camera_T_imu = np.linalg.inv(model.thigh_T_frame("camera_optical")) @ model.thigh_T_frame("imu")
    q = np.array([0.1, 0.0])
    t = np.arange(0.0, 0.4, 0.005)
    w = np.array([0.0, 0.0, 1.5])  # rad/s about the IMU z axis
    slam = StrideSLAM(camera_T_imu=camera_T_imu, leg_model=model)
    slam.add_imu(t, np.tile(w, (t.size, 1)), np.tile([6.0, 0.0, 7.0], (t.size, 1)))
    slam.add_joints(t, np.full(t.size, q[0]), np.full(t.size, q[1]))
    up_strike = np.array([-9.0, 1.0, 3.0])
    slam.foot_strike(0.1, up_in_imu=up_strike)
    est = slam.add_frame(0.3)
    strike_R_frame = Rotation.from_rotvec(w * 0.2).as_matrix()
    want = stride_T_camera(model, q, up_in_imu=strike_R_frame.T @ up_strike)
    np.testing.assert_allclose(est.stride_T_camera, want.stride_T_camera, atol=1e-5)
    default = stride_T_camera(model, q, up_in_imu=np.array([6.0, 0.0, 7.0]))
    assert np.abs(default.stride_T_camera - want.stride_T_camera).max() > 0.05
    with pytest.raises(EstimationError, match="up_in_imu"):
        slam.foot_strike(0.35, up_in_imu=np.array([np.nan, 0.0, 1.0]))


def test_tilt_covariance_replaces_roll_pitch_about_the_stride_origin():
    """``foot_strike(up_sigma_rad=σ)``: the anchor's tilt about the stride x/y axes (through the
    heel) gets σ, independent of the rest; yaw and position keep the kinematics' covariance."""
    from graph_slam.strides.kinematics import tilt_covariance
    from kinematics.conversions import adjoint_rot_first as adjoint

    rng = np.random.default_rng(3)
    a = rng.normal(size=(6, 6))
    cov = a @ a.T * 1e-3 + np.eye(6) * 1e-4
    pose = gtsam.Pose3(gtsam.Rot3.RzRyRx(0.1, -0.6, 0.2), np.array([0.1, 0.05, 0.7])).matrix()
    out = tilt_covariance(pose, cov, 0.01)
    ad = adjoint(pose)
    left_in, left_out = ad @ cov @ ad.T, ad @ out @ ad.T
    np.testing.assert_allclose(left_out[:2, :2], np.eye(2) * 1e-4, atol=1e-12)
    np.testing.assert_allclose(left_out[:2, 2:], 0.0, atol=1e-12)
    np.testing.assert_allclose(left_out[2:, 2:], left_in[2:, 2:], atol=1e-12)
    np.testing.assert_allclose(out, out.T, atol=1e-12)
    slam = StrideSLAM()
    with pytest.raises(EstimationError, match="up_sigma_rad"):
        slam.foot_strike(0.0, up_in_imu=np.array([0.0, 0.0, 9.8]), up_sigma_rad=-1.0)


def test_anchor_covariance_is_the_encoders_plus_tilt():
    """With a known up vector the anchor is uncertain by the encoders' FK error, the up vector's
    tilt and a small floor on yaw and position (the foot defines the stride frame); no contact
    noise. Checked in stride-frame (left) coordinates."""
    from graph_slam.strides.kinematics import anchor_covariance
    from kinematics.conversions import adjoint_rot_first as adjoint

    rng = np.random.default_rng(4)
    j = rng.normal(size=(6, 2)) * 0.3
    enc = j @ j.T * 1e-6  # rank 2, like J Σq Jᵀ for two encoders
    pose = gtsam.Pose3(gtsam.Rot3.RzRyRx(-1.9, 0.1, -1.6), np.array([0.2, 0.01, 0.55])).matrix()
    out = anchor_covariance(pose, enc, 0.003, 1e-3, 2e-3)
    ad = adjoint(pose)
    left, left_enc = ad @ out @ ad.T, ad @ enc @ ad.T
    np.testing.assert_allclose(left[:2, :2], np.eye(2) * 0.003**2, atol=1e-15)
    np.testing.assert_allclose(left[:2, 2:], 0.0, atol=1e-15)
    want = left_enc[2:, 2:] + np.diag([1e-3**2, 2e-3**2, 2e-3**2, 2e-3**2])
    np.testing.assert_allclose(left[2:, 2:], want, atol=1e-15)
    assert np.linalg.eigvalsh(out).min() > 0  # well conditioned for a prior


def test_imu_predicted_relative_motion_is_an_icp_guess_to_millimetres():
    """``predict_relative``: the camera motion from the latest state to the next frame,
    preintegrated from the current estimate (exact IMU): within 2 mm / 0.1° of the true
    motion between frames (the ICP guess of the real-time front end); None at a new stride."""
    syn = SyntheticConfig(duration_s=2.5, seed=0)
    st = synthetic_streams(syn)
    frames = simulate_measurements(
        st.frame_times_s, st.ground_truth.parent_T_child, st.events.foot_strikes_s, seed=100
    )
    slam = StrideSLAM(BackendConfig(), st.calibration.camera_T_imu)
    slam.add_imu(st.imu.t_s, st.imu.gyro_rad_s, st.imu.accel_m_s2)
    truth = np.asarray(st.ground_truth.parent_T_child)
    errs, nones = [], 0
    for i, f in enumerate(frames):
        if f.strike_before:
            slam.foot_strike(f.t_s)
        guess = slam.predict_relative(f.t_s)
        if guess is None:
            nones += 1
        elif i > 5:  # after the first frames, the velocity is known
            true = np.linalg.inv(truth[i - 1]) @ truth[i]
            errs.append(
                (np.linalg.norm(guess[:3, 3] - true[:3, 3]),
                 np.linalg.norm(gtsam.Rot3(guess[:3, :3].T @ true[:3, :3]).ypr()))
            )  # fmt: skip
        slam.add_frame(f.t_s, f.icp, f.foot_loaded, f.kinematics)
    errs = np.array(errs)
    assert nones >= 1 + sum(f.strike_before for f in frames[1:])  # first frame, each stride start
    assert errs[:, 0].max() < 0.002 and np.degrees(errs[:, 1].max()) < 0.1, errs.max(axis=0)


def test_deferred_smoothing_drains_oldest_first_down_to_keep():
    """``smooth_deferred(keep)`` smooths the oldest queued strides until ``keep`` wait; the
    rest, smoothed later, end as an all-at-once drain at the end does."""
    _, frames = run()
    st = synthetic_streams(SyntheticConfig(duration_s=4.5, seed=0))

    def streamed(keep_during: int | None):
        slam = StrideSLAM(BackendConfig(defer_smoothing=True), st.calibration.camera_T_imu)
        t, gyro, accel = st.imu.t_s, st.imu.gyro_rad_s, st.imu.accel_m_s2
        for chunk in np.array_split(np.arange(t.size), 20):
            slam.add_imu(t[chunk], gyro[chunk], accel[chunk])
        early = []
        for f in frames:
            if f.strike_before:
                slam.foot_strike(f.t_s)
            slam.add_frame(f.t_s, f.icp, f.foot_loaded, f.kinematics)
            if keep_during is not None:
                early += slam.smooth_deferred(keep_during)
                assert len(slam.strides.deferred) <= keep_during
        res = slam.finish()
        return res, early, slam.smooth_deferred()

    res_end, early_end, late_end = streamed(None)
    res_now, early_now, late_now = streamed(1)
    n = len(res_end.strides)
    assert early_end == [] and [s.index for s in late_end] == list(range(n))
    assert [s.index for s in early_now] == list(range(n - 2))  # oldest first, one left open
    assert [s.index for s in late_now] == [n - 2, n - 1]
    np.testing.assert_allclose(
        res_now.smoothed_stride_T_camera, res_end.smoothed_stride_T_camera, atol=1e-9
    )


@pytest.mark.parametrize(
    "first", [{"up_sigma_rad": None}, {"up_sigma_rad": 0.01, "up_assumed": True}]
)
def test_the_bias_is_loosened_only_out_of_a_stride_without_a_known_up_sigma(monkeypatch, first):
    """A first strike's up without σ (or resting on an assumption), then strikes with σ: only
    the carry out of the first anchored stride into the next is marked (``out_of_loose_tilt``)."""
    import graph_slam.backend.stride_chain as chain
    from kinematics.leg_model import LegModel

    marks = []
    real = chain.carried_priors

    def spy(*args, **kwargs):
        marks.append(args[-1])
        return real(*args, **kwargs)

    monkeypatch.setattr(chain, "carried_priors", spy)
    model = LegModel()
    camera_T_imu = np.linalg.inv(model.thigh_T_frame("camera_optical")) @ model.thigh_T_frame("imu")
    t = np.arange(0.0, 1.2, 0.005)
    up = np.array([0.0, 0.0, 9.81])
    slam = StrideSLAM(camera_T_imu=camera_T_imu, leg_model=model)
    slam.add_imu(t, np.zeros((t.size, 3)), np.tile(up, (t.size, 1)))
    slam.add_joints(t, np.full(t.size, 0.1), np.zeros(t.size))
    slam.add_frame(0.05)
    for t_strike, kw in (
        (0.2, first),
        (0.5, {"up_sigma_rad": 0.01}),
        (0.8, {"up_sigma_rad": 0.01}),
    ):
        slam.foot_strike(t_strike, up_in_imu=up, **kw)
        for k in range(5):
            slam.add_frame(t_strike + 0.02 + 0.04 * k, foot_loaded=True)
    assert marks == [False, True, False]


def test_velocity_change_takes_the_mean_acceleration_out_of_the_accelerometer():
    """``velocity_change``: over the open stride the accelerometer's gyro-rotated mean is
    gravity plus Δv/T (the IMU frame at the frame's time). Removing the estimated Δv/T
    brings its magnitude within 1 % of g at every frame 0.4 s or more into a stride,
    where the plain mean is up to 3 % off (the leg's velocity at a frame differs from the
    stride start's); None before the first frame."""
    from graph_slam.strides.gravity import GravityEstimator

    st = synthetic_streams(SyntheticConfig(duration_s=2.5, seed=0))
    frames = simulate_measurements(
        st.frame_times_s, st.ground_truth.parent_T_child, st.events.foot_strikes_s, seed=100
    )
    slam = StrideSLAM(BackendConfig(), st.calibration.camera_T_imu)
    slam.add_imu(st.imu.t_s, st.imu.gyro_rad_s, st.imu.accel_m_s2)
    gravity = GravityEstimator()
    gravity.add_imu(st.imu.t_s, st.imu.gyro_rad_s, st.imu.accel_m_s2)
    assert slam.velocity_change(frames[0].t_s) is None
    raw, corrected = [], []
    for f in frames:
        if f.strike_before:
            slam.foot_strike(f.t_s)
        change = slam.velocity_change(f.t_s)
        if change is not None and f.t_s - change[0] >= 0.4:
            window = f.t_s - change[0]
            mean = gravity.up_at(f.t_s, window)
            raw.append(np.linalg.norm(mean) / 9.81 - 1.0)
            corrected.append(np.linalg.norm(mean - change[1] / window) / 9.81 - 1.0)
        slam.add_frame(f.t_s, f.icp, f.foot_loaded, f.kinematics)
    assert len(corrected) > 20
    assert np.abs(corrected).max() < 0.01 and np.abs(raw).max() > 0.025, (raw, corrected)


def test_pose_covariance_is_the_frames_marginal_on_demand():
    """With per-frame covariances off, ``pose_covariance(k)`` gives what ``covariances: true``
    puts in the frame's estimate (same graph, same marginal; 1e-12); None without a state."""
    t = np.arange(0, 0.3, 0.005)
    out = {}
    for on in (False, True):
        slam = StrideSLAM(BackendConfig(covariances=on), camera_T_imu=np.eye(4))
        assert slam.pose_covariance(0) is None  # no open stride
        slam.add_imu(t, np.zeros((t.size, 3)), np.tile([0, 0, 9.81], (t.size, 1)))
        ests = [slam.add_frame(tf) for tf in (0.0, 0.1, 0.2)]
        out[on] = (slam.pose_covariance(2), ests[2].covariance)
        assert slam.pose_covariance(3) is None
    assert out[False][1] is None
    np.testing.assert_allclose(out[False][0], out[True][1], rtol=1e-9, atol=1e-12)
    assert np.all(np.linalg.eigvalsh(out[False][0]) > 0)

"""The session's first stride smoothed again with the first strike's up vector
(graph_slam.backend.first_stride): a recording begun mid-swing with a first anchor tilted
10° (the accelerometer mean of a moving leg), on the analytic synthetic session."""

from __future__ import annotations

import gtsam
import numpy as np

from graph_slam.backend import BackendConfig, KinematicMeasurement, StrideSLAM
from graph_slam.backend.config import PriorConfig
from graph_slam.backend.first_stride import relaxed_pose_prior, strike_attitude
from graph_slam.report.summary import rigid_fit
from graph_slam.session.synthetic import SyntheticConfig, synthetic_streams
from graph_slam.sim.measurements import simulate_measurements


def walk_from_mid_swing(refit: bool, tilt_deg: float = 10.0, seed: int = 0):
    """Frames from 70 % of the first stride on (in swing, no ICP in swing); the first frame's
    anchor tilted ``tilt_deg`` about the stride x axis. Returns (results, frames)."""
    st = synthetic_streams(SyntheticConfig(duration_s=2.6, seed=seed))
    strikes = st.events.foot_strikes_s
    keep = st.frame_times_s >= strikes[0] + 0.7 * (strikes[1] - strikes[0])
    frames = simulate_measurements(
        st.frame_times_s[keep],
        st.ground_truth.parent_T_child[keep],
        strikes,
        swing_icp_drop=1.0,
        seed=seed + 100,
    )
    cfg = BackendConfig(priors=PriorConfig(first_stride_refit=refit))
    slam = StrideSLAM(cfg, st.calibration.camera_T_imu)
    slam.add_imu(st.imu.t_s, st.imu.gyro_rad_s, st.imu.accel_m_s2)
    first = frames[0].kinematics
    tilt = gtsam.Rot3.Rx(np.deg2rad(tilt_deg)).matrix()
    wrong = np.eye(4)
    wrong[:3, :3] = tilt
    kin0 = KinematicMeasurement(wrong @ first.stride_T_camera, first.covariance)
    online = []
    for i, f in enumerate(frames):
        if f.strike_before and i > 0:
            slam.foot_strike(f.t_s)
        kin = kin0 if i == 0 else f.kinematics
        online.append(slam.add_frame(f.t_s, f.icp if i else None, f.foot_loaded, kin))
    return slam.finish(), frames


def world_errors_m(res, frames) -> tuple[np.ndarray, np.ndarray]:
    """Smoothed world position errors of the frames before and from the first strike, after an
    SE(3) fit over the frames from the first strike on."""
    est = res.smoothed_world_T_camera[:, :3, 3]
    truth = np.array([f.world_T_camera_true[:3, 3] for f in frames])
    pre = np.array([f.stride_index == frames[0].stride_index for f in frames])
    rot, t = rigid_fit(est[~pre], truth[~pre])
    err = np.linalg.norm(est @ rot.T + t - truth, axis=1)
    return err[pre], err[~pre]


def test_first_stride_before_the_first_strike_is_smoothed_with_its_up_vector():
    res, frames = walk_from_mid_swing(refit=True)
    pre, post = world_errors_m(res, frames)
    assert pre.size >= 5 and "first_stride_refit" in res.strides[0].flags
    assert pre.mean() < 0.02 and pre.max() < 0.03  # measured 10 / 14 mm
    off, frames_off = walk_from_mid_swing(refit=False)
    pre_off, post_off = world_errors_m(off, frames_off)
    assert pre_off.mean() > 0.08  # measured 176 mm: the tilted gravity, the unknown velocity
    np.testing.assert_allclose(post, post_off, atol=1e-9)  # later strides unchanged
    # the online (causal) poses are untouched
    np.testing.assert_allclose(res.online_world_T_camera, off.online_world_T_camera, atol=1e-12)


def test_strike_attitude_carries_the_anchor_up_back_by_the_gyro():
    params = gtsam.PreintegrationCombinedParams.MakeSharedU(9.81)
    pim = gtsam.PreintegratedCombinedMeasurements(params, gtsam.imuBias.ConstantBias())
    w = np.array([0.0, 1.0, 0.0])  # rad/s about the IMU y axis for 0.1 s
    for _ in range(10):
        pim.integrateMeasurement(np.array([0.0, 0.0, 9.81]), w, 0.01)
    stride_T_camera = np.eye(4)
    stride_T_camera[:3, :3] = gtsam.Rot3.Rx(0.2).matrix()
    cov = np.diag([0.01**2, 0.01**2, 0.01**2, 1e-6, 1e-6, 1e-6])  # isotropic rotation
    a = strike_attitude(KinematicMeasurement(stride_T_camera, cov), np.eye(4), pim)
    up_now = stride_T_camera[:3, :3].T @ [0.0, 0.0, 1.0]
    want = gtsam.Rot3.Ry(0.1).matrix() @ up_now  # last_R_now: 0.1 rad about y
    np.testing.assert_allclose(a.up_in_imu, want, atol=1e-9)
    assert np.isclose(a.sigma_rad, 0.01, rtol=1e-6)


def test_relaxed_pose_prior_loosens_only_the_tilt():
    pose = gtsam.Pose3(gtsam.Rot3.Rz(0.4), np.array([0.1, 0.0, 0.5]))
    cov = np.diag(np.r_[np.full(3, 1e-4), np.full(3, 1e-6)])
    prior = gtsam.PriorFactorPose3(0, pose, gtsam.noiseModel.Gaussian.Covariance(cov))
    new = relaxed_pose_prior(prior, 0.5)
    assert new.prior().equals(pose, 1e-12)
    cov_new = np.asarray(new.noiseModel().covariance())
    from kinematics.conversions import adjoint_rot_first

    ad = adjoint_rot_first(pose.matrix())
    left = ad @ cov_new @ ad.T
    np.testing.assert_allclose(np.diag(left)[:2], 0.25, rtol=1e-6)  # tilt about stride x/y
    left_old = ad @ cov @ ad.T
    np.testing.assert_allclose(left[2:, 2:], left_old[2:, 2:], rtol=1e-6, atol=1e-15)

"""Factors, noise, gating and the IMU extrinsic of graph_slam.backend."""

from __future__ import annotations

import gtsam
import numpy as np
import pytest

from graph_slam.backend import factors
from graph_slam.backend.config import GateConfig, ImuNoiseConfig
from graph_slam.backend.gating import gate_icp
from graph_slam.backend.imu import ImuBuffer, check_imu_samples
from graph_slam.backend.keys import X
from graph_slam.backend.measurements import IcpMeasurement
from graph_slam.errors import EstimationError

RNG = np.random.default_rng(7)


def random_pose(rng, scale=0.5):
    return gtsam.Pose3.Expmap(rng.normal(0, scale, 6))


def numerical_jacobian(f, poses, which, eps=1e-6):
    """d f / d ξ for the right perturbation poses[which]·Exp(ξ) (central differences)."""
    cols = []
    for d in range(6):
        xi = np.zeros(6)
        xi[d] = eps
        plus = list(poses)
        minus = list(poses)
        plus[which] = poses[which].compose(gtsam.Pose3.Expmap(xi))
        minus[which] = poses[which].compose(gtsam.Pose3.Expmap(-xi))
        cols.append((f(*plus) - f(*minus)) / (2 * eps))
    return np.column_stack(cols)


CAMERA_T_IMU = gtsam.Pose3(gtsam.Rot3.RzRyRx(0.3, -1.2, 2.0), np.array([0.05, -0.1, 0.02])).matrix()


def test_icp_between_factor_matches_camera_frame_definition():
    """Whitened error and Jacobians of the IMU-frame factor equal numerical derivatives of
    the camera-frame definition Rc·Log(M⁻¹ (Xi A⁻¹)⁻¹ (Xj A⁻¹)), A = camera_T_imu,
    X = stride_T_imu."""
    a = gtsam.Pose3(CAMERA_T_IMU)
    m = random_pose(RNG, 0.1)
    rc = np.triu(RNG.normal(0, 1, (6, 6))) + 5 * np.eye(6)
    rc[4] = 0.0  # a dropped (degenerate) direction
    f = factors.icp_between_factor(0, 1, m.matrix(), rc, CAMERA_T_IMU, kernel="none")
    xi, xj = random_pose(RNG), random_pose(RNG)

    def camera_error(pi, pj):
        return rc @ gtsam.Pose3.Logmap(
            m.between(pi.compose(a.inverse()).between(pj.compose(a.inverse())))
        )

    values = gtsam.Values()
    values.insert(X(0), xi)
    values.insert(X(1), xj)
    np.testing.assert_allclose(f.whitenedError(values), camera_error(xi, xj), atol=1e-9)
    jf = f.linearize(values)
    a_mat, b = jf.jacobian()
    np.testing.assert_allclose(-b, camera_error(xi, xj), atol=1e-9)
    num = np.hstack([numerical_jacobian(camera_error, [xi, xj], w) for w in (0, 1)])
    np.testing.assert_allclose(a_mat, num, atol=1e-6)


def test_kinematic_factor_matches_camera_frame_definition():
    a = gtsam.Pose3(CAMERA_T_IMU)
    meas = random_pose(RNG, 0.3)
    l = RNG.normal(0, 0.01, (6, 6))
    cov = l @ l.T + 1e-4 * np.eye(6)
    f = factors.kinematic_prior_factor(0, meas.matrix(), cov, CAMERA_T_IMU)
    r = np.linalg.cholesky(np.linalg.inv(cov)).T  # RᵀR = Σ⁻¹

    def camera_error(x):
        return r @ gtsam.Pose3.Logmap(meas.between(x.compose(a.inverse())))

    x = random_pose(RNG)
    values = gtsam.Values()
    values.insert(X(0), x)
    e = camera_error(x)
    assert np.linalg.norm(f.whitenedError(values)) == pytest.approx(np.linalg.norm(e), rel=1e-8)
    a_mat, _ = f.linearize(values).jacobian()
    num = numerical_jacobian(camera_error, [x], 0)
    # Whitening is unique up to an orthogonal factor: compare the information AᵀA.
    np.testing.assert_allclose(a_mat.T @ a_mat, num.T @ num, rtol=1e-6, atol=1e-3)


def test_pure_rotation_about_camera_axis_gives_imu_frame_rates():
    """Camera spinning about its own optical axis at 1 rad/s: the IMU sees imu_R_camera·ω,
    and preintegrating those IMU-frame rates turns the camera about its own z axis only."""
    w_cam = np.array([0.0, 0.0, 1.0])
    imu_R_camera = np.linalg.inv(CAMERA_T_IMU)[:3, :3]
    gyro_imu = imu_R_camera @ w_cam
    t = np.arange(0, 1.001, 0.005)
    stride_T_camera0 = np.eye(4)
    stride_T_imu0 = stride_T_camera0 @ CAMERA_T_IMU
    g_imu = stride_T_imu0[:3, :3].T @ np.array([0, 0, 9.81])  # static, no centripetal (lever)
    # A lever arm makes the IMU circle: give the exact specific force of that motion.
    r_cam_imu = CAMERA_T_IMU[:3, 3]  # IMU origin in the camera frame
    accel = []
    for ti in t:
        rz = gtsam.Rot3.Rz(ti).matrix()
        world_R_imu = rz @ CAMERA_T_IMU[:3, :3]
        acc_world = rz @ np.cross(w_cam, np.cross(w_cam, r_cam_imu))
        accel.append(world_R_imu.T @ (acc_world + np.array([0, 0, 9.81])))
    del g_imu
    buf = ImuBuffer(ImuNoiseConfig())
    buf.add(t, np.tile(gyro_imu, (t.size, 1)), np.array(accel))
    seg = buf.integrate(0.0, 0.5, gtsam.imuBias.ConstantBias())
    v0 = np.cross(w_cam, r_cam_imu)
    pred = seg.pim.predict(gtsam.NavState(gtsam.Pose3(stride_T_imu0), v0), seg.pim.biasHat())
    stride_T_camera = pred.pose().matrix() @ np.linalg.inv(CAMERA_T_IMU)
    expected = gtsam.Rot3.Rz(0.5).matrix()
    np.testing.assert_allclose(stride_T_camera[:3, :3], expected, atol=1e-6)
    np.testing.assert_allclose(stride_T_camera[:3, 3], 0.0, atol=1e-4)


def _icp(info, **kw):
    base = dict(
        source_index=1,
        target_index=0,
        target_T_source=np.eye(4),
        information=info,
        fitness=0.9,
        inlier_rmse_m=0.004,
        correspondences=1000,
    )
    base.update(kw)
    return IcpMeasurement(**base)


def test_gate_rules_and_reasons():
    cfg = GateConfig()
    info = np.diag([1e4] * 3 + [1e6] * 3)
    assert gate_icp(_icp(info), cfg).reason == "ok"
    assert gate_icp(_icp(info, fitness=0.1), cfg).reason.startswith("low_fitness")
    assert gate_icp(_icp(info, inlier_rmse_m=0.05), cfg).reason.startswith("high_rmse")
    assert gate_icp(_icp(info, correspondences=10), cfg).reason.startswith("few_correspondences")
    failed = _icp(np.zeros((6, 6)), ok=False, reason="empty cloud")
    d = gate_icp(failed, cfg)
    assert not d.accepted and "empty cloud" in d.reason
    big = np.eye(4)
    big[0, 3] = 1.0
    assert gate_icp(_icp(info, target_T_source=big), cfg).reason.startswith("implausible_step")
    nan_info = info.copy()
    nan_info[0, 0] = np.nan
    assert gate_icp(_icp(nan_info), cfg).reason == "nonfinite"
    with pytest.raises(EstimationError):
        _icp(np.eye(5))


def test_degenerate_floor_direction_gets_zero_information():
    """A flat floor: translation in the plane (x, y) and yaw are unobservable. The gate
    keeps the other three directions with their information and zeroes the rest."""
    info = np.diag([1e4, 1e4, 1e-3, 1e-2, 1e-2, 1e6])
    d = gate_icp(_icp(info), GateConfig())
    assert d.accepted and d.rank == 3 and d.reason == "partial (3 DoF)"
    for axis in (2, 3, 4):
        e = np.zeros(6)
        e[axis] = 1.0
        assert e @ d.information @ e == pytest.approx(0.0, abs=1e-9)
    assert d.information[5, 5] == pytest.approx(1e6)
    np.testing.assert_allclose(d.sqrt_information.T @ d.sqrt_information, d.information, atol=1e-6)
    # Rotated degenerate subspace, reported by eigen data: still removed.
    q, _ = np.linalg.qr(RNG.normal(size=(6, 6)))
    lam = np.array([1e-4, 1e-4, 1e5, 1e5, 1e5, 1e5])
    info = q @ np.diag(lam) @ q.T
    d = gate_icp(_icp(info, eigenvalues=lam, eigenvectors=q), GateConfig())
    assert d.rank == 4
    np.testing.assert_allclose(d.information @ q[:, :2], 0.0, atol=1e-6)
    fully = gate_icp(_icp(np.zeros((6, 6))), GateConfig())
    assert not fully.accepted and fully.reason.startswith("degenerate")


def test_gate_takes_the_front_ends_count_of_constrained_directions():
    """With ``dof`` (the front end's degeneracy test) the gate does not re-decide from the
    information's eigenvalues (mixed units): k ≥ min_rank is a partial factor with the
    information as given, fewer is rejected (the frame is bridged), 6 is registered."""
    info = np.diag([1e4, 1e4, 0.0, 0.0, 0.0, 1e6])
    d = gate_icp(_icp(info, dof=3), GateConfig())
    assert d.accepted and d.reason == "partial (3 DoF)" and d.rank == 3
    np.testing.assert_allclose(d.information, info)
    low = gate_icp(_icp(np.diag([1e4, 0, 0, 0, 0, 1e6]), dof=2), GateConfig())
    assert not low.accepted and low.reason == "degenerate (rank 2 < 3)"
    full = gate_icp(_icp(np.diag([1e4, 1e4, 1e4, 1e-3, 1e6, 1e6]), dof=6), GateConfig())
    assert full.accepted and full.reason == "ok"  # 1e-3 < ratio·λmax: the count decides


def test_imu_checks_count_every_rejection():
    cfg = ImuNoiseConfig()
    t = np.array([0.0, 0.005, 0.005, 0.01, 0.004, 0.015, 0.02])
    g = np.zeros((7, 3))
    a = np.tile([0, 0, 9.81], (7, 1))
    g[3, 1] = np.nan
    a[5, 2] = 1e4
    check = check_imu_samples(t, g, a, cfg)
    assert check.counts == {"nonfinite": 1, "non_monotonic": 2, "out_of_range": 1}
    assert check.usable.tolist() == [True, True, False, False, False, False, True]
    with pytest.raises(EstimationError, match="N×3"):
        check_imu_samples(t, g[:3], a, cfg)


def test_imu_gap_splits_preintegration():
    buf = ImuBuffer(ImuNoiseConfig(max_gap_s=0.02))
    t = np.r_[np.arange(0, 0.2, 0.005), np.arange(0.3, 0.5, 0.005)]
    buf.add(t, np.zeros((t.size, 3)), np.tile([0, 0, 9.81], (t.size, 1)))
    assert buf.integrate(0.0, 0.15, gtsam.imuBias.ConstantBias()).ok
    gap = buf.integrate(0.15, 0.35, gtsam.imuBias.ConstantBias())
    assert not gap.ok and gap.reason == "imu_gap" and gap.max_hold_s > 0.09
    assert buf.integrate(0.31, 0.45, gtsam.imuBias.ConstantBias()).ok


def test_contact_point_jacobian_matches_numerical():
    """The stance contact-point factor: residual R·p + t − p_stride, Jacobian vs numerical
    derivatives (right perturbation, rotation first) and through gtsam's linearisation."""
    import gtsam

    from graph_slam.backend.factors import contact_point_factor, contact_point_residual
    from graph_slam.backend.keys import X

    rng = np.random.default_rng(7)
    pose = gtsam.Pose3.Expmap(rng.normal(size=6) * 0.5)
    p_imu = np.array([0.05, -0.6, 0.2])
    p_stride = np.array([0.26, 0.0, 0.0])
    err, h = contact_point_residual(pose.matrix(), p_imu, p_stride)
    np.testing.assert_allclose(err, pose.transformFrom(p_imu) - p_stride, atol=1e-12)
    num = np.zeros((3, 6))
    eps = 1e-6
    for i in range(6):
        d = np.zeros(6)
        d[i] = eps
        plus = contact_point_residual(
            pose.compose(gtsam.Pose3.Expmap(d)).matrix(), p_imu, p_stride
        )[0]
        minus = contact_point_residual(
            pose.compose(gtsam.Pose3.Expmap(-d)).matrix(), p_imu, p_stride
        )[0]
        num[:, i] = (plus - minus) / (2 * eps)
    np.testing.assert_allclose(h, num, atol=1e-7)
    f = contact_point_factor(3, p_imu, p_stride, sigma_m=0.004, kernel="none")
    values = gtsam.Values()
    values.insert(X(3), pose)
    np.testing.assert_allclose(f.unwhitenedError(values), err, atol=1e-12)
    a, b = f.linearize(values).jacobian()
    np.testing.assert_allclose(a, h / 0.004, atol=1e-6)
    np.testing.assert_allclose(b, -err / 0.004, atol=1e-9)


def test_factors_use_the_canonical_adjoint_gtsam_convention():
    """``kinematics.conversions.adjoint_rot_first`` (the one adjoint) is GTSAM's
    ``Pose3.AdjointMap`` (rotation first): the camera<->IMU covariance transport agrees."""
    from kinematics.conversions import adjoint_rot_first

    pose = random_pose(RNG)
    np.testing.assert_allclose(adjoint_rot_first(pose.matrix()), pose.AdjointMap(), atol=1e-12)
    a = RNG.normal(size=(6, 6))
    cov = a @ a.T
    ad = gtsam.Pose3(CAMERA_T_IMU).AdjointMap()
    np.testing.assert_allclose(
        factors.imu_cov_to_camera(cov, CAMERA_T_IMU), ad @ cov @ ad.T, atol=1e-10
    )
    assert not hasattr(factors, "adjoint")  # no second copy in the back end


def test_imu_interval_reads_no_sample_beyond_the_first_after_its_end():
    """Preintegration over [t0, t1] is the same whether samples after the first one at or
    after t1 have arrived: online, a frame waits one IMU period for that sample and reads
    nothing further ahead (causal replay)."""
    from graph_slam.backend.config import ImuNoiseConfig
    from graph_slam.backend.imu import ImuBuffer

    rng = np.random.default_rng(4)
    t = np.arange(0.0, 0.2, 0.005)
    gyro = rng.normal(size=(t.size, 3)) * 0.5
    accel = rng.normal(size=(t.size, 3)) + np.array([0.0, 0.0, 9.81])
    bias = gtsam.imuBias.ConstantBias()
    t0, t1 = 0.0512, 0.1113
    full, part = ImuBuffer(ImuNoiseConfig()), ImuBuffer(ImuNoiseConfig())
    full.add(t, gyro, accel)
    k = np.searchsorted(t, t1, side="left") + 1  # up to the first sample at/after t1
    part.add(t[:k], gyro[:k], accel[:k])
    a, b = full.integrate(t0, t1, bias), part.integrate(t0, t1, bias)
    assert a.ok and b.ok
    np.testing.assert_array_equal(
        np.asarray(a.pim.deltaRij().matrix()), np.asarray(b.pim.deltaRij().matrix())
    )
    np.testing.assert_array_equal(np.asarray(a.pim.deltaVij()), np.asarray(b.pim.deltaVij()))
    np.testing.assert_array_equal(np.asarray(a.pim.deltaPij()), np.asarray(b.pim.deltaPij()))


def _integrate_one_sample_at_a_time(buf, t0, t1, bias):
    """The preintegration written one sample at a time (the vectorised one's reference)."""
    t, acc, gyr = buf._t, buf._accel, buf._gyro
    i0 = int(np.searchsorted(t, t0, side="right")) - 1
    i1 = int(np.searchsorted(t, t1, side="left"))
    pim = gtsam.PreintegratedCombinedMeasurements(buf.params, bias)
    for j in range(i0, min(i1, t.size)):
        s, e = max(t[j], t0), min(t[j + 1] if j + 1 < min(i1, t.size) else t1, t1)
        if e - s <= 0:
            continue
        mid = (s + e) / 2.0
        if j + 1 >= t.size:
            a, g = acc[j], gyr[j]
        else:
            w = (mid - t[j]) / (t[j + 1] - t[j])
            a, g = (1 - w) * acc[j] + w * acc[j + 1], (1 - w) * gyr[j] + w * gyr[j + 1]
        pim.integrateMeasurement(a, g, float(e - s))
    return pim


@pytest.mark.parametrize("t1", [0.1113, 0.1150, 0.31], ids=["inside", "on_sample", "held"])
def test_imu_integration_equals_one_sample_at_a_time_and_is_remembered(t1):
    """The vectorised midpoint samples give the same preintegration as the per-sample loop
    (bit for bit, the last sample held past the buffer's end); asked again with the same
    interval, bias and samples the same segment comes back, and new samples or another bias
    integrate afresh."""
    from graph_slam.backend.config import ImuNoiseConfig
    from graph_slam.backend.imu import ImuBuffer

    rng = np.random.default_rng(7)
    t = np.arange(0.0, 0.3, 0.005)
    gyro = rng.normal(size=(t.size, 3)) * 0.5
    accel = rng.normal(size=(t.size, 3)) + np.array([0.0, 0.0, 9.81])
    buf = ImuBuffer(ImuNoiseConfig(max_gap_s=0.05))
    buf.add(t, gyro, accel)
    bias = gtsam.imuBias.ConstantBias(np.array([0.01, -0.02, 0.03]), np.array([1e-3, 0, -1e-3]))
    seg = buf.integrate(0.0512, t1, bias)
    ref = _integrate_one_sample_at_a_time(buf, 0.0512, t1, bias)
    assert seg.ok
    for name in ("deltaPij", "deltaVij", "preintMeasCov"):
        np.testing.assert_array_equal(
            np.asarray(getattr(seg.pim, name)()), np.asarray(getattr(ref, name)()), err_msg=name
        )
    np.testing.assert_array_equal(seg.pim.deltaRij().matrix(), ref.deltaRij().matrix())
    assert buf.integrate(0.0512, t1, bias) is seg
    assert buf.integrate(0.0512, t1, gtsam.imuBias.ConstantBias()) is not seg
    buf.add(np.array([0.31]), gyro[:1], accel[:1])
    assert buf.integrate(0.0512, t1, gtsam.imuBias.ConstantBias()) is not seg


def test_fixed_transforms_are_the_per_frame_ones():
    """The extrinsic's inverse and adjoint, computed once per matrix, are the per-frame
    ``np.linalg.inv`` / ``adjoint_rot_first`` bit for bit, read-only, and another extrinsic
    gets its own."""
    from graph_slam.backend.factors import fixed_transforms
    from kinematics.conversions import adjoint_rot_first

    rng = np.random.default_rng(3)
    for _ in range(3):
        m = gtsam.Pose3(gtsam.Rot3.Expmap(rng.normal(size=3)), rng.normal(size=3) * 0.1).matrix()
        inverse, ad = fixed_transforms(m)
        np.testing.assert_array_equal(inverse, np.linalg.inv(m))
        np.testing.assert_array_equal(ad, adjoint_rot_first(m))
        assert not inverse.flags.writeable and not ad.flags.writeable
        assert fixed_transforms(m.copy())[0] is inverse

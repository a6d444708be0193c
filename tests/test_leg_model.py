"""LegModel: FK vs hand-computed planar geometry, Jacobians vs finite differences,
covariance vs Monte-Carlo, URDF parameters, channel mismatch."""

from __future__ import annotations

import math

import numpy as np
import pytest

from kinematics.conversions import expmap_rot_first, logmap_rot_first
from kinematics.errors import EncoderError, LegModelError
from kinematics.leg_model import ContactNoise, LegModel
from kinematics.leg_params import LegParams, leg_urdf

P = LegParams()


@pytest.fixture(scope="module")
def model() -> LegModel:
    return LegModel()


def ry(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def planar_foot_T_camera(knee: float, ankle: float, p: LegParams = P) -> np.ndarray:
    """Hand-derived sagittal-plane geometry (x forward, z up; flexion rotates about +y)."""
    knee_pos = np.array([0.0, 0.0, -p.thigh_length_m])
    shank_dir = np.array([-math.sin(knee), 0.0, -math.cos(knee)])  # flexion swings foot back
    ankle_pos = knee_pos + p.shank_length_m * shank_dir
    foot_angle = knee - ankle  # foot rotation about +y relative to thigh
    r_foot = ry(foot_angle)
    heel = ankle_pos + r_foot @ np.array([-p.heel_behind_ankle_m, 0.0, -p.ankle_height_m])
    pitch = p.mount_pitch_down_rad
    cam = np.array([p.mount_forward_m, 0.0, -p.thigh_length_m + p.mount_height_above_knee_m])
    view = np.array([math.cos(pitch), 0.0, -math.sin(pitch)])
    up = np.array([math.sin(pitch), 0.0, math.cos(pitch)])
    r_cam = np.column_stack([up, [0.0, -1.0, 0.0], view])  # portrait
    out = np.eye(4)
    out[:3, :3] = r_foot.T @ r_cam
    out[:3, 3] = r_foot.T @ (cam - heel)
    return out


def test_straight_leg_known_answer(model: LegModel) -> None:
    t = model.foot_T_camera([0.0, 0.0])
    # heel 0.06 behind and 0.08 below the ankle; camera 0.08 in front, 0.20 above the knee.
    np.testing.assert_allclose(t[:3, 3], [0.14, 0.0, 0.08 + 0.44 + 0.20], atol=1e-12)
    view_in_foot = t[:3, 2]
    assert math.degrees(math.asin(-view_in_foot[2])) == pytest.approx(35.0, abs=1e-9)
    imu = model.foot_T_imu([0.0, 0.0])
    np.testing.assert_allclose(imu[:3, 3], [0.06, -0.06, 0.08 + 0.44 + 0.15], atol=1e-12)


@pytest.mark.parametrize(
    "q", [(0.0, 0.0), (0.3, 0.1), (1.2, -0.4), (math.pi / 2, 0.0), (0.05, 0.3), (2.0, -0.5)]
)
def test_fk_matches_planar_geometry(model: LegModel, q: tuple[float, float]) -> None:
    np.testing.assert_allclose(model.foot_T_camera(q), planar_foot_T_camera(*q), atol=1e-9)


def test_knee_at_ninety_degrees_hand_numbers(model: LegModel) -> None:
    # Shank horizontal backwards, foot rotated 90 deg (toe down):
    # heel = knee + (-0.44 - 0.08, 0, 0.06).
    t = model.foot_T_camera([math.pi / 2, 0.0])
    cam_in_thigh = np.array([0.08, 0.0, -0.24])
    heel_in_thigh = np.array([-0.44 - 0.08, 0.0, -0.44 + 0.06])
    np.testing.assert_allclose(
        t[:3, 3], ry(math.pi / 2).T @ (cam_in_thigh - heel_in_thigh), atol=1e-9
    )


@pytest.mark.parametrize("q", [(0.2, 0.05), (1.0, -0.3), (0.6, 0.25)])
@pytest.mark.parametrize("which", ["camera", "imu"])
@pytest.mark.parametrize("perturbation", ["right", "left"])
def test_jacobians_match_finite_differences(model, q, which, perturbation) -> None:
    fk = model.foot_T_camera if which == "camera" else model.foot_T_imu
    jac_fn = model.foot_T_camera_jacobian if which == "camera" else model.foot_T_imu_jacobian
    jac = jac_fn(q, perturbation)
    assert jac.shape == (6, 2)
    t0 = fk(q)
    h = 1e-6
    for i in range(2):
        dq = np.zeros(2)
        dq[i] = h
        tp, tm = fk(np.add(q, dq)), fk(np.subtract(q, dq))
        if perturbation == "right":
            num = (
                logmap_rot_first(np.linalg.inv(t0) @ tp) - logmap_rot_first(np.linalg.inv(t0) @ tm)
            ) / (2 * h)
        else:
            num = (
                logmap_rot_first(tp @ np.linalg.inv(t0)) - logmap_rot_first(tm @ np.linalg.inv(t0))
            ) / (2 * h)
        np.testing.assert_allclose(jac[:, i], num, atol=1e-7)


def test_jacobian_rotation_rows_are_the_planar_rates(model: LegModel) -> None:
    # In the sagittal plane the foot-camera rotation is about y: d/dknee = -1, d/dankle = +1
    # (foot rotation is knee - ankle about +y; the camera is fixed on the thigh).
    jac = model.foot_T_camera_jacobian([0.4, 0.1])
    r_cam = model.foot_T_camera([0.4, 0.1])[:3, :3]
    axis_in_cam = r_cam.T @ np.array([0.0, 1.0, 0.0])
    np.testing.assert_allclose(jac[:3, 0], -axis_in_cam, atol=1e-12)
    np.testing.assert_allclose(jac[:3, 1], axis_in_cam, atol=1e-12)


def test_covariance_matches_monte_carlo(model: LegModel) -> None:
    rng = np.random.default_rng(42)
    q0 = np.array([0.35, 0.05])
    cov_q = np.array(
        [
            [np.radians(0.8) ** 2, 0.3 * np.radians(0.8) * np.radians(0.5)],
            [0.3 * np.radians(0.8) * np.radians(0.5), np.radians(0.5) ** 2],
        ]
    )
    contact_cov = ContactNoise().covariance("heel_strike")
    predicted = model.camera_covariance(q0, cov_q, contact="heel_strike")
    t0 = model.foot_T_camera(q0)
    n = 6000
    qs = rng.multivariate_normal(q0, cov_q, size=n)
    eps = rng.multivariate_normal(np.zeros(6), contact_cov, size=n)
    samples = np.empty((n, 6))
    for k in range(n):
        # ground_T_camera = ground_T_foot0 Exp(eps) foot_T_camera(q); ground_T_foot0 = I.
        t = expmap_rot_first(eps[k]) @ model.foot_T_camera(qs[k])
        samples[k] = logmap_rot_first(np.linalg.inv(t0) @ t)
    sampled = np.cov(samples.T)
    sig_p, sig_s = np.sqrt(np.diag(predicted)), np.sqrt(np.diag(sampled))
    np.testing.assert_allclose(sig_s, sig_p, rtol=0.05)  # 6000 samples: sigma within ~2 %
    corr_p = predicted / np.outer(sig_p, sig_p)
    corr_s = sampled / np.outer(sig_s, sig_s)
    np.testing.assert_allclose(corr_s, corr_p, atol=0.05)


def test_encoder_only_covariance_is_rank_two(model: LegModel) -> None:
    cov = model.camera_covariance([0.3, 0.0], np.radians(0.5) ** 2)
    eig = np.linalg.eigvalsh(cov)
    assert np.sum(eig > 1e-12) == 2
    flat = model.camera_covariance([0.3, 0.0], np.radians(0.5) ** 2, contact="foot_flat")
    strike = model.camera_covariance([0.3, 0.0], np.radians(0.5) ** 2, contact="heel_strike")
    assert np.trace(strike) > np.trace(flat) > np.trace(cov)


def test_params_override_without_xml_and_shipped_urdf() -> None:
    from graph_slam_models import model_path

    shipped = model_path("urdf/transfemoral_leg.urdf")
    assert shipped.read_text() == leg_urdf(LegParams())
    from_file = LegModel.from_urdf(shipped)
    np.testing.assert_allclose(
        from_file.foot_T_camera([0.5, 0.1]), LegModel().foot_T_camera([0.5, 0.1])
    )

    p = LegParams(
        mount_pitch_down_rad=math.radians(42.0),
        thigh_length_m=0.47,
        shank_length_m=0.41,
        mount_height_above_knee_m=0.25,
    )
    m = LegModel(p)
    np.testing.assert_allclose(
        m.foot_T_camera([0.7, -0.2]), planar_foot_T_camera(0.7, -0.2, p), atol=1e-9
    )
    r = m.thigh_T_frame("camera_optical")[:3, :3]
    assert math.degrees(math.asin(-r[2, 2])) == pytest.approx(42.0)
    assert abs(r[1, 0]) < 1e-12 and r[1, 1] == pytest.approx(
        -1.0
    )  # portrait: image x in sagittal plane
    land = LegModel(LegParams(camera_orientation="landscape")).thigh_T_frame("camera_optical")
    assert land[1, 0] == pytest.approx(-1.0)  # landscape: image x to the wearer's right
    assert land[2, 1] < 0  # image y points down


def test_params_validation_and_mapping() -> None:
    with pytest.raises(LegModelError, match="30-45 deg"):
        LegParams(mount_pitch_down_rad=math.radians(20))
    with pytest.raises(LegModelError, match="thigh_length_m"):
        LegParams(thigh_length_m=-0.1)
    with pytest.raises(
        LegModelError, match=r"cfg.yaml: unknown leg parameter\(s\) \['thigh_len'\]"
    ):
        LegParams.from_mapping({"thigh_len": 0.4}, source="cfg.yaml")
    p = LegParams.from_mapping({"shank_length_m": 0.4, "knee_limits_rad": [0.0, 2.0]})
    assert p.shank_length_m == 0.4 and p.knee_limits_rad == (0.0, 2.0)
    assert LegParams.from_mapping(P.to_dict()) == P


def test_channel_mismatch_lists_both(model: LegModel) -> None:
    np.testing.assert_array_equal(model.channel_order(["ankle", "knee"]), [1, 0])
    with pytest.raises(
        LegModelError,
        match=r"\['knee', 'hip'\].*\['knee', 'ankle'\].*missing: \['ankle'\]"
        r".*unexpected: \['hip'\]",
    ):
        model.channel_order(["knee", "hip"])
    with pytest.raises(LegModelError):
        model.channel_order(["knee", "knee"])


def test_urdf_with_other_joints_is_rejected() -> None:
    xml = leg_urdf().replace('name="ankle"', 'name="ankle_pitch"')
    with pytest.raises(LegModelError, match=r"\['knee', 'ankle'\].*\['knee', 'ankle_pitch'\]"):
        LegModel(urdf_xml=xml, source="custom.urdf")
    with pytest.raises(LegModelError, match="camera_optical"):
        LegModel(urdf_xml=leg_urdf().replace("camera_optical", "cam"))


def test_bad_q_is_rejected(model: LegModel) -> None:
    with pytest.raises(EncoderError, match="NaN"):
        model.foot_T_camera([np.nan, 0.0])
    with pytest.raises(EncoderError, match=r"'knee' = 2\.5000 rad is outside its URDF limits"):
        model.foot_T_camera([2.5, 0.0])
    with pytest.raises(EncoderError, match="shape"):
        model.foot_T_camera([0.1, 0.2, 0.3])

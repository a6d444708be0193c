"""The gait-driven simulator: pinned stance foot, IMU consistency, encoder FK, rendered depth,
noise statistics, determinism and a valid session (graph_slam.sim)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from graph_slam.session.reader import open_session
from graph_slam.session.validation import validate_session
from graph_slam.sim import SimConfig, simulate
from graph_slam.sim.config import CameraProfile, DropModel, ImuProfile, MotionConfig, load_profile
from graph_slam.sim.motion import GaitMotion
from graph_slam.sim.quicklook import write_quicklook
from graph_slam.sim.render import Renderer, intrinsics_for
from graph_slam.sim.scene import load_scene
from graph_slam.sim.sensors import apply_depth_noise, depth_sigma_m, frame_schedule, simulate_imu
from kinematics.leg_model import LegModel
from kinematics.leg_params import LegParams

LEG = LegParams()


@pytest.fixture(scope="module", params=[0.8, 1.4])
def motion(request) -> GaitMotion:
    return GaitMotion(request.param, 3, seed=4, leg=LEG, cfg=MotionConfig())


@pytest.fixture(scope="module")
def leg_model() -> LegModel:
    return LegModel(LEG)


def test_stance_foot_stays_put(motion: GaitMotion) -> None:
    t = np.arange(0.0, motion.duration_s, 1e-3)
    heel = motion.world_T_heel(t)
    toe = heel[:, :3, 3] + heel[:, :3, 0] * LEG.foot_length_m
    pinned = motion.pinned_mask(t)
    stride = np.searchsorted(motion.foot_strikes_s, t, side="right") - 1
    for k in range(motion.strides):
        sel = pinned & (stride == k)
        assert sel.sum() > 100
        on_heel = heel[sel, 2, 3] <= toe[sel, 2] + 1e-12
        heel_pts, toe_pts = heel[sel, :3, 3][on_heel], toe[sel][~on_heel]
        assert np.abs(heel_pts - heel_pts[0]).max() < 1e-3  # the heel does not slide...
        assert np.abs(toe_pts - toe_pts[0]).max() < 1e-3  # ...nor the toe after foot flat
        assert abs(heel_pts[0, 2]) < 1e-9 and abs(toe_pts[0, 2]) < 1e-9  # on the floor
    # The hip moves forward about at the walking speed.
    assert 0.7 * motion.speed_m_s < motion.mean_speed_m_s < 1.3 * motion.speed_m_s


def test_noise_free_imu_integrates_to_the_trajectory(motion: GaitMotion, leg_model) -> None:
    thigh_T_imu = leg_model.thigh_T_frame("imu")
    rate = 1000.0  # at 400 Hz the foot-flat shocks (~4 g, ~30 ms) leave ~1.4 cm per stride
    t0 = motion.foot_strikes_s[1]
    t = t0 + np.arange(int(motion.nominal_stride_s * rate) + 1) / rate
    gyro, accel = motion.imu_ideal(t, thigh_T_imu)
    truth = motion.world_T(t, thigh_T_imu)
    rot = truth[0, :3, :3].copy()
    pos = truth[0, :3, 3].copy()
    vel = motion.velocity_world(t[:1], thigh_T_imu)[0]
    g = np.array([0.0, 0.0, -9.81])
    dt = 1.0 / rate
    for i in range(t.size - 1):
        a0 = rot @ accel[i] + g
        rot_next = rot @ Rotation.from_rotvec(0.5 * (gyro[i] + gyro[i + 1]) * dt).as_matrix()
        a1 = rot_next @ accel[i + 1] + g
        pos = pos + vel * dt + (2 * a0 + a1) / 6 * dt**2
        vel = vel + 0.5 * (a0 + a1) * dt
        rot = rot_next
    assert np.linalg.norm(pos - truth[-1, :3, 3]) < 0.003  # < 3 mm after a whole stride
    angle = Rotation.from_matrix(rot.T @ truth[-1, :3, :3]).magnitude()
    assert math.degrees(angle) < 0.2


def test_encoder_fk_reproduces_the_camera_pose_in_stance(motion: GaitMotion, leg_model) -> None:
    thigh_T_camera = leg_model.thigh_T_frame("camera_optical")
    t = np.arange(0.0, motion.duration_s, 1 / 500)  # the encoder clock
    knee, ankle = motion.joint_angles(t)
    world_T_camera = motion.world_T(t, thigh_T_camera)
    heel = motion.world_T_heel(t)
    pinned = motion.pinned_mask(t)
    flat = pinned & (np.abs(heel[:, 2, 0]) < 1e-12)  # foot flat: the heel frame is fixed
    assert flat.sum() > 50
    for i in np.flatnonzero(pinned)[::7]:
        fk = heel[i] @ leg_model.foot_T_camera([knee[i], ankle[i]])
        assert np.abs(fk - world_T_camera[i]).max() < 1e-9
    stride = np.searchsorted(motion.foot_strikes_s, t, side="right") - 1
    for k in range(motion.strides):
        idx = np.flatnonzero(flat & (stride == k))
        anchor = heel[idx[0]]  # one fixed foot pose on the floor for the whole foot-flat
        assert abs(anchor[2, 3]) < 1e-12 and abs(anchor[2, 2] - 1.0) < 1e-12
        for i in idx[::5]:
            fk = anchor @ leg_model.foot_T_camera([knee[i], ankle[i]])
            assert np.abs(fk - world_T_camera[i]).max() < 1e-6


def test_rendered_depth_of_the_floor_matches_geometry() -> None:
    scene = load_scene("flat-floor")
    camera = load_profile(CameraProfile, "d455")
    k = intrinsics_for(camera, fast=True)
    renderer = Renderer(scene, k, camera, noise_scale=0.0, motion_blur=False)
    pitch = math.radians(40.0)
    pose = np.eye(4)  # optical axis 40° below +x, image x up (portrait), camera 0.6 m high
    z_axis = np.array([math.cos(pitch), 0.0, -math.sin(pitch)])
    y_axis = np.array([0.0, -1.0, 0.0])
    pose[:3, :3] = np.column_stack([np.cross(y_axis, z_axis), y_axis, z_axis])
    pose[:3, 3] = [0.0, 0.0, 0.6]
    depth, color = renderer.render(pose, np.random.default_rng(0))
    u, v = np.meshgrid(np.arange(k.width_px), np.arange(k.height_px))
    rays = np.stack([(u - k.cx_px) / k.fx_px, (v - k.cy_px) / k.fy_px, np.ones(u.shape)], -1)
    down = -(rays @ pose[:3, :3].T)[..., 2]
    expected = np.where(down > 1e-6, 0.6 / np.where(down > 1e-6, down, 1.0), np.inf)
    in_range = (expected >= camera.min_range_m) & (expected <= camera.max_range_m)
    valid = depth > 0
    assert valid.sum() > 0.5 * valid.size
    assert not np.any(valid & ~in_range)
    assert np.abs(depth[valid] - expected[valid]).max() < 1e-5
    assert color is not None and color.std() > 5  # the floor is textured


def test_depth_noise_statistics_match_the_profile() -> None:
    noise = load_profile(CameraProfile, "d455").noise
    rng = np.random.default_rng(3)
    z = np.full((400, 500), 2.0, np.float32)
    out = apply_depth_noise(z, np.ones_like(z), noise, rng, min_range_m=0.3, max_range_m=6.0)
    valid = out > 0
    assert abs(1 - valid.mean() - noise.random_dropout_prob) < 0.002  # no edges on a plane
    sigma = float(depth_sigma_m(np.float32(2.0), noise))
    assert sigma == pytest.approx(noise.sigma_at_1m_m * 4 + noise.sigma_floor_m)
    assert out[valid].std() == pytest.approx(sigma, rel=0.03)
    # A depth step makes an edge: its pixels drop out or fly at about the profile's rates.
    step = np.where(np.arange(500) < 250, 1.0, 2.0).astype(np.float32)[None].repeat(400, 0)
    out = apply_depth_noise(step, np.ones_like(step), noise, rng, noise_scale=1e-6)
    edge = out[:, 249:251]
    assert (edge == 0).mean() == pytest.approx(noise.edge_dropout_prob, abs=0.05)
    flying = (edge > 1.01) & (edge < 1.99)
    p_fly = (1 - noise.edge_dropout_prob) * noise.flying_pixel_prob
    assert flying.mean() == pytest.approx(p_fly, abs=0.05)


def test_imu_noise_and_frame_drops_match_their_profiles(leg_model) -> None:
    motion = GaitMotion(1.1, 8, seed=2, leg=LEG)
    profile = load_profile(ImuProfile, "thigh_imu")
    quiet = profile.model_copy(
        update={"gyro_random_walk_rad_s2_sqrt_hz": 0.0, "accel_random_walk_m_s3_sqrt_hz": 0.0}
    )
    imu, ideal = simulate_imu(
        motion, leg_model.thigh_T_frame("imu"), quiet, np.random.default_rng(1), rate_hz=400.0
    )
    err_g = imu.gyro_rad_s - ideal.gyro_rad_s
    err_a = imu.accel_m_s2 - ideal.accel_m_s2
    assert err_g.std(axis=0) == pytest.approx(
        [profile.gyro_noise_density_rad_s_sqrt_hz * 20.0] * 3, rel=0.05
    )  # σ_d = density · √400
    assert err_a.std(axis=0) == pytest.approx(
        [profile.accel_noise_density_m_s2_sqrt_hz * 20.0] * 3, rel=0.05
    )
    sat, _ = simulate_imu(
        motion, leg_model.thigh_T_frame("imu"), profile, np.random.default_rng(1), accel_range_g=2
    )
    assert np.abs(sat.accel_m_s2).max() <= 2 * 9.81 + 1e-9
    # Thesis: 90 Hz recorded at 35-40 Hz effective.
    drops = load_profile(CameraProfile, "d455").drops
    t, _ = frame_schedule(600.0, 90.0, drops, np.random.default_rng(5))
    assert 35.0 <= t.size / 600.0 <= 40.0
    assert np.all(np.diff(t) > 0)
    t_none, _ = frame_schedule(10.0, 90.0, DropModel(model="none"), np.random.default_rng(5))
    assert t_none.size == 901


def test_same_seed_same_bytes_and_a_valid_session(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1700000000")
    from graph_slam.cli import main

    cfg = SimConfig(strides=1, seed=3, fast=True, speed_m_s=1.4)
    result = simulate(cfg, tmp_path / "a")
    write_quicklook(result)  # the caller's step, as graph-slam simulate does
    a = result.path
    with pytest.raises(SystemExit) as exit_info:  # the command gives the same session
        main(
            ["simulate", "--out", str(tmp_path / "b"), "--strides", "1", "--seed", "3",
             "--fast", "--speed", "fast"]
        )  # fmt: skip
    assert exit_info.value.code == 0
    files_a = sorted(p.relative_to(a) for p in a.rglob("*") if p.is_file())
    files_b = sorted(p.relative_to(tmp_path / "b") for p in (tmp_path / "b").rglob("*"))
    assert files_a == [f for f in files_b if (tmp_path / "b" / f).is_file()]
    for rel in files_a:
        assert (a / rel).read_bytes() == (tmp_path / "b" / rel).read_bytes(), rel
    report = validate_session(a)
    assert report.ok, report.problems
    session = open_session(a)
    assert set(session.events.source) == {"load_cell"}
    assert session.ground_truth is not None and len(session.ground_truth) == session.n_frames
    assert session.scene is not None and session.scene.object("Box1").size_m[2] == 0.1905
    assert (a / "quicklook.png").stat().st_size > 10_000
    truth = (a / "events_truth.csv").read_text().splitlines()
    assert truth[0] == "t_s,kind,source" and all(r.endswith(",truth") for r in truth[1:])
    # Load-cell events lag the true ones by the profile's latency (15 ms ± 3 ms).
    t_true = np.array([float(r.split(",")[0]) for r in truth[1:]])
    lag = session.events.t_s[: t_true.size] - t_true[: session.events.t_s.size]
    assert np.all((lag > 0.0) & (lag < 0.03))
    c = simulate(cfg.model_copy(update={"seed": 4, "quicklook": False}), tmp_path / "c").path
    assert (c / "depth/000000.png").read_bytes() != (a / "depth/000000.png").read_bytes()

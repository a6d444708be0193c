"""The terrain-following walker: pinned stance on treads and slopes, no penetration, swing
clearance, IMU and forward-kinematics consistency, the scenes' truth (fast: no rendering)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from graph_slam.sim.footholds import TERRAIN_LABELS
from graph_slam.sim.scene import load_scene
from graph_slam.sim.walker import GROUND_TOLERANCE_M, TerrainMotion
from kinematics.leg_model import LegModel
from kinematics.leg_params import LegParams

LEG = LegParams()
SCENES = (
    "stairs-ascent", "stairs-descent", "ramp-up-8", "ramp-down-10", "curb-up", "step-over",
    "step-onto",
)  # fmt: skip


@pytest.fixture(scope="module")
def leg_model() -> LegModel:
    return LegModel(LEG)


@pytest.fixture(scope="module", params=SCENES)
def walk(request):
    scene = load_scene(request.param)
    return scene, TerrainMotion(1.1, 4, seed=3, surfaces=scene.surfaces, leg=LEG)


def test_height_function_matches_the_geometry() -> None:
    scene = load_scene("stairs-ascent")
    x = np.array([0.5, 0.95, 1.2, 2.4, 3.0, 0.95])
    y = np.array([0.0, 0.0, 0.3, 0.0, 0.0, 0.7])  # the last is beside the 1.2 m wide flight
    assert np.allclose(scene.height_at(x, y), [0.0, 0.17, 0.34, 1.02, 1.02, 0.0])
    ramp = load_scene("ramp-up-8")
    assert scene.height_at(np.zeros((2, 3)), np.zeros((2, 3))).shape == (2, 3)
    slope = (ramp.height_at(2.0, 0.0) - ramp.height_at(1.5, 0.0)) / 0.5
    assert math.degrees(math.atan(slope)) == pytest.approx(8.0, abs=0.01)


def test_stance_foot_is_pinned_and_on_the_surface(walk) -> None:
    scene, m = walk
    t = np.arange(0.0, m.duration_s, 1e-3)
    heel = m.world_T_heel(t)
    toe = m.world_toe(t)
    stance = m.stance_mask(t)
    stride = np.searchsorted(m.foot_strikes_s, t, side="right") - 1
    for k in range(m.strides):
        idx = np.flatnonzero(stance & (stride == k))
        f = m.stride_footholds[k]
        # the pivot (heel, then toe) never moves: the lowest sole point is fixed on the surface
        flat = idx[np.abs(np.arctan2(heel[idx, 2, 0], heel[idx, 0, 0]) - f.slope_rad) < 1e-12]
        assert flat.size > 20
        assert np.ptp(heel[flat, :3, 3], axis=0).max() < 1e-6
        assert np.ptp(toe[idx[-5:]], axis=0).max() < 1e-6  # rolling over the toe
        assert heel[flat[0], 2, 3] == pytest.approx(f.heel_z_m, abs=1e-9)
    # no point of the sole below the surface, at any sample
    for frac in np.linspace(0.0, 1.0, 9):
        p = heel[:, :3, 3] + frac * LEG.foot_length_m * heel[:, :3, 0]
        gap = p[:, 2] - scene.height_at(p[:, 0], p[:, 1])
        assert gap.min() > -GROUND_TOLERANCE_M


def test_swing_clears_the_edges_by_the_margin(walk) -> None:
    _, m = walk
    for k in range(1, m.strides + 1):
        gap, ground = m._swing_clearance(k, m._lift[k])
        assert gap >= -1e-9 or not np.isfinite(gap)
        assert ground > -GROUND_TOLERANCE_M
    assert set(m.stride_labels) <= set(TERRAIN_LABELS)


def test_imu_integration_and_fk_reproduce_the_motion(walk, leg_model) -> None:
    _, m = walk
    thigh_T_imu = leg_model.thigh_T_frame("imu")
    rate = 1000.0
    t0 = m.foot_strikes_s[1]
    t = t0 + np.arange(int((m.foot_strikes_s[2] - t0) * rate) + 1) / rate
    gyro, accel = m.imu_ideal(t, thigh_T_imu)
    truth = m.world_T(t, thigh_T_imu)
    rot, pos = truth[0, :3, :3].copy(), truth[0, :3, 3].copy()
    vel = m.velocity_world(t[:1], thigh_T_imu)[0]
    g = np.array([0.0, 0.0, -9.81])
    dt = 1.0 / rate
    steps = Rotation.from_rotvec(gyro * dt).as_matrix()
    for i in range(t.size - 1):
        acc = rot @ accel[i] + g
        pos = pos + vel * dt + 0.5 * acc * dt * dt
        vel = vel + acc * dt
        rot = rot @ steps[i]
    assert np.linalg.norm(pos - truth[-1, :3, 3]) < 0.005
    assert math.degrees(Rotation.from_matrix(rot.T @ truth[-1, :3, :3]).magnitude()) < 0.3
    # encoders: the leg model's FK from the heel frame gives the camera pose
    thigh_T_camera = leg_model.thigh_T_frame("camera_optical")
    ts = np.arange(0.0, m.duration_s, 0.013)
    knee, ankle = m.joint_angles(ts)
    cam = m.world_T(ts, thigh_T_camera)
    heel = m.world_T_heel(ts)
    for i in range(0, ts.size, 5):
        fk = heel[i] @ leg_model.foot_T_camera([knee[i], ankle[i]], check_limits=False)
        assert np.abs(fk - cam[i]).max() < 1e-9


def test_the_camera_climbs_the_stairs(leg_model) -> None:
    scene = load_scene("stairs-ascent")
    m = TerrainMotion(1.1, 4, seed=1, surfaces=scene.surfaces, leg=LEG)
    cam = m.world_T(m.foot_strikes_s, leg_model.thigh_T_frame("camera_optical"))
    assert m.stride_labels[:4] == ["stairs_up"] * 4
    assert cam[-1, 2, 3] - cam[0, 2, 3] > 0.5
    z = [f.heel_z_m for f in m.stride_footholds]
    assert np.allclose(np.diff(z[1:4]), 0.34)  # step over step: two risers a stride


def test_features_truth_lists_steps_and_ramp() -> None:
    feats = {f.name: f for f in load_scene("terrain-course").surfaces.features()}
    stairs = feats["Stairs"]
    assert len(stairs.steps) == 4 and stairs.steps[0].rise_m == pytest.approx(0.17)
    assert stairs.steps[0].nosing_m[0][2] == pytest.approx(0.3513 + 0.17)
    assert feats["Ramp"].slope_deg == pytest.approx(8.0, abs=0.01)
    assert feats["Ramp"].start_line_m[0][0] == pytest.approx(1.5)


#: Bands (deg) around published means: level walking (Schwartz et al. 2008, the curves the
#: level walker plays), stair ascent (Riener et al. 2002; Protopapadaki et al. 2007), ramps
#: (McIntosh et al. 2006). docs/simulator.md has the table and what is not met (the ankle).
BANDS = {
    "level": {"knee_swing": (50, 80), "thigh_max": (20, 50), "knee_stance": (10, 45)},
    "ramp_up": {"knee_swing": (50, 85), "thigh_max": (25, 55), "knee_strike": (5, 25)},
    "ramp_down": {"knee_swing": (50, 85), "thigh_max": (20, 50)},
    "stairs_up": {"knee_swing": (85, 110), "thigh_max": (50, 80), "knee_strike": (50, 65)},
}


@pytest.mark.parametrize("scene", ["flat-floor", "stairs-ascent", "ramp-up-10", "ramp-down-8"])
def test_joint_angles_within_the_published_bands(scene) -> None:
    from graph_slam.bench.terrain_walk import joint_peaks

    rows = [r for r in joint_peaks(scene, "normal", 4) if r["label"] in BANDS]
    labels = {r["label"] for r in rows}
    assert labels & set(BANDS)
    for r in rows:
        if r["label"] == "level" and r["knee_strike"] > 30:  # arrived from the stairs
            continue
        for key, (lo, hi) in BANDS[r["label"]].items():
            assert lo <= r[key] <= hi, (scene, r["label"], key, r[key])


def test_the_camera_goes_down_the_stairs(leg_model) -> None:
    scene = load_scene("stairs-descent")
    m = TerrainMotion(1.1, 4, seed=1, surfaces=scene.surfaces, leg=LEG)
    cam = m.world_T(m.foot_strikes_s, leg_model.thigh_T_frame("camera_optical"))
    assert m.stride_labels[1:4] == ["stairs_down"] * 3
    assert cam[0, 2, 3] - cam[-1, 2, 3] > 0.5
    z = [f.heel_z_m for f in m.stride_footholds]
    assert np.allclose(np.diff(z[1:4]), -0.34)  # step over step
    knee_strike = [
        r["knee_strike"] for r in _peaks("stairs-descent") if r["label"] == "stairs_down"
    ]
    assert all(5 <= k <= 20 for k in knee_strike)  # Riener et al. 2002: ~10-15° at contact


def _peaks(scene):
    from graph_slam.bench.terrain_walk import joint_peaks

    return joint_peaks(scene, "normal", 4)


#: Published ankle ranges (deg, plantarflexion −, dorsiflexion +) of a stride that stays in
#: one activity: level walking (Winter 2009: −20 ± 5° at toe-off, ≤ 15° in stance), stair
#: ascent and descent (Riener et al. 2002; Protopapadaki et al. 2007: up to ~20–25°), ramps
#: (McIntosh et al. 2006: up to ~20–25° going up). The URDF's limit (20°) is the tighter.
ANKLE_RANGES_DEG = {
    "level": (-25.0, 15.0), "stairs_up": (-25.0, 25.0), "stairs_down": (-25.0, 25.0),
    "ramp_up": (-25.0, 25.0), "ramp_down": (-25.0, 25.0),
}  # fmt: skip
ANKLE_SCENES = (
    "stairs-ascent", "stairs-descent", "ramp-up-5", "ramp-up-8", "ramp-up-10", "ramp-down-5",
    "ramp-down-8", "ramp-down-10", "curb-up", "curb-down", "step-over", "step-onto",
    "terrain-course",
)  # fmt: skip


@pytest.mark.parametrize("speed_m_s", [0.8, 1.4])
def test_ankle_stays_within_the_urdf_limits_and_published_ranges(leg_model, speed_m_s) -> None:
    lower, upper = (math.degrees(lim[1]) for lim in
                    (leg_model.lower_limits_rad, leg_model.upper_limits_rad))  # fmt: skip
    assert upper == pytest.approx(20.0) and lower == pytest.approx(-30.0)
    checked = set()
    for name in ANKLE_SCENES:
        m = TerrainMotion(speed_m_s, 4, seed=3, surfaces=load_scene(name).surfaces, leg=LEG)
        for k, label in enumerate(m.stride_labels):
            t = np.linspace(m.foot_strikes_s[k], m.foot_strikes_s[k + 1], 300)[:-1]
            ankle = np.degrees(m.joint_angles(t)[1])
            assert lower <= ankle.min() and ankle.max() <= upper, (name, k, label)
            arrived = "level" if k == 0 else m.stride_labels[k - 1]
            if arrived == label and label in ANKLE_RANGES_DEG:
                lo, hi = ANKLE_RANGES_DEG[label]
                assert lo <= ankle.min() and ankle.max() <= hi + 1e-6, (name, k, label, ankle.min(),
                                                                 ankle.max())  # fmt: skip
                checked.add(label)
    assert checked == set(ANKLE_RANGES_DEG)

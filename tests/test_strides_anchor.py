"""The stride anchor: the ground plane fused with the IMU's up only where it is level
(known answers on synthetic planes; no rendering)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from graph_slam.frontend.floor import FloorConfig
from graph_slam.frontend.treads import TreadsConfig
from graph_slam.strides.anchor import StrideAnchor
from tests.test_frontend_treads import flight_points

PITCH = math.radians(35.0)
# world x forward, y left, z up; camera (optical: x right, y down, z forward) 35° down
Z_CAM = np.array([math.cos(PITCH), 0.0, -math.sin(PITCH)])
X_CAM = np.array([0.0, -1.0, 0.0])
WORLD_R_CAMERA = np.column_stack([X_CAM, np.cross(Z_CAM, X_CAM), Z_CAM])
CAMERA_POS = np.array([0.0, 0.0, 0.6])


class FakeGravity:
    """The IMU's up (IMU frame = camera frame here) with a chosen error, for any window."""

    def __init__(self, up_world: np.ndarray) -> None:
        self.up = 9.81 * WORLD_R_CAMERA.T @ (up_world / np.linalg.norm(up_world))

    def window_before(self, t_s: float) -> float:
        return 1.1

    def up_at(self, t_s: float, window_s: float) -> np.ndarray:
        return self.up

    def history_s(self, t_s: float) -> float:
        return 10.0


def ramp_points(slope_deg: float, seed: int = 0, n: int = 4000) -> np.ndarray:
    """Camera-frame points of ground rising along +x at ``slope_deg`` (1 mm noise)."""
    rng = np.random.default_rng(seed)
    x = rng.uniform(0.5, 2.0, n)
    y = rng.uniform(-0.6, 0.6, n)
    z = math.tan(math.radians(slope_deg)) * x + rng.normal(0.0, 0.001, n)
    world = np.column_stack([x, y, z])
    return (world - CAMERA_POS) @ WORLD_R_CAMERA


def anchor_for(up_world, **floor) -> StrideAnchor:
    return StrideAnchor(FakeGravity(np.asarray(up_world, float)), FloorConfig(**floor),
                        np.eye(4), 0.01, 0.8, 0.2)  # fmt: skip


def tilt_deg(up_camera: np.ndarray) -> float:
    up = WORLD_R_CAMERA @ (up_camera / np.linalg.norm(up_camera))
    return math.degrees(math.acos(min(1.0, up[2])))


@pytest.mark.parametrize("slope_deg", [5.0, 8.0, -10.0])
def test_a_slope_is_recorded_and_the_frame_stays_level(slope_deg):
    a = anchor_for([0.0, 0.0, 1.0]).at_strike(0.0, 0.05, ramp_points(slope_deg))
    assert a.case == "slope"
    assert math.degrees(a.slope_rad) == pytest.approx(slope_deg, abs=0.1)
    assert math.degrees(a.contact_slope_rad) == pytest.approx(slope_deg, abs=0.1)
    assert tilt_deg(a.up_in_imu) < 1e-5  # the IMU's up, untouched: the frame is level
    assert "anchor:slope" in a.flags and any(f.startswith("slope_deg:") for f in a.flags)


def test_level_ground_is_fused_as_before():
    imu_error = math.radians(1.0)  # the IMU's up 1° off (an accelerometer bias)
    up = [math.sin(imu_error), 0.0, math.cos(imu_error)]
    new = anchor_for(up).at_strike(0.0, 0.05, ramp_points(0.0))
    old = anchor_for(up, assume_level=True).at_strike(0.0, 0.05, ramp_points(0.0))
    assert new.case == old.case == "floor"
    assert np.allclose(new.up_in_imu, old.up_in_imu) and new.sigma_rad == old.sigma_rad
    assert tilt_deg(new.up_in_imu) < 0.1  # the plane fixed the IMU's tilt
    assert new.contact_slope_rad == 0.0


def test_the_level_ground_anchor_tilts_with_a_gentle_ramp():
    """Today's level-ground anchor on a 3° ramp tilts the stride frame by almost the slope;
    the new one keeps the IMU's (here exact) up."""
    points = ramp_points(3.0)
    old = anchor_for([0.0, 0.0, 1.0], assume_level=True).at_strike(0.0, 0.05, points)
    new = anchor_for([0.0, 0.0, 1.0]).at_strike(0.0, 0.05, points)
    assert old.case == "floor" and tilt_deg(old.up_in_imu) > 2.5
    assert new.case == "slope" and tilt_deg(new.up_in_imu) < 1e-5


def test_no_depth_or_no_imu():
    anchor = anchor_for([0.0, 0.0, 1.0])
    assert anchor.at_strike(0.0, 0.05, None).case == "imu"
    anchor.gravity.up_at = lambda t, w: None
    assert anchor.at_strike(0.0, 0.05, ramp_points(0.0)).case == "none"


def test_a_first_strike_takes_the_ground_as_level():
    """Under a second of IMU history the up vector is too poor to tell a slope: fused."""
    anchor = StrideAnchor(FakeGravity(np.array([0.0, 0.0, 1.0])), FloorConfig(), np.eye(4),
                          0.01, 100.0, 0.2)  # fmt: skip
    a = anchor.at_strike(0.0, 0.05, ramp_points(8.0))
    assert a.case == "floor" and a.sigma_rad < 0.01
    assert tilt_deg(a.up_in_imu) == pytest.approx(8.0, abs=0.2)


class FirstStrikeGravity(FakeGravity):
    """A session's first strike: under a second of IMU history (no σ for its up)."""

    def history_s(self, t_s: float) -> float:
        return 0.3


def test_a_plane_taken_as_level_at_the_first_strike_is_an_assumption():
    a = StrideAnchor(FirstStrikeGravity(np.array([0.0, 0.0, 1.0])), FloorConfig(), np.eye(4),
                     0.01, 0.8, 0.2).at_strike(0.0, 0.05, ramp_points(0.0))  # fmt: skip
    assert a.case == "floor" and a.assumed
    b = anchor_for([0.0, 0.0, 1.0]).at_strike(0.0, 0.05, ramp_points(0.0))
    assert b.case == "floor" and not b.assumed  # tested against the IMU's σ: not assumed


def _first_strike_anchor() -> StrideAnchor:
    return StrideAnchor(FakeGravity(np.array([0.0, 0.0, 1.0])), FloorConfig(), np.eye(4),
                        0.01, 100.0, 0.2)  # fmt: skip


def _in_camera(p_world) -> np.ndarray:
    return (np.asarray(p_world, float) - CAMERA_POS) @ WORLD_R_CAMERA


def test_a_first_strike_refuses_a_plane_that_does_not_pass_under_the_heel():
    """Stairs ahead of a first strike on level floor: the plane through the nosings (31° on a
    0.17/0.28 flight, here its points alone) is no ground the foot stands on; the heel
    (from the encoders) is 0.38 m below it, so the IMU's up is kept. The floor itself,
    through the heel, is still taken."""
    rng = np.random.default_rng(1)
    x = rng.uniform(0.9, 2.0, 4000)
    slope = math.atan2(0.17, 0.28)
    nosings = np.column_stack([x, rng.uniform(-0.6, 0.6, x.size),
                               math.tan(slope) * (x - 0.9) + 0.17])  # fmt: skip
    heel = _in_camera([0.0, 0.0, 0.0])
    refused = _first_strike_anchor().at_strike(0.0, 0.05, _in_camera(nosings), heel)
    assert refused.case == "imu" and refused.fit is not None and not refused.fit.ok
    assert refused.fit.reason.startswith("not_under_heel")
    assert tilt_deg(refused.up_in_imu) < 1e-5
    # without the heel the old rule took that plane as level: a 31° tilt
    blind = _first_strike_anchor().at_strike(0.0, 0.05, _in_camera(nosings))
    assert blind.case == "floor" and tilt_deg(blind.up_in_imu) > 25.0
    floor = _first_strike_anchor().at_strike(0.0, 0.05, ramp_points(0.0), heel)
    assert floor.case == "floor" and tilt_deg(floor.up_in_imu) < 0.1
    off = _first_strike_anchor().at_strike(0.0, 0.05, ramp_points(0.0), _in_camera([0, 0, -0.1]))
    assert off.case == "imu"


def test_a_first_strike_finds_the_floor_under_the_heel_far_from_a_poor_up():
    """A first strike's IMU up 45° off (under a second of history): with the heel known the
    floor is searched within 60° of it and fused (the frame level); a wall through the heel
    and the camera is refused (the camera does not stand above it)."""
    tilt = math.radians(45.0)
    gravity = FakeGravity(np.array([math.sin(tilt), 0.0, math.cos(tilt)]))
    anchor = StrideAnchor(gravity, FloorConfig(), np.eye(4), 0.01, 100.0, 0.2)
    heel = _in_camera([0.0, 0.0, 0.0])
    a = anchor.at_strike(0.0, 0.05, ramp_points(0.0), heel)
    assert a.case == "floor" and tilt_deg(a.up_in_imu) < 0.1
    assert anchor.at_strike(0.0, 0.05, ramp_points(0.0)).case == "imu"  # no heel: 45° is off
    rng = np.random.default_rng(2)
    wall = np.column_stack([np.zeros(4000), rng.uniform(-0.6, 0.6, 4000),
                            rng.uniform(0.0, 1.2, 4000)])  # fmt: skip
    w = anchor.at_strike(0.0, 0.05, _in_camera(wall), heel)
    assert w.case == "imu" and w.fit.reason.startswith("not_under_camera")


def test_a_ramp_ahead_of_the_heel_leaves_the_contact_level():
    """The plane is the ground's slope ahead; the contact factors take it only when it passes
    under the stance heel: a heel 0.3 m before an 8° ramp (4.2 cm below its plane) keeps
    the last stride's contact (level here), a heel on the ramp takes its slope. The frame's up is the IMU's in
    both (a sloped plane is never fused)."""
    points = ramp_points(8.0)
    on = anchor_for([0.0, 0.0, 1.0]).at_strike(0.0, 0.05, points, _in_camera([0.02, 0.0, 0.0028]))
    before = anchor_for([0.0, 0.0, 1.0]).at_strike(0.0, 0.05, points, _in_camera([-0.3, 0, 0]))
    assert on.case == before.case == "slope"
    assert math.degrees(on.contact_slope_rad) == pytest.approx(8.0, abs=0.1)
    assert on.heel_off_m < 0.002 and not any(f.startswith("heel_off") for f in on.flags)
    assert on.previous_slope_rad == 0.0  # a fresh anchor: the last stride's contact level
    assert before.heel_off_m == pytest.approx(0.3 * math.sin(math.radians(8.0)), abs=0.002)
    assert before.contact_slope_rad == 0.0 and math.degrees(before.slope_rad) > 7.9
    assert "heel_off_plane:0.042" in before.flags
    assert np.allclose(on.up_in_imu, before.up_in_imu)
    no_heel = anchor_for([0.0, 0.0, 1.0]).at_strike(0.0, 0.05, points)  # not known: as before
    assert math.degrees(no_heel.contact_slope_rad) == pytest.approx(8.0, abs=0.1)


class MovingGravity(FakeGravity):
    """The accelerometer's rotated mean over a window: gravity plus a mean acceleration."""

    def __init__(self, up_world, accel_world) -> None:
        super().__init__(up_world)
        self.accel = WORLD_R_CAMERA.T @ np.asarray(accel_world, float)
        self.windows: list[float] = []

    def up_at(self, t_s: float, window_s: float) -> np.ndarray:
        self.windows.append(window_s)
        return self.up + self.accel


def test_the_strides_velocity_change_is_taken_out_of_the_accelerometers_up():
    """Known answer: a stride that speeds up by 0.35 m/s along the heading and 0.2 m/s
    downwards over 1.0 s (a stair descent's first stride) tilts the plain mean 2.4°; with
    the velocity change given (IMU frame = camera frame here) the up is exact, over the
    open stride's own span; a span under ``min_window_s`` keeps the plain window."""
    accel = np.array([0.35, 0.0, -0.2])  # m/s², world, over 1.0 s
    plain = StrideAnchor(MovingGravity([0, 0, 1.0], accel), FloorConfig(enabled=False),
                         np.eye(4), 0.01, 0.8, 0.2)  # fmt: skip
    assert tilt_deg(plain.at_strike(0.0, 1.0, None).up_in_imu) > 2.0
    gravity = MovingGravity([0, 0, 1.0], accel)
    dv = WORLD_R_CAMERA.T @ accel * 1.0
    anchor = StrideAnchor(gravity, FloorConfig(enabled=False), np.eye(4), 0.01, 0.8, 0.2,
                          velocity_change=lambda t: (t - 1.0, dv))  # fmt: skip
    a = anchor.at_strike(0.0, 1.0, None)
    assert tilt_deg(a.up_in_imu) < 1e-5 and gravity.windows == [1.0]
    short = StrideAnchor(MovingGravity([0, 0, 1.0], accel), FloorConfig(enabled=False),
                         np.eye(4), 0.01, 0.8, 0.2,
                         velocity_change=lambda t: (t - 0.5, dv * 0.5))  # fmt: skip
    assert tilt_deg(short.at_strike(0.0, 1.0, None).up_in_imu) > 2.0


def test_a_heel_still_on_the_ramp_keeps_its_slope_under_a_level_plane_ahead():
    """At a ramp's foot the plane ahead is the level floor: fused (it is level), but the heel,
    3 cm above it, still stands on the ramp: the contact keeps the last stride's slope."""
    anchor = anchor_for([0.0, 0.0, 1.0])
    anchor.last_contact_slope_rad = math.radians(-8.0)  # the last stride was on the ramp
    a = anchor.at_strike(0.0, 0.05, ramp_points(0.0), _in_camera([0.0, 0.0, 0.03]))
    assert a.case == "floor" and a.heel_off_m == pytest.approx(0.03, abs=0.002)
    assert math.degrees(a.contact_slope_rad) == pytest.approx(-8.0)
    assert "heel_off_plane:0.030" in a.flags
    on_floor = anchor.at_strike(1.0, 1.05, ramp_points(0.0), _in_camera([0.0, 0.0, 0.001]))
    assert on_floor.case == "floor" and on_floor.contact_slope_rad == 0.0
    assert anchor.last_contact_slope_rad == 0.0  # remembered for the next strike


def test_a_known_lateral_bias_is_not_a_roll():
    """Known answer: the accelerometer's up read through a 0.1 m/s² lateral bias is 0.58° off
    in roll; with the graph's lateral bias at σ 0.02 (≤ the limit) it is removed exactly, at
    σ 0.2 (a bias the stride could not tell from a roll) it is not."""
    lateral = WORLD_R_CAMERA.T @ np.array([0.0, 1.0, 0.0])  # the stride's y, IMU = camera
    bias = 0.1 * lateral

    class Biased(FakeGravity):
        def up_at(self, t_s, window_s):
            return self.up + bias

    def anchor(sigma):
        return StrideAnchor(Biased(np.array([0.0, 0.0, 1.0])), FloorConfig(enabled=False),
                            np.eye(4), 0.01, 0.8, 0.2, lateral_bias=lambda t: (bias, sigma),
                            lateral_bias_max_sigma=0.05)  # fmt: skip

    assert tilt_deg(anchor(0.2).at_strike(0.0, 1.0, None).up_in_imu) == pytest.approx(
        math.degrees(math.atan(0.1 / 9.81)), abs=1e-3
    )
    assert tilt_deg(anchor(0.02).at_strike(0.0, 1.0, None).up_in_imu) < 1e-5


def _stairs_anchor(up_world, treads: TreadsConfig | None = None, **floor) -> StrideAnchor:
    return StrideAnchor(FakeGravity(np.asarray(up_world, float)), FloorConfig(**floor),
                        np.eye(4), 0.01, 0.8, 0.2, treads=treads or TreadsConfig())  # fmt: skip


def _flight_in_camera(**kw) -> np.ndarray:
    return (flight_points(**kw) - CAMERA_POS) @ WORLD_R_CAMERA


def test_the_treads_of_a_flight_fix_the_roll():
    """Known answer: on a flight no plane passes the floor fit; the IMU's up 0.5° off in roll
    (a lateral accelerometer bias of 0.086 m/s²) is brought within 0.05° of level by the
    treads' common normal, fused like a floor (σ 0.002 rad against the IMU's 0.01); the
    contact is level (a tread)."""
    roll = math.radians(0.5)
    up = [0.0, math.sin(roll), math.cos(roll)]
    a = _stairs_anchor(up).at_strike(0.0, 0.05, _flight_in_camera())
    assert a.case == "treads" and a.fit is not None and not a.fit.ok
    assert tilt_deg(a.up_in_imu) < 0.05
    assert a.sigma_rad == pytest.approx(1.0 / math.sqrt(1 / 0.01**2 + 1 / 0.002**2), rel=1e-6)
    assert a.contact_slope_rad == 0.0
    assert "anchor:treads" in a.flags and any(f.startswith("treads:") for f in a.flags)
    off = _stairs_anchor(up, TreadsConfig(enabled=False)).at_strike(0.0, 0.05, _flight_in_camera())
    assert off.case == "imu" and tilt_deg(off.up_in_imu) == pytest.approx(0.5, abs=1e-4)


def test_treads_that_are_not_level_are_not_fused():
    """A "flight" rolled 3° (beyond the 2° level gate against an exact IMU up) keeps the
    IMU's up; so does the level-ground anchor (assume_level), which never searches treads."""
    a = _stairs_anchor([0.0, 0.0, 1.0]).at_strike(0.0, 0.05, _flight_in_camera(roll_deg=3.0))
    assert a.case == "imu" and tilt_deg(a.up_in_imu) < 1e-5
    assert a.treads is not None and a.treads.ok
    old = _stairs_anchor([0.0, 0.0, 1.0], assume_level=True).at_strike(
        0.0, 0.05, _flight_in_camera()
    )
    assert old.case == "imu" and old.treads is None


def test_a_level_platform_beside_a_ramp_fixes_the_up_and_the_ramp_keeps_the_contact():
    """Known answer: an 8° ramp under the foot and a level platform ahead of it (from 1.3 m,
    0.6 m deep, 1.2 m wide); the IMU's up 0.5° off along the heading (its error on a ramp).
    The ramp is the contact's slope (against the fused up), the platform fixes the up within 0.05°
    (``slope_level``); without the platform the IMU's up is kept (``slope``)."""
    rng = np.random.default_rng(3)
    ramp = ramp_points(8.0, n=6000)
    x, y = rng.uniform(1.3, 1.9, 3000), rng.uniform(-0.6, 0.6, 3000)
    top = np.column_stack([x, y, np.full(3000, math.tan(math.radians(8.0)) * 1.3)])
    top[:, 2] += rng.normal(0.0, 0.001, 3000)
    on_ramp = ramp[(ramp @ WORLD_R_CAMERA.T + CAMERA_POS)[:, 0] < 1.3]
    points = np.vstack([on_ramp, (top - CAMERA_POS) @ WORLD_R_CAMERA])
    err = math.radians(0.5)
    up = [math.sin(err), 0.0, math.cos(err)]
    a = _stairs_anchor(up).at_strike(0.0, 0.05, points)
    assert a.case == "slope_level"
    n = WORLD_R_CAMERA @ a.fit.normal  # the fitted ramp (the platform's edge pulls it a little)
    ramp_deg = math.degrees(math.atan2(-n[0], n[2]))
    assert ramp_deg == pytest.approx(8.0, abs=0.5)
    # its slope against the fused (level) up, not the IMU's 0.5°-off one
    assert math.degrees(a.contact_slope_rad) == pytest.approx(ramp_deg, abs=0.05)
    assert tilt_deg(a.up_in_imu) < 0.05
    assert a.sigma_rad < 0.0025
    plain = _stairs_anchor(up).at_strike(0.0, 0.05, on_ramp)
    assert plain.case == "slope" and tilt_deg(plain.up_in_imu) == pytest.approx(0.5, abs=1e-4)


def test_a_first_strike_takes_the_encoders_up_over_the_accelerometers():
    """A first strike (short IMU history, no σ) with the accelerometer 40° off and no ground
    in view: the encoders' up (here 4° off) is taken; with a long history it is not asked."""
    bad = np.array([math.sin(math.radians(40.0)), 0.0, math.cos(math.radians(40.0))])
    kin_world = np.array([math.sin(math.radians(4.0)), 0.0, math.cos(math.radians(4.0))])
    asked = []

    def kinematic_up(t_s):
        asked.append(t_s)
        return WORLD_R_CAMERA.T @ kin_world

    first = StrideAnchor(FirstStrikeGravity(bad), FloorConfig(), np.eye(4), 0.01, 0.8, 0.2,
                         kinematic_up=kinematic_up)  # fmt: skip
    a = first.at_strike(0.0, 0.05, None)
    assert a.up_source == "kinematics" and "up:kinematics" in a.flags and a.sigma_rad is None
    assert tilt_deg(a.up_in_imu) == pytest.approx(4.0, abs=1e-6)
    # the floor under the heel still decides where it is seen
    heel = _in_camera([0.0, 0.0, 0.0])
    b = first.at_strike(0.0, 0.05, ramp_points(0.0), heel)
    assert b.case == "floor" and tilt_deg(b.up_in_imu) < 0.5
    later = StrideAnchor(FakeGravity(bad), FloorConfig(), np.eye(4), 0.01, 0.8, 0.2,
                         kinematic_up=kinematic_up).at_strike(0.0, 0.05, None)  # fmt: skip
    assert later.up_source == "imu" and len(asked) == 2
    assert tilt_deg(later.up_in_imu) == pytest.approx(40.0, abs=1e-6)


def test_a_first_strike_with_a_sigma_for_the_encoders_up_is_anchored_like_a_later_one():
    """With σ 0.1 rad for the encoders' up (4° off here) the floor is tested against it, not
    taken as level: a level floor is fused (not an assumption); without depth the encoders'
    up keeps that σ."""
    bad = np.array([math.sin(math.radians(40.0)), 0.0, math.cos(math.radians(40.0))])
    kin = WORLD_R_CAMERA.T @ np.array([math.sin(math.radians(4.0)), 0.0,
                                       math.cos(math.radians(4.0))])  # fmt: skip
    first = StrideAnchor(FirstStrikeGravity(bad), FloorConfig(), np.eye(4), 0.01, 0.8, 0.2,
                         kinematic_up=lambda t: kin, kinematic_sigma_rad=0.1)  # fmt: skip
    level = first.at_strike(0.0, 0.05, ramp_points(0.0))
    assert level.case == "floor" and not level.assumed and level.sigma_rad < 0.01
    assert tilt_deg(level.up_in_imu) < 0.2 and level.up_source == "kinematics"
    blind = first.at_strike(0.0, 0.05, None)
    assert blind.case == "imu" and blind.sigma_rad == 0.1
    assert tilt_deg(blind.up_in_imu) == pytest.approx(4.0, abs=1e-6)

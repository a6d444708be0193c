"""An analytic synthetic session: a camera bobbing over a textured floor, with exact truth.

This is the always-available source of the session layer (tests, the foundation demo). It needs
no renderer: depth is the exact ray–plane intersection with the floor ``z = 0``, and the IMU is
the analytic derivative of the trajectory. It is *not* the gait simulator (``graph_slam.sim``);
the motion is a smooth sinusoidal stand-in for walking. With ``scene="box_course"`` the thesis's
three boxes (Table 3.1) stand on the floor ahead (exact ray–box intersection): a flat floor
alone leaves ICP unconstrained along the floor, the boxes constrain it.

Frames: ``world`` x forward, y left, z up; the camera is optical (x right, y down, z forward),
pitched ``pitch_deg`` below the horizontal and oscillating in pitch and height at the stride
frequency. The IMU shares the camera's origin (``camera_T_imu`` is a pure rotation) so its
specific force is exactly ``R_world_imuᵀ (p̈ + g ẑ)``.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import Field

from graph_slam.config import ConfigModel
from graph_slam.session.manifest import Provenance
from graph_slam.session.records import (
    Calibration,
    CameraIntrinsics,
    GaitEvents,
    ImuSeries,
    JointSeries,
    PoseTrajectory,
    RgbdFrame,
    SceneObject,
    SceneTruth,
)
from graph_slam.session.writer import SessionWriter

GRAVITY_M_S2 = 9.81
#: Optical camera looking along world +x with zero pitch (columns: camera axes in world).
WORLD_R_CAMERA_LEVEL = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
#: The IMU's axes: x forward, y left, z up when the camera is level.
CAMERA_R_IMU = WORLD_R_CAMERA_LEVEL.T


class SyntheticConfig(ConfigModel):
    """Parameters of the analytic synthetic session."""

    duration_s: float = Field(4.0, gt=0, le=3600)
    camera_rate_hz: float = Field(30.0, gt=0, le=1000)
    imu_rate_hz: float = Field(200.0, gt=0, le=4000)
    joints_rate_hz: float = Field(500.0, gt=0, le=4000)
    mocap_rate_hz: float = Field(200.0, gt=0, le=4000)
    width_px: int = Field(64, gt=0)
    height_px: int = Field(48, gt=0)
    fov_x_deg: float = Field(65.0, gt=10, lt=170)
    speed_m_s: float = Field(1.0, ge=0, le=3)
    stride_time_s: float = Field(1.1, gt=0.3, le=3)
    camera_height_m: float = Field(0.5, gt=0.1, le=2)
    height_amplitude_m: float = Field(0.03, ge=0, le=0.2)
    pitch_deg: float = Field(40.0, ge=0, le=89)
    pitch_amplitude_deg: float = Field(10.0, ge=0, le=40)
    depth_noise_m: float = Field(0.001, ge=0, description="depth noise σ at 1 m (grows with z²)")
    gyro_noise_rad_s: float = Field(0.002, ge=0, description="per-sample white noise σ")
    accel_noise_m_s2: float = Field(0.02, ge=0, description="per-sample white noise σ")
    depth_unit_m: float = Field(2e-4, gt=0)
    with_color: bool = True
    scene: Literal["floor", "box_course"] = Field(
        "floor", description="floor only, or the thesis's three boxes on the floor ahead"
    )
    seed: int = 0


@dataclass(frozen=True)
class Motion:
    """Closed-form camera motion: position, rotation and their derivatives at times ``t_s``."""

    cfg: SyntheticConfig

    @property
    def omega(self) -> float:
        return 2.0 * np.pi / self.cfg.stride_time_s

    def pitch(self, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pitch below horizontal (rad) and its rate."""
        amp = np.deg2rad(self.cfg.pitch_amplitude_deg)
        theta = np.deg2rad(self.cfg.pitch_deg) + amp * np.sin(self.omega * t_s)
        return theta, amp * self.omega * np.cos(self.omega * t_s)

    def position(self, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World position of the camera (N×3) and its acceleration (N×3)."""
        c, w = self.cfg, self.omega
        phase = w * t_s + 0.5 * np.pi
        pos = np.column_stack(
            [
                c.speed_m_s * t_s,
                np.zeros_like(t_s),
                c.camera_height_m + c.height_amplitude_m * np.sin(phase),
            ]
        )
        acc = np.column_stack(
            [np.zeros_like(t_s), np.zeros_like(t_s), -c.height_amplitude_m * w**2 * np.sin(phase)]
        )
        return pos, acc

    def world_T_camera(self, t_s: np.ndarray) -> np.ndarray:
        theta, _ = self.pitch(t_s)
        pos, _ = self.position(t_s)
        poses = np.tile(np.eye(4), (t_s.size, 1, 1))
        poses[:, :3, :3] = _rot_y(theta) @ WORLD_R_CAMERA_LEVEL
        poses[:, :3, 3] = pos
        return poses

    def imu(self, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Noise-free gyro (rad/s) and specific force (m/s²) in the IMU frame."""
        theta, theta_dot = self.pitch(t_s)
        _, acc = self.position(t_s)
        world_R_imu = _rot_y(theta) @ WORLD_R_CAMERA_LEVEL @ CAMERA_R_IMU
        omega_world = np.column_stack([np.zeros_like(t_s), theta_dot, np.zeros_like(t_s)])
        gyro = np.einsum("nji,nj->ni", world_R_imu, omega_world)
        specific_force = np.einsum(
            "nji,nj->ni", world_R_imu, acc + np.array([0.0, 0.0, GRAVITY_M_S2])
        )
        return gyro, specific_force


def _rot_y(theta: np.ndarray) -> np.ndarray:
    c, s = np.cos(theta), np.sin(theta)
    rot = np.zeros((np.size(theta), 3, 3))
    rot[:, 0, 0] = c
    rot[:, 0, 2] = s
    rot[:, 1, 1] = 1.0
    rot[:, 2, 0] = -s
    rot[:, 2, 2] = c
    return rot


def intrinsics_for(cfg: SyntheticConfig) -> CameraIntrinsics:
    fx = 0.5 * cfg.width_px / np.tan(0.5 * np.deg2rad(cfg.fov_x_deg))
    return CameraIntrinsics(
        width_px=cfg.width_px,
        height_px=cfg.height_px,
        fx_px=float(fx),
        fy_px=float(fx),
        cx_px=(cfg.width_px - 1) / 2.0,
        cy_px=(cfg.height_px - 1) / 2.0,
    )


def _floor_color(xy: np.ndarray, rng_phases: np.ndarray) -> np.ndarray:
    """A smooth, non-periodic-looking floor texture (sum of a few incommensurate waves)."""
    x, y = xy[..., 0], xy[..., 1]
    channels = []
    for c in range(3):
        ph = rng_phases[c]
        value = (
            np.sin(7.3 * x + ph[0]) * np.cos(5.1 * y + ph[1])
            + 0.6 * np.sin(13.7 * x + 11.3 * y + ph[2])
            + 0.4 * np.cos(3.1 * x - 17.9 * y + ph[3])
        )
        channels.append(127.5 + 55.0 * value)
    return np.clip(np.stack(channels, axis=-1), 0, 255).astype(np.uint8)


#: The thesis's boxes (Table 3.1, mm): depth along x, width along y, height along z.
THESIS_BOXES_MM: dict[str, tuple[float, float, float]] = {
    "box1": (203.20, 266.70, 190.50),
    "box2": (266.70, 355.60, 76.20),
    "box3": (336.55, 438.15, 63.50),
}


def box_on_floor(
    name: str, center_xy_m: Sequence[float], size_m: Sequence[float], yaw_rad: float = 0.0
) -> SceneObject:
    """A box standing on the floor ``z = 0`` (``size_m`` = depth x, width y, height z)."""
    c, s = np.cos(yaw_rad), np.sin(yaw_rad)
    world_T_object = np.eye(4)
    world_T_object[:3, :3] = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
    world_T_object[:3, 3] = [center_xy_m[0], center_xy_m[1], 0.5 * size_m[2]]
    return SceneObject(name, world_T_object, np.asarray(size_m, dtype=float))


def scene_truth(cfg: SyntheticConfig) -> SceneTruth:
    """The boxes of the configured scene (none for ``floor``): the course is 1.2 m, 2.4 m and
    3.6 m ahead of the start, on the camera's path."""
    if cfg.scene == "floor":
        return SceneTruth("floor")
    objects = tuple(
        box_on_floor(name, (1.2 * (i + 1), 0.0), np.asarray(size_mm) / 1000.0)
        for i, (name, size_mm) in enumerate(THESIS_BOXES_MM.items())
    )
    return SceneTruth("box_course", objects)


def _ray_box(
    origin: np.ndarray, rays: np.ndarray, box: SceneObject
) -> tuple[np.ndarray, np.ndarray]:
    """Ray parameter of the first hit of each ray with ``box`` (inf if none) and the hit face
    coordinates (two in-face coordinates in the box frame, for the texture)."""
    object_T_world = np.linalg.inv(box.world_T_object)
    o = object_T_world[:3, :3] @ origin + object_T_world[:3, 3]
    d = rays @ object_T_world[:3, :3].T
    half = 0.5 * box.size_m
    with np.errstate(divide="ignore", invalid="ignore"):
        t1 = (-half - o) / d
        t2 = (half - o) / d
    t_near = np.nanmax(np.minimum(t1, t2), axis=-1)
    t_far = np.nanmin(np.maximum(t1, t2), axis=-1)
    hit = (t_far >= t_near) & (t_near > 0)
    t = np.where(hit, t_near, np.inf)
    p = o + d * np.where(hit, t_near, 0.0)[..., None]
    axis = np.argmax(np.abs(p) / half, axis=-1)  # the face the ray hits
    uv = np.stack(
        [np.take_along_axis(p, ((axis + k) % 3)[..., None], -1)[..., 0] for k in (1, 2)], -1
    )
    return t, uv


def render_frame(
    cfg: SyntheticConfig,
    world_T_camera: np.ndarray,
    t_s: float,
    index: int,
    rng: np.random.Generator,
    phases: np.ndarray,
    boxes: Sequence[SceneObject] = (),
) -> RgbdFrame:
    """Exact depth of the floor ``z = 0`` and of ``boxes`` seen from ``world_T_camera``
    (+ seeded noise)."""
    k = intrinsics_for(cfg)
    u, v = np.meshgrid(np.arange(k.width_px), np.arange(k.height_px))
    rays_cam = np.stack(
        [(u - k.cx_px) / k.fx_px, (v - k.cy_px) / k.fy_px, np.ones_like(u, float)], -1
    )
    rays_world = rays_cam @ world_T_camera[:3, :3].T
    origin = world_T_camera[:3, 3]
    with np.errstate(divide="ignore", invalid="ignore"):
        scale = -origin[2] / rays_world[..., 2]  # depth along the optical axis (z_cam = scale)
    hit = np.isfinite(scale) & (scale > 0)
    depth = np.where(hit, scale, np.inf)
    box_uv = np.zeros((*depth.shape, 2))
    box_id = np.full(depth.shape, -1)
    for i, box in enumerate(boxes):
        t_box, uv = _ray_box(origin, rays_world, box)
        closer = t_box < depth
        depth = np.where(closer, t_box, depth)
        box_uv[closer] = uv[closer]
        box_id[closer] = i
    hit = np.isfinite(depth)
    depth = np.where(hit, depth, 0.0)
    if cfg.depth_noise_m > 0:
        depth = np.where(
            hit, depth + rng.normal(0.0, 1.0, depth.shape) * cfg.depth_noise_m * depth**2, 0.0
        )
    color = None
    if cfg.with_color:
        points = origin + rays_world * np.where(hit, depth, 0.0)[..., None]
        color = _floor_color(points[..., :2], phases)
        on_box = box_id >= 0
        if on_box.any():  # box faces: the same texture, finer and shifted per box
            box_color = _floor_color(3.0 * box_uv + box_id[..., None], phases[::-1])
            color[on_box] = box_color[on_box]
        color[~hit] = 0
    return RgbdFrame(t_s=t_s, depth_m=depth.astype(np.float32), color_rgb=color, index=index)


def _times(duration_s: float, rate_hz: float) -> np.ndarray:
    return np.arange(int(np.floor(duration_s * rate_hz)) + 1) / rate_hz


@dataclass(frozen=True)
class SyntheticStreams:
    """Everything of a synthetic session but the frames."""

    imu: ImuSeries
    joints: JointSeries
    events: GaitEvents
    frame_times_s: np.ndarray
    ground_truth: PoseTrajectory
    ground_truth_hf: PoseTrajectory
    calibration: Calibration


def synthetic_streams(cfg: SyntheticConfig) -> SyntheticStreams:
    """Everything but the frames: IMU, joints, events, ground truth, calibration."""
    rng = np.random.default_rng([cfg.seed, 1])
    motion = Motion(cfg)
    t_imu = _times(cfg.duration_s, cfg.imu_rate_hz)
    gyro, accel = motion.imu(t_imu)
    gyro = gyro + rng.normal(0.0, cfg.gyro_noise_rad_s, gyro.shape)
    accel = accel + rng.normal(0.0, cfg.accel_noise_m_s2, accel.shape)
    t_joint = _times(cfg.duration_s, cfg.joints_rate_hz)
    phase = motion.omega * t_joint
    joints = JointSeries(t_joint, 0.35 - 0.3 * np.cos(phase), 0.1 * np.sin(phase))
    strikes = np.arange(0.0, cfg.duration_s, cfg.stride_time_s)
    times = np.sort(np.concatenate([strikes, strikes + 0.6 * cfg.stride_time_s]))
    times = times[times < cfg.duration_s]
    kinds = tuple("foot_strike" if np.any(np.isclose(t, strikes)) else "toe_off" for t in times)
    t_frames = _times(cfg.duration_s, cfg.camera_rate_hz)
    t_mocap = _times(cfg.duration_s, cfg.mocap_rate_hz)
    return SyntheticStreams(
        imu=ImuSeries(t_imu, gyro, accel),
        joints=joints,
        events=GaitEvents(times, kinds, ("synthetic",) * len(kinds)),
        frame_times_s=t_frames,
        ground_truth=PoseTrajectory(t_frames, motion.world_T_camera(t_frames)),
        ground_truth_hf=PoseTrajectory(t_mocap, motion.world_T_camera(t_mocap)),
        calibration=Calibration(camera_T_imu=_pose(CAMERA_R_IMU)),
    )


def _pose(rot: np.ndarray) -> np.ndarray:
    pose = np.eye(4)
    pose[:3, :3] = rot
    return pose


def iter_synthetic_frames(cfg: SyntheticConfig) -> Iterator[RgbdFrame]:
    """Render the frames one at a time (seeded)."""
    rng = np.random.default_rng([cfg.seed, 2])
    phases = np.random.default_rng([cfg.seed, 3]).uniform(0, 2 * np.pi, (3, 4))
    t_frames = _times(cfg.duration_s, cfg.camera_rate_hz)
    poses = Motion(cfg).world_T_camera(t_frames)
    boxes = scene_truth(cfg).objects
    for index, (t, pose) in enumerate(zip(t_frames, poses, strict=True)):
        yield render_frame(cfg, pose, float(t), index, rng, phases, boxes)


def write_synthetic_session(
    out: str | Path, cfg: SyntheticConfig | None = None, *, overwrite: bool = False, progress=None
) -> Path:
    """Write the synthetic session to ``out`` and return its path."""
    cfg = cfg or SyntheticConfig()
    streams = synthetic_streams(cfg)
    writer = SessionWriter(
        out,
        name=f"synthetic-seed{cfg.seed}",
        intrinsics=intrinsics_for(cfg),
        depth_unit_m=cfg.depth_unit_m,
        camera_profile="synthetic",
        camera_rate_hz=cfg.camera_rate_hz,
        imu_profile="synthetic",
        imu_rate_hz=cfg.imu_rate_hz,
        joints_rate_hz=cfg.joints_rate_hz,
        calibration=streams.calibration,
        provenance=Provenance(generator="graph_slam.session.synthetic", seed=cfg.seed),
        overwrite=overwrite,
    )
    with writer:
        n = streams.frame_times_s.size
        for frame in iter_synthetic_frames(cfg):
            writer.add_frame(frame)
            if progress is not None:
                progress(frame.index + 1, n)
        writer.write_imu(streams.imu)
        writer.write_joints(streams.joints)
        writer.write_events(streams.events)
        writer.write_ground_truth(streams.ground_truth)
        writer.write_ground_truth(streams.ground_truth_hf, high_rate=True)
        if cfg.scene != "floor":
            writer.write_scene(scene_truth(cfg))
    return writer.path

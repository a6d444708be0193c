"""The renderer: ray casting depth (Open3D ``RaycastingScene``), colour and motion blur.

One :class:`Renderer` holds the ray-casting scene and the per-pixel ray directions, and is
reused for every frame. The rays' directions have unit z in the camera frame, so Open3D's
``t_hit`` is the depth along the optical axis (what a depth camera reports).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from graph_slam.errors import SimulationError
from graph_slam.session.records import CameraIntrinsics
from graph_slam.sim.config import CameraProfile
from graph_slam.sim.scene import Scene
from graph_slam.sim.sensors import apply_depth_noise

BACKGROUND_RGB = np.array([205.0, 205.0, 200.0], np.float32)  # beyond the floor (walls, far)
MAX_BLUR_SAMPLES = 12


def image_size(
    profile: CameraProfile, fast: bool = False, resolution: str | None = None
) -> tuple[int, int]:
    """The rendered image's (width, height): the profile's, a quarter of it (``fast``), or
    ``resolution`` (``"WxH"``), which must be the profile's size divided by one factor on both
    axes (binning: the field of view stays the profile's)."""
    if resolution is None:
        div = 4 if fast else 1
        return max(profile.width_px // div, 8), max(profile.height_px // div, 8)
    try:
        w, h = (int(part) for part in resolution.lower().split("x"))
    except ValueError:
        raise SimulationError(
            f"resolution {resolution!r}: write it WIDTHxHEIGHT, e.g. 424x240"
        ) from None
    pw, ph = profile.width_px, profile.height_px
    if not (8 <= w <= pw and 8 <= h <= ph and w * ph == h * pw):
        modes = ", ".join(f"{pw // k}x{ph // k}" for k in (1, 2, 4) if pw % k == 0 == ph % k)
        raise SimulationError(
            f"resolution {resolution!r}: camera {profile.name} ({pw}x{ph}) renders its own "
            f"size divided by one factor on both axes, at least 8 px (e.g. {modes})"
        )
    return w, h


def intrinsics_for(
    profile: CameraProfile, fast: bool = False, resolution: str | None = None
) -> CameraIntrinsics:
    """Pinhole intrinsics from the image size (:func:`image_size`) and the profile's field of
    view: ``fx``, ``fy`` scale with the size, the principal point stays at the centre."""
    w, h = image_size(profile, fast, resolution)
    fx = 0.5 * w / math.tan(math.radians(profile.fov_x_deg) / 2)
    fy = 0.5 * h / math.tan(math.radians(profile.fov_y_deg) / 2)
    return CameraIntrinsics(w, h, fx, fy, (w - 1) / 2.0, (h - 1) / 2.0)


class Renderer:
    """Renders depth (metres, float32, 0 = invalid) and colour (uint8) of a scene."""

    def __init__(
        self,
        scene: Scene,
        intrinsics: CameraIntrinsics,
        profile: CameraProfile,
        *,
        noise_scale: float = 1.0,
        motion_blur: bool = True,
    ) -> None:
        import open3d as o3d

        self._o3d = o3d
        self.scene = scene
        self.intrinsics = intrinsics
        self.profile = profile
        self.noise_scale = noise_scale
        self.motion_blur = motion_blur and profile.color and profile.exposure_s > 0
        self._raycaster: Any = scene.raycasting_scene()
        k = intrinsics
        u, v = np.meshgrid(np.arange(k.width_px), np.arange(k.height_px))
        self._dirs_cam = np.stack(
            [(u - k.cx_px) / k.fx_px, (v - k.cy_px) / k.fy_px, np.ones(u.shape)], axis=-1
        ).reshape(-1, 3)
        self._inv_norm = (1.0 / np.linalg.norm(self._dirs_cam, axis=1)).astype(np.float32)
        self._rays = np.empty((self._dirs_cam.shape[0], 6), np.float32)

    def cast(self, world_T_camera: np.ndarray) -> dict[str, np.ndarray]:
        """Exact hits: depth (inf = none), geometry id, normal, cos(incidence), world point."""
        rot = world_T_camera[:3, :3]
        origin = world_T_camera[:3, 3]
        dirs = (self._dirs_cam @ rot.T).astype(np.float32)
        self._rays[:, :3] = origin
        self._rays[:, 3:] = dirs
        ans = self._raycaster.cast_rays(self._o3d.core.Tensor.from_numpy(self._rays))
        t_hit = ans["t_hit"].numpy()
        normals = ans["primitive_normals"].numpy()
        cos_inc = np.abs(np.einsum("ij,ij->i", normals, dirs)) * self._inv_norm
        return {
            "depth": t_hit,
            "geometry_ids": ans["geometry_ids"].numpy(),
            "normals": normals,
            "cos_incidence": cos_inc,
            "dirs": dirs,
            "origin": origin,
        }

    def render(
        self,
        world_T_camera: np.ndarray,
        rng: np.random.Generator,
        gyro_camera_rad_s: np.ndarray | None = None,
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """Depth (noisy, with dropouts) and colour (blurred by the camera's angular rate)."""
        hw = self.intrinsics.shape_hw
        hit = self.cast(world_T_camera)
        depth = apply_depth_noise(
            hit["depth"].reshape(hw),
            hit["cos_incidence"].reshape(hw),
            self.profile.noise,
            rng,
            noise_scale=self.noise_scale,
            min_range_m=self.profile.min_range_m,
            max_range_m=self.profile.max_range_m,
        )
        if not self.profile.color:
            return depth, None
        return depth, self._shade(hit, gyro_camera_rad_s)

    def render_color(
        self, world_T_camera: np.ndarray, gyro_camera_rad_s: np.ndarray | None = None
    ) -> np.ndarray:
        """Colour only (uint8, blurred like :meth:`render`'s): the pass of a colour camera
        that is not the depth camera (its own pose, intrinsics and size; no depth noise, so
        no random numbers are drawn)."""
        return self._shade(self.cast(world_T_camera), gyro_camera_rad_s)

    def _shade(self, hit: dict[str, np.ndarray], gyro_camera_rad_s: np.ndarray | None):
        hw = self.intrinsics.shape_hw
        t = hit["depth"]
        ok = np.isfinite(t)
        rgb = np.empty((t.size, 3), np.float32)
        rgb[:] = BACKGROUND_RGB
        points = hit["origin"] + hit["dirs"][ok] * t[ok, None]
        rgb[ok] = self.scene.colors_at(points, hit["normals"][ok], hit["geometry_ids"][ok])
        rgb = rgb.reshape(*hw, 3)
        if self.motion_blur and gyro_camera_rad_s is not None:
            rgb = self._blur(rgb, gyro_camera_rad_s)
        return np.clip(rgb + 0.5, 0, 255).astype(np.uint8)

    def blur_vector_px(self, gyro_camera_rad_s: np.ndarray) -> np.ndarray:
        """Image motion (du, dv) in pixels during the exposure, from the rotation rate.

        A static point ahead moves by (-fx ω_y, fy ω_x) px/s at the image centre (translation
        and roll are neglected; at 0.5-1 m and 1-2 m/s they add a few pixels at most).
        """
        k = self.intrinsics
        w = np.asarray(gyro_camera_rad_s, float)
        return np.array([-k.fx_px * w[1], k.fy_px * w[0]]) * self.profile.exposure_s

    def _blur(self, rgb: np.ndarray, gyro_camera_rad_s: np.ndarray) -> np.ndarray:
        vec = self.blur_vector_px(gyro_camera_rad_s)
        length = float(np.hypot(*vec))
        if length < 1.0:
            return rgb
        n = min(MAX_BLUR_SAMPLES, math.ceil(length) + 1)
        shifts = np.rint(np.outer(np.linspace(-0.5, 0.5, n), vec)).astype(int)
        pad = int(np.abs(shifts).max())
        padded = np.pad(rgb, ((pad, pad), (pad, pad), (0, 0)), mode="edge")
        h, w = rgb.shape[:2]
        out = np.zeros_like(rgb)
        for du, dv in shifts:
            out += padded[pad + dv : pad + dv + h, pad + du : pad + du + w]
        return out / n

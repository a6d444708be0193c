"""Scenes: YAML descriptions under ``models/scenes/``, their meshes, textures and ground truth.

A scene is a floor (the plane z = 0, world x forward along the walk, y left, z up) and objects:
``box`` (the thesis's obstacles), ``ramp`` (a wedge rising along +x) and ``stairs`` (a flight
of steps rising along +x). ``repeat`` copies the objects along x; ``random_boxes`` adds seeded
random obstacles. Textures (colour of every surface) are ``random`` (multi-scale smoothed
noise, 1.5-30 cm features, no period below 5 m), ``smooth`` (only ≥ 10 cm features) or
``none`` (one flat colour per object: the textureless variant). A fine periodic texture of
5-7 cm is avoided on purpose: it makes colored ICP lock onto the wrong period.

Open3D is imported lazily (only :meth:`Scene.raycasting_scene` needs it).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, Literal

import numpy as np
from pydantic import Field

from graph_slam.config import ConfigModel
from graph_slam.errors import SimulationError
from graph_slam.session.records import SceneObject, SceneTruth
from graph_slam.sim.surface import Surfaces

TEXTURE_TEXEL_M = 0.005
TEXTURE_TILE_PX = 1024  # 5.12 m period


class ObjectSpec(ConfigModel):
    name: str
    kind: Literal["box", "ramp", "stairs"] = "box"
    size_m: tuple[float, float, float] = Field(
        description="box: depth (x) × width (y) × height (z); ramp: length × width × rise; "
        "stairs: run × width × rise of one step"
    )
    center_xy_m: tuple[float, float] = Field(description="box/ramp: centre; stairs: first step")
    yaw_deg: float = 0.0
    steps: int = Field(1, ge=1, le=50, description="stairs only")
    base_m: float = Field(0.0, ge=0, le=5, description="stairs: height of the floor they start on")
    direction: Literal["up", "down"] = Field(
        "up", description="ramp/stairs: rising (up) or falling (down) along +x"
    )
    role: Literal["obstacle", "step_on", "platform", "curb"] = Field(
        "obstacle",
        description="box: what the walker does with it (terrain truth): an obstacle beside "
        "or in the path, a box to step onto, a platform (stair landing, ramp top) or a curb",
    )
    color_rgb: tuple[int, int, int] = (170, 120, 80)


class RepeatSpec(ConfigModel):
    count: int = Field(1, ge=1, le=100)
    spacing_m: float = Field(4.0, gt=0)


class RandomBoxesSpec(ConfigModel):
    count: int = Field(0, ge=0, le=500)
    seed: int = 0
    x_range_m: tuple[float, float] = (1.0, 15.0)
    y_abs_range_m: tuple[float, float] = (0.25, 1.2)
    size_min_m: tuple[float, float, float] = (0.1, 0.1, 0.03)
    size_max_m: tuple[float, float, float] = (0.45, 0.45, 0.25)


class FloorSpec(ConfigModel):
    color_rgb: tuple[int, int, int] = (128, 120, 108)
    x_range_m: tuple[float, float] = (-3.0, 60.0)
    y_range_m: tuple[float, float] = (-4.0, 4.0)


class SceneSpec(ConfigModel):
    """The YAML file of a scene."""

    name: str
    description: str = ""
    texture: Literal["random", "smooth", "none"] = "random"
    texture_seed: int = 0
    floor: FloorSpec = FloorSpec()
    objects: tuple[ObjectSpec, ...] = ()
    repeat: RepeatSpec = RepeatSpec()
    random_boxes: RandomBoxesSpec = RandomBoxesSpec()
    walk: Literal["floor", "terrain"] = Field(
        "floor",
        description="floor: the level-floor walker (objects beside the path); terrain: the "
        "terrain-following walker steps onto, up, down and over what is in its path",
    )


@dataclass
class Solid:
    """One rendered solid: triangle mesh (world frame) and its look."""

    name: str
    vertices: np.ndarray  # (n, 3) float
    triangles: np.ndarray  # (m, 3) int
    color_rgb: np.ndarray  # (3,) float 0..255
    texture_offset_m: np.ndarray = field(default_factory=lambda: np.zeros(2))


def _box_mesh(center: np.ndarray, size: np.ndarray, yaw: float) -> tuple[np.ndarray, np.ndarray]:
    hx, hy, hz = size / 2
    corners = np.array(
        [[sx * hx, sy * hy, sz * hz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]
    )
    c, s = math.cos(yaw), math.sin(yaw)
    rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    verts = corners @ rot.T + center
    # vertex index = 4*ix + 2*iy + iz; outward-facing triangles per face.
    tris = np.array(
        [
            [0, 1, 3], [0, 3, 2],  # -x
            [4, 6, 7], [4, 7, 5],  # +x
            [0, 4, 5], [0, 5, 1],  # -y
            [2, 3, 7], [2, 7, 6],  # +y
            [0, 2, 6], [0, 6, 4],  # -z
            [1, 5, 7], [1, 7, 3],  # +z
        ]
    )  # fmt: skip
    return verts, tris


def _ramp_mesh(spec: ObjectSpec, dx: float) -> tuple[np.ndarray, np.ndarray]:
    length, width, rise = spec.size_m
    x0 = spec.center_xy_m[0] + dx - length / 2
    y0, y1 = spec.center_xy_m[1] - width / 2, spec.center_xy_m[1] + width / 2
    x1 = x0 + length
    v = np.array(
        [[x0, y0, 0], [x1, y0, 0], [x1, y0, rise], [x0, y1, 0], [x1, y1, 0], [x1, y1, rise]],
        dtype=float,
    )
    if spec.direction == "down":  # mirror along x about the ramp's centre
        v[:, 0] = x0 + x1 - v[:, 0]
        tris = np.array(
            [[0, 1, 2], [3, 5, 4], [0, 5, 3], [0, 2, 5], [1, 5, 2], [1, 4, 5], [0, 4, 1], [0, 3, 4]]
        )
        return v, tris
    tris = np.array(
        [[0, 2, 1], [3, 4, 5], [0, 3, 5], [0, 5, 2], [1, 2, 5], [1, 5, 4], [0, 1, 4], [0, 4, 3]]
    )
    return v, tris


class Scene:
    """A loaded scene: solids to render and the ground truth to write."""

    def __init__(self, spec: SceneSpec, source: str = "<spec>") -> None:
        self.spec = spec
        self.source = source
        self.solids: list[Solid] = []
        self.truth_objects: list[SceneObject] = []
        self.surfaces = Surfaces()
        rng = np.random.default_rng([spec.texture_seed, 5])
        f = spec.floor
        (x0, x1), (y0, y1) = f.x_range_m, f.y_range_m
        floor_v = np.array([[x0, y0, 0.0], [x1, y0, 0.0], [x1, y1, 0.0], [x0, y1, 0.0]])
        self._add("floor", floor_v, np.array([[0, 1, 2], [0, 2, 3]]), f.color_rgb, rng)
        for copy in range(spec.repeat.count):
            dx = copy * spec.repeat.spacing_m
            suffix = "" if copy == 0 else f"#{copy + 1}"
            for obj in spec.objects:
                self._add_object(obj, dx, suffix, rng)
        self._add_random_boxes(spec.random_boxes, rng)

    # ---------------------------------------------------------------- building
    def _add(self, name, verts, tris, color, rng) -> None:
        self.solids.append(
            Solid(name, verts, tris, np.asarray(color, float), rng.uniform(0, 5.12, 2))
        )

    def _add_object(self, obj: ObjectSpec, dx: float, suffix: str, rng) -> None:
        name = obj.name + suffix
        size = np.asarray(obj.size_m, float)
        yaw = math.radians(obj.yaw_deg)
        cx, cy = obj.center_xy_m[0] + dx, obj.center_xy_m[1]
        if obj.kind == "box":
            center = np.array([cx, cy, size[2] / 2])
            self._add(name, *_box_mesh(center, size, yaw), obj.color_rgb, rng)
            self.truth_objects.append(SceneObject(name, _pose(center, yaw), size, "box"))
            self.surfaces.add_box(name, center, size, yaw, obj.role)
        elif obj.kind == "ramp":
            self._add(name, *_ramp_mesh(obj, dx), obj.color_rgb, rng)
            center = np.array([cx, cy, size[2] / 2])
            self.truth_objects.append(SceneObject(name, _pose(center, 0.0), size, "ramp"))
            self.surfaces.add_ramp(name, center, size, obj.direction)
        else:  # stairs up: step i is a box of height (i+1)·rise starting at x + i·run;
            # down: (steps-1-i)·rise (steps - 1 boxes; the top is the platform before them)
            run, width, rise = size
            down = obj.direction == "down"
            self.surfaces.add_stairs(name, (cx, cy), size, obj.steps, obj.direction, obj.base_m)
            for i in range(obj.steps - 1 if down else obj.steps):
                h = obj.base_m + (obj.steps - 1 - i if down else i + 1) * rise
                center = np.array([cx + (i + 0.5) * run, cy, h / 2])
                step_size = np.array([run, width, h])
                step_name = f"{name}.step{i + 1}"
                self._add(step_name, *_box_mesh(center, step_size, 0.0), obj.color_rgb, rng)
                self.truth_objects.append(
                    SceneObject(step_name, _pose(center, 0.0), step_size, "step")
                )

    def _add_random_boxes(self, spec: RandomBoxesSpec, rng_tex) -> None:
        rng = np.random.default_rng([spec.seed, 9])
        for i in range(spec.count):
            size = rng.uniform(spec.size_min_m, spec.size_max_m)
            x = rng.uniform(*spec.x_range_m)
            y = rng.choice([-1.0, 1.0]) * rng.uniform(*spec.y_abs_range_m)
            y += np.sign(y) * size[1] / 2
            yaw = rng.uniform(-0.5, 0.5)
            color = rng.integers(60, 220, 3)
            center = np.array([x, y, size[2] / 2])
            name = f"Obstacle{i + 1}"
            self._add(name, *_box_mesh(center, size, yaw), color, rng_tex)
            self.truth_objects.append(SceneObject(name, _pose(center, yaw), size, "box"))
            self.surfaces.add_box(name, center, size, yaw, "obstacle")

    # ---------------------------------------------------------------- products
    @property
    def name(self) -> str:
        return self.spec.name

    def height_at(self, x_m: np.ndarray, y_m: np.ndarray) -> np.ndarray:
        """Height (m, world z) of the top surface at world (x, y): the floor is 0 (vectorised)."""
        return self.surfaces.height_at(x_m, y_m)

    def truth(self) -> SceneTruth:
        return SceneTruth(self.spec.name, tuple(self.truth_objects))

    def raycasting_scene(self) -> Any:
        """An Open3D ``RaycastingScene`` of every solid; geometry id = index in ``solids``."""
        import open3d as o3d

        scene = o3d.t.geometry.RaycastingScene()
        for i, solid in enumerate(self.solids):
            gid = scene.add_triangles(
                o3d.core.Tensor(solid.vertices.astype(np.float32)),
                o3d.core.Tensor(solid.triangles.astype(np.uint32)),
            )
            if gid != i:
                raise SimulationError(f"Open3D gave geometry id {gid} to solid {i}")
        return scene

    @cached_property
    def texture_tile(self) -> np.ndarray:
        """(N, N, 3) float32 multiplicative texture in [0.45, 1.55] (1 = flat), tileable."""
        n = TEXTURE_TILE_PX
        kind = self.spec.texture
        if kind == "none":
            return np.ones((1, 1, 3), np.float32)
        from scipy.ndimage import gaussian_filter

        rng = np.random.default_rng([self.spec.texture_seed, 3])
        scales_m = (0.10, 0.30) if kind == "smooth" else (0.015, 0.05, 0.12, 0.30)
        tile = np.zeros((n, n, 3), np.float64)
        for scale in scales_m:
            sigma = scale / TEXTURE_TEXEL_M / 2.0
            lum = gaussian_filter(rng.standard_normal((n, n)), sigma, mode="wrap")
            chroma = gaussian_filter(rng.standard_normal((n, n, 3)), (sigma, sigma, 0), mode="wrap")
            lum /= lum.std() + 1e-12
            chroma /= chroma.std() + 1e-12
            tile += lum[..., None] + 0.35 * chroma
        tile /= tile.std() + 1e-12
        return np.clip(1.0 + 0.22 * tile, 0.45, 1.55).astype(np.float32)

    def colors_at(
        self, points: np.ndarray, normals: np.ndarray, geometry_ids: np.ndarray
    ) -> np.ndarray:
        """Shaded RGB (float32 0..255) of hit points: object colour × texture × Lambert light."""
        n_solids = len(self.solids)
        looks = self._looks
        gid = np.minimum(geometry_ids, n_solids).astype(np.intp)
        color = looks["base"][gid]
        tile = self.texture_tile
        if tile.shape[0] > 1:
            n = tile.shape[0]  # a power of two: wrap with a bit mask
            axis = np.abs(normals).argmax(axis=1)
            u = np.where(axis == 0, points[:, 1], points[:, 0])
            v = np.where(axis == 2, points[:, 1], points[:, 2])
            off = looks["offset_px"][gid]
            iu = (u * np.float32(1.0 / TEXTURE_TEXEL_M)).astype(np.int32) + off[:, 0]
            iv = (v * np.float32(1.0 / TEXTURE_TEXEL_M)).astype(np.int32) + off[:, 1]
            flat = ((iu & (n - 1)) * n + (iv & (n - 1))).astype(np.intp)
            color *= tile.reshape(-1, 3)[flat]
        shade = np.float32(0.55) + np.float32(0.45) * np.abs(normals @ looks["light"])
        color *= shade[:, None]
        return color

    @cached_property
    def _looks(self) -> dict[str, np.ndarray]:
        base = np.array([s.color_rgb for s in self.solids] + [[0, 0, 0]], np.float32)
        offsets = np.array([s.texture_offset_m for s in self.solids] + [[0, 0]])
        light = np.array([0.35, 0.25, 0.90], np.float32)
        return {
            "base": base,
            "offset_px": (offsets / TEXTURE_TEXEL_M).astype(np.int32),
            "light": light / np.linalg.norm(light),
        }


def _pose(center: np.ndarray, yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    pose = np.eye(4)
    pose[:3, :3] = [[c, -s, 0], [s, c, 0], [0, 0, 1]]
    pose[:3, 3] = center
    return pose


def load_scene(name_or_path: str) -> Scene:
    """Load ``models/scenes/<name>.yaml`` or a YAML file path."""
    from graph_slam.sim.config import load_model_config

    spec, path = load_model_config(SceneSpec, "scenes", "scene", name_or_path)
    return Scene(spec, source=str(path))

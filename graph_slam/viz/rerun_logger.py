"""Loggers for a 3D view of a run: a :class:`NullLogger` (the default) and a rerun logger.

Estimation code never plots: it is handed a logger (``make_logger(None)`` gives the null one)
and calls its methods. :class:`RerunLogger` writes a ``.rrd`` recording file (rerun-sdk 0.41,
imported lazily; no viewer needed; open it with ``rerun FILE.rrd``).

Entity tree (constants below): ``world`` (z up) → ``world/stride`` (``world_T_stride``) →
``world/stride/camera`` (``stride_T_camera``) → ``world/stride/camera/image`` (pinhole, depth,
colour). Clouds, maps, trajectories and obstacles live under ``world/stride``; the live elevation
grid (``log_grid``: heights, σ layer, its boxes) under ``world/stride/terrain``. Two timelines:
``stride`` (stride index, a sequence) and ``time`` (session time, seconds).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Protocol

import numpy as np

from graph_slam.errors import GraphSlamError
from graph_slam.session.records import CameraIntrinsics
from graph_slam.terrain.maps.obstacles import Obstacle

WORLD = "world"
STRIDE = "world/stride"
CAMERA = "world/stride/camera"
IMAGE = "world/stride/camera/image"
DEPTH = "world/stride/camera/image/depth"
COLOR = "world/stride/camera/image/color"
CLOUD = "world/stride/cloud"
MAP = "world/stride/map"
TRAJECTORY = "world/stride/trajectory"
"""Trajectories are logged at ``TRAJECTORY/<name>`` (``truth``, a variant's name)."""
OBSTACLES = "world/stride/obstacles"
TERRAIN_HEIGHT = "world/stride/terrain/height"
"""The live elevation grid's known cells at their heights, coloured by height."""
TERRAIN_SIGMA = "world/stride/terrain/sigma"
"""The same cells coloured by their height σ (the variance layer: 0 → 2 cm, clipped)."""
TERRAIN_OBSTACLES = "world/stride/terrain/obstacles"
"""The live grid's boxes (red: whole, magenta: seen in part)."""
SIGMA_COLOUR_MAX_M = 0.02
VIEW_JPEG_QUALITY = 90
"""The camera images in a recording are for looking at: colour as JPEG (a fifth of the raw
size), depth as whole millimetres (half of float32). The data itself is never changed."""
HEIGHT_COLOUR_SPAN_M = 0.25

TIMELINE_STRIDE = "stride"
TIMELINE_TIME = "time"


def depth_view_mm(depth_m) -> np.ndarray:
    """Depth for the view: uint16 millimetres (0 where unknown or beyond 65.5 m)."""
    depth = np.asarray(depth_m, dtype=np.float64)
    ok = np.isfinite(depth) & (depth > 0) & (depth < 65.535)
    return np.where(ok, np.rint(np.where(ok, depth, 0.0) * 1000.0), 0).astype(np.uint16)


class Logger(Protocol):
    """What estimation and reporting code may call; every method is cheap on the null logger."""

    def set_time(self, stride_index: int, t_s: float) -> None: ...

    def log_stride(self, world_T_stride: np.ndarray) -> None: ...

    def log_camera(
        self,
        stride_T_camera: np.ndarray,
        intrinsics: CameraIntrinsics | None = None,
        depth_m: np.ndarray | None = None,
        color_rgb: np.ndarray | None = None,
    ) -> None: ...

    def log_cloud(
        self, points_m: np.ndarray, colors_rgb: np.ndarray | None = None, entity: str = CLOUD
    ) -> None: ...

    def log_trajectory(self, name: str, positions_m: np.ndarray) -> None: ...

    def log_obstacles(
        self, obstacles: Sequence[Obstacle], floor_T_stride: np.ndarray | None = None
    ) -> None: ...

    def log_grid(self, snapshot) -> None: ...

    def close(self) -> None: ...


class NullLogger:
    """Logs nothing (the default)."""

    def set_time(self, stride_index: int, t_s: float) -> None:
        pass

    def log_stride(self, world_T_stride: np.ndarray) -> None:
        pass

    def log_camera(self, stride_T_camera, intrinsics=None, depth_m=None, color_rgb=None) -> None:
        pass

    def log_cloud(self, points_m, colors_rgb=None, entity: str = CLOUD) -> None:
        pass

    def log_trajectory(self, name: str, positions_m: np.ndarray) -> None:
        pass

    def log_obstacles(self, obstacles, floor_T_stride=None) -> None:
        pass

    def log_grid(self, snapshot) -> None:
        pass

    def close(self) -> None:
        pass


def _colours(values: np.ndarray, lo: float, hi: float, cmap: str) -> np.ndarray:
    """RGB uint8 of ``values`` through a matplotlib colour map over [lo, hi] (clipped)."""
    from matplotlib import colormaps

    t = np.clip((np.asarray(values, float) - lo) / max(hi - lo, 1e-9), 0.0, 1.0)
    return (colormaps[cmap](t)[:, :3] * 255).astype(np.uint8)


def grid_layers(snapshot) -> dict[str, np.ndarray]:
    """What :meth:`RerunLogger.log_grid` draws of a grid snapshot (heights ``height_m`` and
    ``sigma_m`` (nx, ny), ``origin_xy_m``, ``cell_m``): the known cells' centres at their
    heights (N×3), coloured by height (viridis from the 5th percentile over
    ``HEIGHT_COLOUR_SPAN_M``) and by σ (magma, 0 to ``SIGMA_COLOUR_MAX_M``)."""
    h = np.asarray(snapshot.height_m, float)
    sigma = np.asarray(snapshot.sigma_m, float)
    i, j = np.nonzero(np.isfinite(h))
    cell = float(snapshot.cell_m)
    x = snapshot.origin_xy_m[0] + (i + 0.5) * cell
    y = snapshot.origin_xy_m[1] + (j + 0.5) * cell
    z = h[i, j]
    lo = float(np.percentile(z, 5)) if z.size else 0.0
    return {
        "points_m": np.column_stack([x, y, z]).astype(np.float32),
        "height_rgb": _colours(z, lo, lo + HEIGHT_COLOUR_SPAN_M, "viridis"),
        "sigma_rgb": _colours(sigma[i, j], 0.0, SIGMA_COLOUR_MAX_M, "magma"),
    }


def grid_boxes(obstacles, floor_T_stride: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """Centres and sizes (stride frame, N×3 each) of a grid's boxes
    (:class:`~graph_slam.terrain.grid.grid_obstacles.GridObstacle`: axis-aligned, height above the
    floor plane), standing on the floor plane (``floor_T_stride``; None: on z = 0)."""
    centers, sizes = [], []
    for o in obstacles:
        x, y = map(float, o.center_xy_m)
        z_floor = 0.0
        if floor_T_stride is not None:
            stride_T_floor = np.linalg.inv(np.asarray(floor_T_stride, float))
            n, p0 = stride_T_floor[:3, 2], stride_T_floor[:3, 3]  # the floor's normal, a point
            z_floor = float(p0[2] - (n[0] * (x - p0[0]) + n[1] * (y - p0[1])) / n[2])
        centers.append([x, y, z_floor + o.height_m / 2])
        sizes.append([o.depth_m, o.width_m, o.height_m])
    return np.array(centers).reshape(-1, 3), np.array(sizes).reshape(-1, 3)


def _transform(rr, a_T_b: np.ndarray):
    a_T_b = np.asarray(a_T_b, dtype=np.float64)
    if a_T_b.shape != (4, 4) or not np.isfinite(a_T_b).all():
        raise GraphSlamError(
            f"rerun logger: a pose must be a finite 4×4 array, got shape {a_T_b.shape}"
        )
    return rr.Transform3D(translation=a_T_b[:3, 3], mat3x3=a_T_b[:3, :3])


class RerunLogger:
    """Writes everything logged to a ``.rrd`` file (rerun-sdk, imported here, lazily)."""

    def __init__(
        self, path: str | Path, application_id: str = "graph_slam", recording_id: str | None = None
    ):
        import rerun as rr

        self._rr = rr
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._rec = rr.RecordingStream(application_id, recording_id=recording_id)
        self._rec.save(self.path)
        self._rec.log(WORLD, rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)

    def set_time(self, stride_index: int, t_s: float) -> None:
        self._rec.set_time(TIMELINE_STRIDE, sequence=int(stride_index))
        self._rec.set_time(TIMELINE_TIME, duration=float(t_s))

    def log_stride(self, world_T_stride: np.ndarray) -> None:
        self._rec.log(STRIDE, _transform(self._rr, world_T_stride))

    def log_camera(self, stride_T_camera, intrinsics=None, depth_m=None, color_rgb=None) -> None:
        rr = self._rr
        if not np.isfinite(np.asarray(stride_T_camera, dtype=np.float64)).all():
            return  # no pose for this frame (failed registration): nothing to draw
        self._rec.log(CAMERA, _transform(rr, stride_T_camera))
        if intrinsics is not None:
            self._rec.log(
                IMAGE,
                rr.Pinhole(
                    image_from_camera=intrinsics.K,
                    resolution=[intrinsics.width_px, intrinsics.height_px],
                    camera_xyz=rr.ViewCoordinates.RDF,
                    image_plane_distance=0.3,
                ),
            )
        if depth_m is not None:
            self._rec.log(DEPTH, rr.DepthImage(depth_view_mm(depth_m), meter=1000.0))
        if color_rgb is not None:
            image = rr.Image(np.asarray(color_rgb, dtype=np.uint8))
            self._rec.log(COLOR, image.compress(jpeg_quality=VIEW_JPEG_QUALITY))

    def log_cloud(self, points_m, colors_rgb=None, entity: str = CLOUD) -> None:
        self._rec.log(
            entity,
            self._rr.Points3D(
                np.asarray(points_m, dtype=np.float32), colors=colors_rgb, radii=0.003
            ),
        )

    def log_trajectory(self, name: str, positions_m: np.ndarray) -> None:
        p = np.asarray(positions_m, dtype=np.float64)
        p = p[np.isfinite(p).all(axis=1)]
        self._rec.log(
            f"{TRAJECTORY}/{name}", self._rr.LineStrips3D([p.astype(np.float32)], radii=0.002)
        )

    def log_obstacles(self, obstacles, floor_T_stride=None) -> None:
        """Boxes in the floor frame (``ObstacleMap.floor.floor_T_stride()``), drawn in the stride frame."""
        rr = self._rr
        if not obstacles:
            return
        from scipy.spatial.transform import Rotation

        centers = np.array([[*o.center_xy_m, o.height_m / 2] for o in obstacles])
        sizes = np.array([[o.depth_m, o.width_m, o.height_m] for o in obstacles])
        stride_T_floor = np.eye(4)
        if floor_T_stride is not None:
            stride_T_floor = np.linalg.inv(np.asarray(floor_T_stride, dtype=np.float64))
        centers = centers @ stride_T_floor[:3, :3].T + stride_T_floor[:3, 3]
        rotations = [
            Rotation.from_matrix(
                stride_T_floor[:3, :3] @ Rotation.from_euler("z", o.yaw_rad).as_matrix()
            ).as_quat()
            for o in obstacles
        ]
        self._rec.log(
            OBSTACLES,
            rr.Boxes3D(
                centers=centers,
                sizes=sizes,
                quaternions=[rr.Quaternion(xyzw=q) for q in rotations],
                colors=[(230, 40, 40) if o.complete else (200, 0, 200) for o in obstacles],
                labels=[
                    f"{o.depth_m * 1000:.0f}×{o.width_m * 1000:.0f}×{o.height_m * 1000:.0f} mm"
                    + ("" if o.complete else f" (part: {o.skip_reason})")
                    for o in obstacles
                ],
            ),
        )

    def log_grid(self, snapshot) -> None:
        """The live elevation grid at one frame (a
        :class:`~graph_slam.report.terrain_trace.GridSnapshot`: stride frame): the known cells
        coloured by height (``TERRAIN_HEIGHT``), the same coloured by σ (``TERRAIN_SIGMA``),
        the grid's boxes (``TERRAIN_OBSTACLES``; cleared when there are none)."""
        rr = self._rr
        layers = grid_layers(snapshot)
        radius = 0.5 * float(snapshot.cell_m)
        for entity, colours in ((TERRAIN_HEIGHT, "height_rgb"), (TERRAIN_SIGMA, "sigma_rgb")):
            self._rec.log(
                entity, rr.Points3D(layers["points_m"], colors=layers[colours], radii=radius)
            )
        obstacles = tuple(snapshot.obstacles)
        if not obstacles:
            self._rec.log(TERRAIN_OBSTACLES, rr.Clear(recursive=False))
            return
        centers, sizes = grid_boxes(obstacles, snapshot.floor_T_stride)
        self._rec.log(
            TERRAIN_OBSTACLES,
            rr.Boxes3D(
                centers=centers,
                sizes=sizes,
                colors=[(230, 40, 40) if o.complete else (200, 0, 200) for o in obstacles],
                labels=[
                    f"h {o.height_m * 1000:.0f}±{o.height_sigma_m * 1000:.0f} mm, "
                    f"{o.distance_m:.2f} m ahead"
                    for o in obstacles
                ],
            ),
        )

    def close(self) -> None:
        """Flush and finish the file (call once, at the end)."""
        self._rec.flush()
        self._rec.disconnect()


def make_logger(rrd_path: str | Path | None) -> Logger:
    """A :class:`RerunLogger` writing ``rrd_path``, or a :class:`NullLogger` when it is None."""
    return NullLogger() if rrd_path is None else RerunLogger(rrd_path)

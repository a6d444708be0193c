"""Records: the typed, immutable in-memory form of everything a session holds.

Names carry units and frames (``t_s``, ``gyro_rad_s``, ``world_T_camera``). Arrays are stored
read-only and checked on construction: a record that exists is well-formed (shapes, dtypes,
finite values, strictly increasing time; the rules are in :mod:`graph_slam.session.checks`).
Construction errors are :class:`RecordError` with the record, the field and the rule.

Poses are ``a_T_b`` 4×4 homogeneous matrices that map points from frame ``b`` to frame ``a``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from graph_slam.errors import RecordError, SessionError
from graph_slam.session.checks import (
    check_increasing,
    check_pose,
    float_array,
    frozen_array,
    pose_array,
)
from kinematics import imu as kinematics_imu

GaitEventKind = Literal["foot_strike", "toe_off"]
GAIT_EVENT_KINDS: tuple[str, ...] = ("foot_strike", "toe_off")


# --------------------------------------------------------------------------- camera
@dataclass(frozen=True, slots=True)
class CameraIntrinsics:
    """Pinhole intrinsics of the (rectified) depth image, in pixels.

    The depth and colour images are aligned: they share these intrinsics.
    """

    width_px: int
    height_px: int
    fx_px: float
    fy_px: float
    cx_px: float
    cy_px: float

    def __post_init__(self) -> None:
        for name in ("width_px", "height_px"):
            value = getattr(self, name)
            if not isinstance(value, int | np.integer) or value <= 0:
                raise RecordError(
                    f"CameraIntrinsics.{name}: must be a positive integer, got {value!r}"
                )
        for name in ("fx_px", "fy_px"):
            value = getattr(self, name)
            if not np.isfinite(value) or value <= 0:
                raise RecordError(f"CameraIntrinsics.{name}: must be finite and > 0, got {value!r}")
        for name in ("cx_px", "cy_px"):
            if not np.isfinite(getattr(self, name)):
                raise RecordError(f"CameraIntrinsics.{name}: must be finite")

    @property
    def K(self) -> np.ndarray:
        """The 3×3 camera matrix."""
        return np.array(
            [[self.fx_px, 0.0, self.cx_px], [0.0, self.fy_px, self.cy_px], [0.0, 0.0, 1.0]]
        )

    @property
    def shape_hw(self) -> tuple[int, int]:
        """Image shape as (height, width), numpy's order."""
        return (self.height_px, self.width_px)


@dataclass(frozen=True, slots=True, eq=False)
class RgbdFrame:
    """One depth frame (metres, float32 H×W, 0 = invalid) with optional aligned colour."""

    t_s: float
    depth_m: np.ndarray
    color_rgb: np.ndarray | None = None
    index: int = 0

    def __post_init__(self) -> None:
        if not np.isfinite(self.t_s):
            raise RecordError(f"RgbdFrame[{self.index}].t_s: not finite ({self.t_s!r})")
        depth = np.asarray(self.depth_m)
        if depth.ndim != 2:
            raise RecordError(
                f"RgbdFrame[{self.index}].depth_m: must be H×W, got shape {depth.shape}"
            )
        if depth.dtype != np.float32:
            raise RecordError(
                f"RgbdFrame[{self.index}].depth_m: dtype must be float32, got {depth.dtype}"
            )
        if not np.isfinite(depth).all() or (depth < 0).any():
            raise RecordError(
                f"RgbdFrame[{self.index}].depth_m: values must be finite and >= 0 (0 = invalid)"
            )
        object.__setattr__(self, "depth_m", frozen_array(depth))
        if self.color_rgb is not None:
            color = np.asarray(self.color_rgb)
            if color.dtype != np.uint8 or color.shape != (*depth.shape, 3):
                raise RecordError(
                    f"RgbdFrame[{self.index}].color_rgb: must be uint8 {depth.shape[0]}×"
                    f"{depth.shape[1]}×3 like the depth, got {color.dtype} {color.shape}"
                )
            object.__setattr__(self, "color_rgb", frozen_array(color))

    def renumbered(self, index: int) -> RgbdFrame:
        """The same frame with another ``index``, not checked again (its arrays were checked
        and made read-only when it was made)."""
        out = object.__new__(RgbdFrame)
        for name, value in (("t_s", self.t_s), ("depth_m", self.depth_m),
                            ("color_rgb", self.color_rgb), ("index", int(index))):  # fmt: skip
            object.__setattr__(out, name, value)
        return out

    @property
    def valid_fraction(self) -> float:
        """Fraction of pixels with a depth reading."""
        return float(np.count_nonzero(self.depth_m)) / self.depth_m.size


# --------------------------------------------------------------------------- streams
@dataclass(frozen=True, slots=True, eq=False)
class ImuSeries(kinematics_imu.ImuSeries):
    """:class:`kinematics.imu.ImuSeries` (angular rate rad/s, specific force m/s², IMU frame)
    validated on construction: shapes, finite values, strictly increasing time."""

    def __post_init__(self) -> None:
        t = float_array("ImuSeries", "t_s", self.t_s, (None,))
        object.__setattr__(self, "t_s", t)
        object.__setattr__(
            self,
            "gyro_rad_s",
            float_array("ImuSeries", "gyro_rad_s", self.gyro_rad_s, (t.size, 3)),
        )
        object.__setattr__(
            self,
            "accel_m_s2",
            float_array("ImuSeries", "accel_m_s2", self.accel_m_s2, (t.size, 3)),
        )
        check_increasing("ImuSeries", t)


JOINT_NAMES: tuple[str, ...] = ("knee", "ankle")


@dataclass(frozen=True, slots=True, eq=False)
class JointSeries:
    """Prosthesis joint encoders: knee flexion (+) and ankle dorsiflexion (+), radians."""

    t_s: np.ndarray
    knee_rad: np.ndarray
    ankle_rad: np.ndarray

    def __post_init__(self) -> None:
        t = float_array("JointSeries", "t_s", self.t_s, (None,))
        object.__setattr__(self, "t_s", t)
        object.__setattr__(
            self, "knee_rad", float_array("JointSeries", "knee_rad", self.knee_rad, (t.size,))
        )
        object.__setattr__(
            self, "ankle_rad", float_array("JointSeries", "ankle_rad", self.ankle_rad, (t.size,))
        )
        check_increasing("JointSeries", t)

    def __len__(self) -> int:
        return int(self.t_s.size)

    @property
    def q_rad(self) -> np.ndarray:
        """N×2 joint vector in :data:`JOINT_NAMES` order (knee, ankle)."""
        return np.column_stack([self.knee_rad, self.ankle_rad])


@dataclass(frozen=True, slots=True, eq=False)
class GaitEvents:
    """Foot strikes and toe-offs of the prosthetic leg, in time order.

    ``source`` says where each event came from (e.g. ``load_cell``, ``thigh_imu``, ``truth``).
    """

    t_s: np.ndarray
    kind: tuple[str, ...]
    source: tuple[str, ...]

    def __post_init__(self) -> None:
        t = float_array("GaitEvents", "t_s", self.t_s, (None,))
        object.__setattr__(self, "t_s", t)
        kinds = tuple(str(k) for k in self.kind)
        sources = tuple(str(s) for s in self.source)
        if len(kinds) != t.size or len(sources) != t.size:
            raise RecordError(
                f"GaitEvents: t_s, kind and source must have the same length "
                f"({t.size}, {len(kinds)}, {len(sources)})"
            )
        for i, k in enumerate(kinds):
            if k not in GAIT_EVENT_KINDS:
                raise RecordError(f"GaitEvents.kind[{i}]: {k!r} is not one of {GAIT_EVENT_KINDS}")
        object.__setattr__(self, "kind", kinds)
        object.__setattr__(self, "source", sources)
        check_increasing("GaitEvents", t)

    def __len__(self) -> int:
        return int(self.t_s.size)

    @property
    def foot_strikes_s(self) -> np.ndarray:
        """Times of the foot strikes."""
        return self.t_s[np.array([k == "foot_strike" for k in self.kind], dtype=bool)]

    @property
    def toe_offs_s(self) -> np.ndarray:
        """Times of the toe-offs."""
        return self.t_s[np.array([k == "toe_off" for k in self.kind], dtype=bool)]

    def of_source(self, source: str | None, where: str = "events.csv") -> GaitEvents:
        """The events of one ``source`` (None: all of them) — the one rule for the events that
        cut strides; a :class:`SessionError` naming the sources found when there is none."""
        if source is None:
            return self
        use = np.array([s == source for s in self.source], dtype=bool)
        if not use.any():
            raise SessionError(
                f"{where}: no event with source {source!r} "
                f"(found {sorted(set(self.source))}); set event_source"
            )
        keep = np.flatnonzero(use)
        return GaitEvents(
            self.t_s[keep],
            tuple(self.kind[i] for i in keep),
            tuple(self.source[i] for i in keep),
        )

    @classmethod
    def empty(cls) -> GaitEvents:
        return cls(np.zeros(0), (), ())


@dataclass(frozen=True, slots=True, eq=False)
class PoseTrajectory:
    """Timed poses ``parent_T_child`` (e.g. ``world_T_camera``), N×4×4."""

    t_s: np.ndarray
    parent_T_child: np.ndarray
    parent: str = "world"
    child: str = "camera"

    def __post_init__(self) -> None:
        t = float_array("PoseTrajectory", "t_s", self.t_s, (None,))
        poses = float_array(
            "PoseTrajectory", f"{self.parent}_T_{self.child}", self.parent_T_child, (t.size, 4, 4)
        )
        check_pose("PoseTrajectory", f"{self.parent}_T_{self.child}", poses)
        check_increasing("PoseTrajectory", t)
        object.__setattr__(self, "t_s", t)
        object.__setattr__(self, "parent_T_child", poses)

    def __len__(self) -> int:
        return int(self.t_s.size)

    @property
    def positions_m(self) -> np.ndarray:
        """N×3 positions of the child origin in the parent frame."""
        return self.parent_T_child[:, :3, 3]

    @property
    def name(self) -> str:
        return f"{self.parent}_T_{self.child}"


# --------------------------------------------------------------------------- point clouds
@dataclass(frozen=True, eq=False)
class Cloud:
    """Points (N×3, metres, finite) with optional colours (N×3 RGB in [0, 1]) and unit normals
    (N×3), in the frame the holder names. The one point-cloud type: the front end's clouds, the
    fused terrain map (``FusedMap.to_point_cloud``) and PLY files (``adapters.ply``)."""

    points_m: np.ndarray
    colors: np.ndarray | None = None
    normals: np.ndarray | None = None

    def __post_init__(self) -> None:
        points = np.asarray(self.points_m, dtype=np.float64)
        if points.size == 0:
            points = points.reshape(0, 3)
        if points.ndim != 2 or points.shape[1] != 3:
            raise RecordError(f"Cloud.points_m: shape {points.shape} is not N×3")
        if not np.isfinite(points).all():
            raise RecordError("Cloud.points_m: NaN or inf; every coordinate must be finite")
        object.__setattr__(self, "points_m", frozen_array(points))
        for name in ("colors", "normals"):
            value = getattr(self, name)
            if value is not None:
                value = np.asarray(value, dtype=np.float64)
                if value.shape != points.shape:
                    raise RecordError(
                        f"Cloud.{name}: shape {value.shape} does not match points {points.shape}"
                    )
                object.__setattr__(self, name, frozen_array(value))
        if (
            self.colors is not None
            and self.colors.size
            and not (self.colors.min() >= 0.0 and self.colors.max() <= 1.0 + 1e-9)
        ):
            raise RecordError("Cloud.colors: must be RGB in [0, 1] (divide uint8 colours by 255)")

    def __len__(self) -> int:
        return int(self.points_m.shape[0])

    @property
    def colors_rgb(self) -> np.ndarray | None:
        """The colours as N×3 uint8 (0-255), as PLY files and images hold them."""
        if self.colors is None:
            return None
        return np.clip(np.rint(self.colors * 255.0), 0, 255).astype(np.uint8)

    def transformed(self, a_T_cloud: np.ndarray) -> Cloud:
        """The same cloud expressed in frame ``a``."""
        rot, trans = a_T_cloud[:3, :3], a_T_cloud[:3, 3]
        normals = None if self.normals is None else self.normals @ rot.T
        return Cloud(self.points_m @ rot.T + trans, self.colors, normals)

    def to_open3d(self):
        """An ``open3d.geometry.PointCloud`` copy (points, colours, normals)."""
        import open3d as o3d

        pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.array(self.points_m)))
        if self.colors is not None:
            pcd.colors = o3d.utility.Vector3dVector(np.array(self.colors))
        if self.normals is not None:
            pcd.normals = o3d.utility.Vector3dVector(np.array(self.normals))
        return pcd


# --------------------------------------------------------------------------- calibration, scene
@dataclass(frozen=True, slots=True, eq=False)
class Calibration:
    """Extrinsics and time offsets.

    Time offsets: a sensor sample stamped ``t_sensor`` happened at camera time
    ``t_sensor + offset_s``. The reader does not apply them; the pipelines do.
    """

    thigh_T_camera: np.ndarray = field(default_factory=lambda: np.eye(4))
    camera_T_imu: np.ndarray = field(default_factory=lambda: np.eye(4))
    imu_time_offset_s: float = 0.0
    joints_time_offset_s: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(
            self,
            "thigh_T_camera",
            pose_array("Calibration", "thigh_T_camera", self.thigh_T_camera),
        )
        object.__setattr__(
            self, "camera_T_imu", pose_array("Calibration", "camera_T_imu", self.camera_T_imu)
        )
        for name in ("imu_time_offset_s", "joints_time_offset_s"):
            value = getattr(self, name)
            if not np.isfinite(value) or abs(value) > 1.0:
                raise RecordError(
                    f"Calibration.{name}: must be finite and within ±1 s, got {value!r}"
                )


@dataclass(frozen=True, slots=True, eq=False)
class SceneObject:
    """A box in the scene: ``world_T_object`` at its centre; size along the object's axes.

    ``size_m`` is (depth along x, width along y, height along z), the thesis's Table 3.1 order.
    """

    name: str
    world_T_object: np.ndarray
    size_m: np.ndarray
    kind: str = "box"

    def __post_init__(self) -> None:
        object.__setattr__(
            self,
            "world_T_object",
            pose_array(f"SceneObject[{self.name}]", "world_T_object", self.world_T_object),
        )
        size = float_array(f"SceneObject[{self.name}]", "size_m", self.size_m, (3,))
        if (size <= 0).any():
            raise RecordError(f"SceneObject[{self.name}].size_m: every dimension must be > 0")
        object.__setattr__(self, "size_m", size)


@dataclass(frozen=True, slots=True)
class SceneTruth:
    """Ground truth of the scene: its name and objects (boxes) in the world frame."""

    name: str
    objects: tuple[SceneObject, ...] = ()

    def object(self, name: str) -> SceneObject:
        for obj in self.objects:
            if obj.name == name:
                return obj
        raise RecordError(f"SceneTruth[{self.name}]: no object named {name!r}")

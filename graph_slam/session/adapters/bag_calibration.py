"""Calibration recorded in bags: camera models from ``CameraInfo``, extrinsics from the RealSense
SDK's ``tf`` topics or the ROS wrapper's ``/tf_static``, the SDK's IMU intrinsics.

Conventions: ``a_T_b`` maps points from frame b to frame a. The camera frame is the depth
camera's optical frame (x right, y down, z forward).

- **SDK recordings** (librealsense ``ros_writer``): each stream ``/device_D/sensor_S/<Stream>_<i>``
  has one ``…/tf/<g>`` message (``geometry_msgs/Transform``), the extrinsics *from* the reference
  stream of extrinsics group ``g`` *to* that stream: ``p_stream = R p_ref + t``, i.e.
  ``stream_T_ref``. Two streams of the same group give ``a_T_b = a_T_ref · (b_T_ref)⁻¹``.
- **ROS wrapper**: ``/tf_static`` (``tf2_msgs/TFMessage``) holds ``TransformStamped`` with
  ``header.frame_id`` = parent and ``child_frame_id`` = child; the transform is ``parent_T_child``.
  A stream's frame is the ``header.frame_id`` of its messages (e.g.
  ``camera_depth_optical_frame``, ``camera_imu_optical_frame``); any two frames of the tree are
  related through their common ancestors.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from graph_slam.errors import ConversionError
from graph_slam.session.adapters.align import CameraModel
from graph_slam.session.adapters.bag_sdk import STRING, imu_intrinsic_values, string_transform
from graph_slam.session.records import CameraIntrinsics

TRANSFORM = "geometry_msgs/msg/Transform"
IMU_INTRINSIC = "realsense_msgs/msg/ImuIntrinsic"
#: ``/device_D/sensor_S/<Stream>_<i>/tf/<group>`` (ROS 1: ``tf/0``; ROS 2: ``tf/ref_1``)
SDK_TF = re.compile(r"^(/device_\d+/sensor_\d+/[A-Za-z]+_\d+)/tf/((?:ref_)?\d+)$")
#: ``/device_D/sensor_S/<Stream>_<i>`` of a data topic
SDK_STREAM = re.compile(r"^(/device_\d+/sensor_\d+/[A-Za-z]+_\d+)/")
UNIT_QUATERNION_TOLERANCE = 1e-3


def transform_matrix(msg: Any, where: str) -> np.ndarray:
    """A ``geometry_msgs/Transform`` as a 4×4 matrix (its quaternion must be unit within 1e-3)."""
    q = np.array([msg.rotation.x, msg.rotation.y, msg.rotation.z, msg.rotation.w], dtype=float)
    t = np.array([msg.translation.x, msg.translation.y, msg.translation.z], dtype=float)
    norm = float(np.linalg.norm(q))
    if not (np.all(np.isfinite(q)) and np.all(np.isfinite(t))):
        raise ConversionError(f"{where}: transform is not finite")
    if abs(norm - 1.0) > UNIT_QUATERNION_TOLERANCE:
        raise ConversionError(
            f"{where}: rotation quaternion has norm {norm:.6g}; it must be 1 within "
            f"{UNIT_QUATERNION_TOLERANCE}"
        )
    pose = np.eye(4)
    pose[:3, :3] = Rotation.from_quat(q / norm).as_matrix()
    pose[:3, 3] = t
    return pose


def invert(pose: np.ndarray) -> np.ndarray:
    out = np.eye(4)
    out[:3, :3] = pose[:3, :3].T
    out[:3, 3] = -pose[:3, :3].T @ pose[:3, 3]
    return out


def camera_model_from_info(msg: Any, is_ros2: bool, topic: str) -> CameraModel:
    """``sensor_msgs/CameraInfo`` → :class:`CameraModel` (K, D and the distortion model)."""
    k = np.asarray(msg.k if is_ros2 else msg.K, dtype=np.float64).reshape(3, 3)
    d = np.asarray(msg.d if is_ros2 else msg.D, dtype=np.float64)
    model = CameraModel(
        int(msg.width),
        int(msg.height),
        float(k[0, 0]),
        float(k[1, 1]),
        float(k[0, 2]),
        float(k[1, 2]),
        str(msg.distortion_model),
        tuple(float(c) for c in d),
    )
    try:
        CameraIntrinsics(*_pinhole(model))
        model.kind  # noqa: B018 — refuses an unsupported distortion model here, naming the topic
    except Exception as err:  # RecordError or ConversionError, both re-raised with the topic
        raise ConversionError(f"topic {topic}: camera_info is not usable ({err})") from None
    return model


def _pinhole(model: CameraModel) -> tuple[int, int, float, float, float, float]:
    return (model.width_px, model.height_px, model.fx_px, model.fy_px, model.cx_px, model.cy_px)


def intrinsics_of(model: CameraModel) -> CameraIntrinsics:
    return CameraIntrinsics(*_pinhole(model))


def sdk_stream(topic: str | None) -> str | None:
    """``/device_0/sensor_1/Color_0/image/data`` → ``/device_0/sensor_1/Color_0``."""
    match = SDK_STREAM.match(topic or "")
    return match.group(1) if match else None


def sdk_tf_topics(topics: Mapping[str, str | None]) -> tuple[str, ...]:
    return tuple(
        sorted(t for t, m in topics.items() if SDK_TF.match(t) and m in (TRANSFORM, STRING))
    )


def sdk_imu_intrinsic_topics(
    topics: Mapping[str, str | None], streams: dict[str, str | None]
) -> dict[str, str]:
    """role → ``<stream>/imu_intrinsic`` for the accel / gyro streams that have one."""
    out = {}
    for role, topic in streams.items():
        stream = sdk_stream(topic)
        if stream and f"{stream}/imu_intrinsic" in topics:
            out[role] = f"{stream}/imu_intrinsic"
    return out


@dataclass(frozen=True)
class Extrinsic:
    """``a_T_b`` and where it came from (for the conversion report)."""

    pose: np.ndarray
    source: str


class SdkExtrinsics:
    """The SDK's per-stream ``tf`` messages: ``stream → (group, stream_T_ref)``."""

    def __init__(self, messages: Mapping[str, Any]) -> None:
        self.by_stream: dict[str, tuple[str, np.ndarray, str]] = {}
        for topic, msg in messages.items():
            match = SDK_TF.match(topic)
            if match:
                where = f"topic {topic}"
                if msg.__msgtype__ == STRING:
                    pose = string_transform(msg.data, where)  # the SDK's text (ROS 2)
                else:
                    pose = transform_matrix(msg, where)
                self.by_stream[match.group(1)] = (match.group(2), pose, topic)

    def lookup(self, a: str | None, b: str | None) -> Extrinsic | None:
        """``a_T_b`` between two SDK streams (``/device_0/sensor_0/Depth_0``), or None."""
        if a is None or b is None or a not in self.by_stream or b not in self.by_stream:
            return None
        group_a, a_T_ref, topic_a = self.by_stream[a]
        group_b, b_T_ref, topic_b = self.by_stream[b]
        if group_a != group_b:
            return None
        return Extrinsic(a_T_ref @ invert(b_T_ref), f"bag ({topic_a}, {topic_b})")


class TfTree:
    """Static transforms (``/tf_static``): ``a_T_b`` between any two connected frames."""

    def __init__(self, messages: list[Any], topic: str) -> None:
        self.topic = topic
        self.parent: dict[str, tuple[str, np.ndarray]] = {}
        for msg in messages:
            for ts in msg.transforms:
                parent = str(ts.header.frame_id).lstrip("/")
                child = str(ts.child_frame_id).lstrip("/")
                where = f"topic {topic}, transform {parent} → {child}"
                self.parent[child] = (parent, transform_matrix(ts.transform, where))

    def _ancestors(self, frame: str) -> list[str]:
        """``frame`` and its ancestors up to the root."""
        chain = [frame]
        while chain[-1] in self.parent:
            parent = self.parent[chain[-1]][0]
            if parent in chain:
                raise ConversionError(f"topic {self.topic}: the transforms form a loop at {parent}")
            chain.append(parent)
        return chain

    def _ancestor_T(self, frame: str, ancestor: str) -> np.ndarray:
        """``ancestor_T_frame``, walking up the tree from ``frame``."""
        pose = np.eye(4)
        while frame != ancestor:
            parent, parent_T_frame = self.parent[frame]
            pose = parent_T_frame @ pose
            frame = parent
        return pose

    def lookup(self, a: str | None, b: str | None) -> Extrinsic | None:
        """``a_T_b`` through the nearest common ancestor, or None when not connected."""
        if not a or not b:
            return None
        a, b = a.lstrip("/"), b.lstrip("/")
        ancestors_a = self._ancestors(a)
        for f in self._ancestors(b):
            if f in ancestors_a:
                pose = invert(self._ancestor_T(a, f)) @ self._ancestor_T(b, f)
                return Extrinsic(pose, f"bag ({self.topic}: {a} → {b})")
        return None


def imu_intrinsic_entry(msg: Any, topic: str) -> dict[str, Any]:
    """The SDK's ``realsense_msgs/ImuIntrinsic``: 3×4 [scale and misalignment | bias], variances."""
    data, noise, bias = imu_intrinsic_values(msg)
    return {
        "source": f"bag ({topic})",
        "scale_misalignment": data[:, :3].tolist(),
        "bias": data[:, 3].tolist(),
        "noise_variances": noise.tolist(),
        "bias_variances": bias.tolist(),
        "applied": False,
    }


# --------------------------------------------------------------------------- resolution
@dataclass
class BagCalibration:
    """What the bag says about the cameras and the IMU, with the source of each value."""

    color_model: CameraModel | None = None
    color_T_depth: Extrinsic | None = None
    camera_T_imu: Extrinsic | None = None
    #: rotation of accel samples into the IMU (gyro) frame when the two frames differ
    gyro_R_accel: np.ndarray | None = None
    #: name → {"source": ..., "value": ...} for the conversion report
    entries: dict[str, dict[str, Any]] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)


def extrinsic_entry(ext: Extrinsic) -> dict[str, Any]:
    """An extrinsic for the conversion report: its source and the 4×4 value."""
    return {"source": ext.source, "value": np.round(ext.pose, 12).tolist()}


def resolve_bag_calibration(
    choice: Any,
    frame_ids: Mapping[str, str],
    extra: Mapping[str, Any],
    tf_static: list[Any],
    color_info: Any,
    is_ros2: bool,
    color_T_depth_config: Any = None,
) -> BagCalibration:
    """Colour camera, depth→colour and camera→IMU extrinsics from the SDK's ``tf`` topics (SDK
    layout: a depth topic under ``/device_N/sensor_M/``) or ``/tf_static`` and the messages'
    frame ids (ROS wrapper); ``color_T_depth_config`` (4×4) overrides the bag's."""
    out = BagCalibration()
    sdk = sdk_stream(choice.depth) is not None
    if sdk:
        source: SdkExtrinsics | TfTree | None = SdkExtrinsics(extra)

        def key(role: str) -> str | None:
            return sdk_stream(getattr(choice, role))
    else:
        source = TfTree(tf_static, choice.tf_static) if choice.tf_static else None

        def key(role: str) -> str | None:
            return frame_ids.get(role) if getattr(choice, role) else None

    def lookup(a: str, b: str) -> Extrinsic | None:
        return None if source is None else source.lookup(key(a), key(b))

    if choice.color is not None and color_info is not None:
        out.color_model = camera_model_from_info(color_info, is_ros2, str(choice.color_info))
    if color_T_depth_config is not None:
        out.color_T_depth = Extrinsic(np.asarray(color_T_depth_config, float), "config")
    elif choice.color is not None:
        out.color_T_depth = lookup("color", "depth")
    if out.color_T_depth is not None:
        out.entries["color_T_depth"] = extrinsic_entry(out.color_T_depth)
    imu_ext: dict[str, Extrinsic] = {}
    for role in ("imu", "gyro", "accel"):
        if getattr(choice, role) is not None and (ext := lookup("depth", role)) is not None:
            imu_ext[role] = ext
            out.entries[f"camera_T_{role}"] = extrinsic_entry(ext)
    out.camera_T_imu = imu_ext.get("imu") or imu_ext.get("gyro") or imu_ext.get("accel")
    if "gyro" in imu_ext and "accel" in imu_ext:
        rot = imu_ext["gyro"].pose[:3, :3].T @ imu_ext["accel"].pose[:3, :3]
        if not np.allclose(rot, np.eye(3), atol=1e-9):
            out.gyro_R_accel = rot
            out.notes.append(
                "accel and gyro frames differ in rotation: accel samples rotated into the gyro "
                "frame (the IMU frame of the session); their lever arm is ignored"
            )
    return out


def imu_intrinsics_entries(extra: Mapping[str, Any], choice: Any) -> dict[str, dict[str, Any]]:
    """The SDK's recorded ``imu_intrinsic`` of the accel and gyro streams, for the report."""
    out = {}
    for role in ("accel", "gyro"):
        stream = sdk_stream(getattr(choice, role, None))
        topic = f"{stream}/imu_intrinsic" if stream else None
        if topic in extra:
            out[f"{role}_intrinsics"] = imu_intrinsic_entry(extra[topic], topic)
    return out

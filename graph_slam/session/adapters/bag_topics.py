"""Which topics of a bag a conversion reads: the presets (RealSense SDK recordings, the
RealSense ROS wrapper) and the explicit ``bag.*_topic`` overrides. See docs/adapters.md."""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from graph_slam.errors import ConversionError, MissingStreamError
from graph_slam.session.adapters.config import BagConfig

IMAGE = "sensor_msgs/msg/Image"
COMPRESSED = "sensor_msgs/msg/CompressedImage"
TF_MESSAGE = "tf2_msgs/msg/TFMessage"
CAMERA_INFO = "sensor_msgs/msg/CameraInfo"
IMU = "sensor_msgs/msg/Imu"
JOINT_STATE = "sensor_msgs/msg/JointState"
FLOAT32 = "std_msgs/msg/Float32"
STRING = "std_msgs/msg/String"
EVENT_TYPES = frozenset(
    f"std_msgs/msg/{t}"
    for t in ("String", "Int8", "Int16", "Int32", "Int64", "UInt8", "UInt16", "UInt32", "UInt64")
)
ROLES = (
    "depth",
    "color",
    "camera_info",
    "imu",
    "accel",
    "gyro",
    "joint_states",
    "gait_events",
    "depth_units",
    "color_info",
    "tf_static",
)
ROLE_TYPES: dict[str, frozenset[str]] = {
    "depth": frozenset({IMAGE, COMPRESSED}),
    "color": frozenset({IMAGE, COMPRESSED}),
    "camera_info": frozenset({CAMERA_INFO}),
    "imu": frozenset({IMU}),
    "accel": frozenset({IMU}),
    "gyro": frozenset({IMU}),
    "joint_states": frozenset({JOINT_STATE}),
    "gait_events": EVENT_TYPES,
    "depth_units": frozenset({FLOAT32, STRING}),
    "color_info": frozenset({CAMERA_INFO}),
    "tf_static": frozenset({TF_MESSAGE}),
}


def listing(topics: Mapping[str, str | None]) -> str:
    return ", ".join(f"{t} ({m})" for t, m in sorted(topics.items())) or "none"


def _unique(pattern: str, topics: Mapping[str, str | None], role: str) -> str | None:
    regex = re.compile(pattern)
    found = sorted(t for t in topics if regex.match(t))
    if len(found) > 1:
        raise ConversionError(
            f"several topics could be the {role} stream: {found}; choose one with "
            f"bag.{role}_topic in the conversion config"
        )
    return found[0] if found else None


# --------------------------------------------------------------------------- presets
class RealsenseSdkPreset:
    """Recordings of the RealSense SDK / realsense-viewer (``/device_N/sensor_M/...``).

    ROS 1 ``.bag`` (librealsense before 2.5x): depth ``…/Depth_0/image/data`` (raw), camera
    info ``…/Depth_0/info/camera_info``. ROS 2 ``.db3`` (librealsense 2.5x): depth
    ``…/Depth_0/image/data/compressedDepth``, colour ``…/Color_0/image/data/compressed``, camera
    info ``…/image/camera_info`` with every frame, the frame's own time in ``…/metadata``.
    Accel and gyro are separate ``Accel_K`` and ``Gyro_K`` streams whose sensor index varies by
    device, so they are found by pattern on the same device. Colour is recorded unregistered
    to depth; it is registered to depth with the extrinsics of the streams' ``tf`` topics.
    Depth units: the ``Depth Units`` option topic (Float32, or a text in ROS 2).
    """

    name = "realsense-sdk"
    depth_pattern = re.compile(
        r"^/device_(\d+)/sensor_(\d+)/Depth_\d+/image/data(/compressedDepth)?$"
    )

    def depth_candidates(self, topics: Mapping[str, str | None]) -> list[str]:
        return sorted(t for t in topics if self.depth_pattern.match(t))

    @staticmethod
    def camera_info(image: str, topics: Mapping[str, str | None]) -> str | None:
        """The CameraInfo of an SDK image stream: ``…/image/camera_info`` (ROS 2, with every
        frame), else ``…/info/camera_info`` (ROS 1, once)."""
        stream = image.split("/image/data", 1)[0]
        for topic in (f"{stream}/image/camera_info", f"{stream}/info/camera_info"):
            if topics.get(topic) == CAMERA_INFO:
                return topic
        return None

    def related(self, depth: str, topics: Mapping[str, str | None]) -> dict[str, Any]:
        match = self.depth_pattern.match(depth)
        if match is None:
            return {"color_registered": False}
        device, sensor = match.group(1), match.group(2)
        base = rf"^/device_{device}/sensor_\d+"
        color = _unique(rf"{base}/Color_\d+/image/data(/compressed)?$", topics, "color")
        return {
            "camera_info": self.camera_info(depth, topics),
            "color": color,
            "color_info": self.camera_info(color, topics) if color else None,
            "accel": _unique(rf"{base}/Accel_\d+/imu/data$", topics, "accel"),
            "gyro": _unique(rf"{base}/Gyro_\d+/imu/data$", topics, "gyro"),
            "depth_units": _unique(
                rf"^/device_{device}/sensor_{sensor}/option/Depth[ _]Units/value$",
                topics,
                "depth_units",
            ),
            "color_registered": False,
        }


class RealsenseRosPreset:
    """The RealSense ROS wrapper (``realsense2_camera``), ROS 1 or 2, any namespace.

    Depth: ``<ns>/aligned_depth_to_color/image_raw`` (registered to colour, so colour is used
    as is), else ``<ns>/depth/image_rect_raw`` (colour registered to it with ``/tf_static``);
    either may be its ``/compressedDepth`` topic when the raw one was not recorded;
    ``camera_info`` next to it; colour ``<ns>/color/image_raw`` (else its ``/compressed``) and
    ``<ns>/color/camera_info``; IMU ``<ns>/imu`` (united) or ``<ns>/accel/sample`` +
    ``<ns>/gyro/sample``; joints ``/joint_states`` and ``/tf_static`` when present.
    """

    name = "realsense-ros"
    aligned = re.compile(r"^(.*)/aligned_depth_to_color/image_raw(/compressedDepth)?$")
    raw = re.compile(r"^(.*)/depth/image_rect_raw(/compressedDepth)?$")

    def depth_candidates(self, topics: Mapping[str, str | None]) -> list[str]:
        for pattern in (self.aligned, self.raw):
            found = sorted(t for t in topics if pattern.match(t))
            plain = [t for t in found if not t.endswith("/compressedDepth")]
            # a raw topic wins over its compressed twin; a compressed one alone is used
            found = plain + [
                t
                for t in found
                if t.endswith("/compressedDepth")
                and t.removesuffix("/compressedDepth") not in plain
            ]
            if found:
                return found
        return []

    def related(self, depth: str, topics: Mapping[str, str | None]) -> dict[str, Any]:
        match = self.aligned.match(depth) or self.raw.match(depth)
        if match is None:
            return {"color_registered": False}
        ns = match.group(1)

        def present(topic: str) -> str | None:
            return topic if topic in topics else None

        image = depth.removesuffix("/compressedDepth")
        return {
            "camera_info": present(image.rsplit("/", 1)[0] + "/camera_info"),
            "color": present(f"{ns}/color/image_raw")
            or present(f"{ns}/color/image_raw/compressed"),
            "color_info": present(f"{ns}/color/camera_info"),
            "tf_static": present("/tf_static"),
            "imu": present(f"{ns}/imu"),
            "accel": present(f"{ns}/accel/sample"),
            "gyro": present(f"{ns}/gyro/sample"),
            "joint_states": present("/joint_states"),
            "color_registered": self.aligned.match(depth) is not None,
        }


PRESETS: dict[str, RealsenseSdkPreset | RealsenseRosPreset] = {
    p.name: p for p in (RealsenseSdkPreset(), RealsenseRosPreset())
}


@dataclass(frozen=True)
class TopicChoice:
    """The topics a conversion reads, and how they were chosen."""

    preset: str
    depth: str
    camera_info: str | None = None
    color: str | None = None
    imu: str | None = None
    accel: str | None = None
    gyro: str | None = None
    joint_states: str | None = None
    gait_events: str | None = None
    depth_units: str | None = None
    color_info: str | None = None
    tf_static: str | None = None
    color_registered: bool = False
    notes: tuple[str, ...] = ()

    def topic_of(self) -> dict[str, str]:
        """role → topic for every role in use."""
        return {r: getattr(self, r) for r in ROLES if getattr(self, r) is not None}


def resolve_topics(topics: Mapping[str, str | None], cfg: BagConfig) -> TopicChoice:
    """Choose the topics: explicit ones from ``cfg``, the rest from the preset.

    ``topics`` maps each topic in the bag to its message type. A missing or mistyped topic is a
    :class:`MissingStreamError` / :class:`ConversionError` listing the topics found.
    """
    explicit = _explicit_topics(topics, cfg)
    preset = _preset(topics, cfg)
    depth = cfg.depth_topic or _depth_topic(topics, cfg, preset)
    related = preset.related(depth, topics) if preset is not None else {}
    choice: dict[str, Any] = {"depth": depth}
    for role in (
        "color",
        "camera_info",
        "joint_states",
        "gait_events",
        "depth_units",
        "color_info",
        "tf_static",
    ):
        choice[role] = explicit.get(role) or related.get(role)
    notes = _imu_topics(choice, cfg, related)
    _check_types(choice, topics)
    registered = (
        cfg.color_registered_to_depth
        if cfg.color_registered_to_depth is not None
        else bool(related.get("color_registered", False))
    )
    return TopicChoice(
        preset=preset.name if preset is not None else "none",
        color_registered=registered,
        notes=tuple(notes),
        **choice,
    )


def _explicit_topics(topics: Mapping[str, str | None], cfg: BagConfig) -> dict[str, str | None]:
    """role → topic given in ``cfg``; each must be in the bag."""
    explicit = {
        "depth": cfg.depth_topic,
        "color": cfg.color_topic,
        "camera_info": cfg.camera_info_topic,
        "imu": cfg.imu_topic,
        "accel": cfg.accel_topic,
        "gyro": cfg.gyro_topic,
        "joint_states": cfg.joint_states_topic,
        "gait_events": cfg.gait_events_topic,
        "color_info": cfg.color_info_topic,
    }
    for role, topic in explicit.items():
        if topic is not None and topic not in topics:
            raise MissingStreamError(
                f"bag.{role}_topic = {topic!r} is not in the bag; topics found: {listing(topics)}"
            )
    return explicit


def _preset(
    topics: Mapping[str, str | None], cfg: BagConfig
) -> RealsenseSdkPreset | RealsenseRosPreset | None:
    """``bag.preset``; ``auto``: the preset that knows ``bag.depth_topic``, else the first
    that recognises a depth topic in the bag."""
    if cfg.preset == "none":
        return None
    if cfg.preset != "auto":
        return PRESETS[cfg.preset]
    preset = next((p for p in PRESETS.values() if p.depth_candidates(topics)), None)
    if cfg.depth_topic is not None:
        preset = next(
            (p for p in PRESETS.values() if cfg.depth_topic in p.depth_candidates(topics)),
            preset,
        )
    return preset


def _depth_topic(
    topics: Mapping[str, str | None],
    cfg: BagConfig,
    preset: RealsenseSdkPreset | RealsenseRosPreset | None,
) -> str:
    """The preset's one depth topic; none or several is an error saying what to set."""
    candidates = preset.depth_candidates(topics) if preset is not None else []
    if len(candidates) > 1:
        raise ConversionError(
            f"several depth topics: {candidates}; choose one with bag.depth_topic"
        )
    if not candidates:
        how = f"preset {preset.name!r}" if preset else f"preset {cfg.preset!r}"
        raise MissingStreamError(
            f"no depth topic found ({how}); set bag.depth_topic or another bag.preset. "
            f"Topics found: {listing(topics)}"
        )
    return candidates[0]


def _imu_topics(choice: dict[str, Any], cfg: BagConfig, related: Mapping[str, Any]) -> list[str]:
    """Set ``choice``'s imu, or accel and gyro: the config's, else the preset's; notes."""
    if cfg.imu_topic:
        choice["imu"] = cfg.imu_topic
    elif cfg.accel_topic:
        choice["accel"], choice["gyro"] = cfg.accel_topic, cfg.gyro_topic
    elif related.get("imu"):
        choice["imu"] = related["imu"]
    elif related.get("accel") and related.get("gyro"):
        choice["accel"], choice["gyro"] = related["accel"], related["gyro"]
    elif related.get("accel") or related.get("gyro"):
        found = related.get("accel") or related.get("gyro")
        return [f"only one of accel/gyro found ({found}): no IMU stream"]
    return []


def _check_types(choice: Mapping[str, str | None], topics: Mapping[str, str | None]) -> None:
    """Every chosen topic must carry a message type its role can read."""
    for role, topic in choice.items():
        if topic is None:
            continue
        msgtype = topics.get(topic)
        if msgtype not in ROLE_TYPES[role]:
            raise ConversionError(
                f"topic {topic} ({role}) has message type {msgtype}; expected one of "
                f"{sorted(ROLE_TYPES[role])}"
            )

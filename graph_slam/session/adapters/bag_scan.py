"""The first pass over a bag: stamps, formats and frame ids of the images, a few depth frames
for the unit check, the small streams (IMU, joints, events) and the calibration messages
(camera_info, the SDK's tf and imu_intrinsic topics, /tf_static)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from graph_slam.errors import ConversionError, MissingStreamError
from graph_slam.session.adapters.bag_images import (
    COLOR_ENCODINGS,
    DEPTH_ENCODINGS,
    check_format,
    compressed_array,
    image_array,
)
from graph_slam.session.adapters.bag_reader import Bag
from graph_slam.session.adapters.bag_sdk import metadata_stamp_ns
from graph_slam.session.adapters.bag_topics import COMPRESSED, STRING, TopicChoice
from graph_slam.session.adapters.config import BagConfig

DEPTH_CHECK_FRAMES = 5


def stamp_ns(msg: Any, bag_ns: int, use_header: bool) -> int:
    if not use_header:
        return bag_ns
    stamp = msg.header.stamp
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


@dataclass
class Collected:
    """What the first pass over the bag gathered."""

    depth_ns: list[int] = field(default_factory=list)
    depth_format: tuple[str, int, int] | None = None
    depth_samples: list[np.ndarray] = field(default_factory=list)
    color_ns: list[int] = field(default_factory=list)
    color_format: tuple[str, int, int] | None = None
    camera_info: Any = None
    camera_info_count: int = 0
    color_info: Any = None
    depth_units: float | None = None
    imu: list[tuple[int, float, float, float, float, float, float]] = field(default_factory=list)
    accel: list[tuple[int, float, float, float]] = field(default_factory=list)
    gyro: list[tuple[int, float, float, float]] = field(default_factory=list)
    joints: list[tuple[int, float, float]] = field(default_factory=list)
    events: list[tuple[int, str]] = field(default_factory=list)
    #: role → header.frame_id of the role's first message (depth, color, imu, accel, gyro)
    frame_ids: dict[str, str] = field(default_factory=dict)
    tf_static: list[Any] = field(default_factory=list)
    #: first message of each extra topic (the SDK's tf and imu_intrinsic topics)
    extra: dict[str, Any] = field(default_factory=dict)
    #: role → the frames' own stamps (ns) from the SDK's per-frame metadata, in message order
    metadata_ns: dict[str, list[int]] = field(default_factory=dict)
    #: (msgtype, message) of the SDK's device info topic
    device: list[tuple[str | None, Any]] = field(default_factory=list)


def _vec(v: Any) -> tuple[float, float, float]:
    return float(v.x), float(v.y), float(v.z)


def _image_format(
    out: Collected, role: str, msg: Any, msgtype: str | None, topic: str, i: int
) -> tuple[str, int, int]:
    """Encoding and size of an image message, the same in every message of the topic; a
    compressed image is decoded for its size only when it is the topic's first message."""
    previous = out.depth_format if role == "depth" else out.color_format
    if msgtype != COMPRESSED:
        encodings = DEPTH_ENCODINGS if role == "depth" else COLOR_ENCODINGS
        return check_format(previous, msg, topic, i, encodings)
    if previous is None:
        array = compressed_array(msg, topic, i, role)
        return (str(msg.format), int(array.shape[1]), int(array.shape[0]))
    return previous


def _image(out: Collected, role, topic, msgtype, i, msg, ns, sample_at) -> None:
    fmt = _image_format(out, role, msg, msgtype, topic, i)
    out.frame_ids.setdefault(role, str(msg.header.frame_id))
    if role == "depth":
        out.depth_format = fmt
        out.depth_ns.append(ns)
        if i in sample_at:
            out.depth_samples.append(
                compressed_array(msg, topic, i, role)
                if msgtype == COMPRESSED
                else image_array(msg, topic, i)
            )
    else:
        out.color_format = fmt
        out.color_ns.append(ns)


def _imu(out: Collected, role: str, topic: str, i: int, msg: Any, ns: int) -> None:
    out.frame_ids.setdefault(role, str(msg.header.frame_id))
    if role == "accel":
        out.accel.append((ns, *_vec(msg.linear_acceleration)))
    elif role == "gyro":
        out.gyro.append((ns, *_vec(msg.angular_velocity)))
    else:
        if i == 0:  # covariance[0] = -1 marks a field the sensor does not provide
            for name, cov in (
                ("angular_velocity", msg.angular_velocity_covariance),
                ("linear_acceleration", msg.linear_acceleration_covariance),
            ):
                if float(cov[0]) == -1.0:
                    raise ConversionError(
                        f"topic {topic}: {name}_covariance[0] = -1 (the message has no "
                        f"{name}); give separate bag.accel_topic and bag.gyro_topic"
                    )
        out.imu.append((ns, *_vec(msg.angular_velocity), *_vec(msg.linear_acceleration)))


def _joints(out: Collected, cfg: BagConfig, topic: str, i: int, msg: Any, ns: int) -> None:
    k_names = (cfg.knee_joint, cfg.ankle_joint)
    names = [str(n) for n in msg.name]
    missing = [n for n in k_names if n not in names]
    if missing:
        raise MissingStreamError(
            f"topic {topic}, message {i}: joint(s) {missing} not in its names {names}; "
            "set bag.knee_joint / bag.ankle_joint"
        )
    position = np.asarray(msg.position, dtype=np.float64)
    if position.size != len(names):
        raise ConversionError(
            f"topic {topic}, message {i}: {len(names)} names but {position.size} positions"
        )
    out.joints.append(
        (
            ns,
            float(position[names.index(k_names[0])]),
            float(position[names.index(k_names[1])]),
        )
    )


def first_pass(
    bag: Bag,
    choice: TopicChoice,
    cfg: BagConfig,
    counts: Mapping[str, int],
    msgtypes: Mapping[str, str | None],
    extra_topics: tuple[str, ...] = (),
    metadata_topics: Mapping[str, str] | None = None,
    device_topic: str | None = None,
) -> Collected:
    """Read every chosen topic once (see the module docstring); ``metadata_topics``: the
    SDK's per-frame metadata topic → the role of its frames; ``device_topic``: its device
    info."""
    metadata_topics = dict(metadata_topics or {})
    role_of: dict[str, list[str]] = {}
    for role, topic in choice.topic_of().items():
        role_of.setdefault(topic, []).append(role)
    n_depth = counts.get(choice.depth, 0)
    sample_at = set(np.unique(np.linspace(0, max(n_depth - 1, 0), DEPTH_CHECK_FRAMES).astype(int)))
    out = Collected()
    use_header = cfg.stamps == "header"
    index: dict[str, int] = {}
    wanted = set(role_of) | set(extra_topics) | set(metadata_topics)
    if device_topic is not None:
        wanted.add(device_topic)
    for topic, bag_ns, msg in bag.messages(wanted):
        i = index[topic] = index.get(topic, -1) + 1
        if topic in extra_topics:
            out.extra.setdefault(topic, msg)
        if topic in metadata_topics:
            stamp = metadata_stamp_ns(msg.data, f"topic {topic}, message {i}")
            out.metadata_ns.setdefault(metadata_topics[topic], []).append(stamp)
        if topic == device_topic:
            out.device.append((msgtypes.get(topic), msg))
        for role in role_of.get(topic, ()):
            if role in ("depth", "color"):
                ns = stamp_ns(msg, bag_ns, use_header)
                _image(out, role, topic, msgtypes.get(topic), i, msg, ns, sample_at)
            elif role == "camera_info":
                out.camera_info_count += 1
                if out.camera_info is None:
                    out.camera_info = msg
            elif role == "color_info":
                out.color_info = out.color_info or msg
            elif role == "tf_static":
                out.tf_static.append(msg)
            elif role == "depth_units":
                if out.depth_units is None:  # a float32: keep its 7 significant digits
                    out.depth_units = float(f"{float(msg.data):.7g}")
            elif role in ("imu", "accel", "gyro"):
                _imu(out, role, topic, i, msg, stamp_ns(msg, bag_ns, use_header))
            elif role == "joint_states":
                _joints(out, cfg, topic, i, msg, stamp_ns(msg, bag_ns, use_header))
            elif role == "gait_events":
                out.events.append((bag_ns, str(msg.data).strip()))
    return out


def sdk_metadata_topics(choice: TopicChoice, msgtypes: Mapping[str, str | None]) -> dict[str, str]:
    """The SDK's per-frame metadata topic of each image / IMU stream chosen (ROS 2 SDK
    recordings: ``<stream>/image/metadata``, ``<stream>/imu/metadata``) → the stream's role."""
    out = {}
    for role in ("depth", "color", "accel", "gyro"):
        topic = getattr(choice, role)
        if topic is None or "/device_" not in topic:
            continue
        stream = topic.split("/image/data", 1)[0].split("/imu/data", 1)[0]
        for meta in (f"{stream}/image/metadata", f"{stream}/imu/metadata"):
            if msgtypes.get(meta) == STRING:
                out[meta] = role
    return out


def use_metadata_stamps(got: Collected, choice: TopicChoice, path: Any) -> list[str]:
    """Replace the stamps of every stream that has the SDK's per-frame metadata with the
    frames' own time (the k-th metadata message belongs to the k-th frame); notes."""
    notes = []
    for role, stamps in got.metadata_ns.items():
        values = {"depth": got.depth_ns, "color": got.color_ns}.get(role)
        samples = {"accel": got.accel, "gyro": got.gyro}.get(role)
        n = len(values) if values is not None else len(samples or [])
        topic = getattr(choice, role)
        if len(stamps) != n:
            raise ConversionError(
                f"{path}: {topic} has {n} message(s) but its metadata topic {len(stamps)}; "
                "the frames' own times cannot be paired (set bag.stamps: bag to use the "
                "recording's time)"
            )
        if values is not None:
            values[:] = stamps
        elif samples is not None:
            samples[:] = [(ns, *rest) for ns, (_, *rest) in zip(stamps, samples, strict=True)]
        notes.append(f"{role}: stamps from the SDK's frame metadata (the device's clock)")
    return notes

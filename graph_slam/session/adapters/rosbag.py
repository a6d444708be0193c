"""ROS 1 (``.bag``) and ROS 2 (``.db3``, ``.mcap``, or their folder with ``metadata.yaml``) bags,
read with the ``rosbags`` library (no ROS installation; the optional extra ``bags``).

Topics are chosen by a preset (RealSense SDK recordings, the RealSense ROS wrapper) or given
explicitly in ``bag:`` of the conversion config; see docs/adapters.md. The bag is read twice:
once for stamps, metadata and the small streams (IMU, joints, events), then frame by frame
while the session is written. Stamps are ``header.stamp`` (or the bag's receive time with
``bag.stamps: bag``); messages are put in stamp order and exact duplicate stamps are dropped,
all counted in the report.
"""

from __future__ import annotations

import re
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from graph_slam.errors import BagError, ConversionError, MissingStreamError, RecordError
from graph_slam.session.adapters.base import ConversionReport, Recording, StreamReport
from graph_slam.session.adapters.config import BagConfig, ConvertConfig, IntrinsicsConfig
from graph_slam.session.adapters.timing import (
    associate,
    check_depth_units,
    merge_accel_gyro,
    order_stamps,
)
from graph_slam.session.records import (
    CameraIntrinsics,
    GaitEvents,
    ImuSeries,
    JointSeries,
    RgbdFrame,
)

IMAGE = "sensor_msgs/msg/Image"
CAMERA_INFO = "sensor_msgs/msg/CameraInfo"
IMU = "sensor_msgs/msg/Imu"
JOINT_STATE = "sensor_msgs/msg/JointState"
FLOAT32 = "std_msgs/msg/Float32"
EVENT_TYPES = frozenset(
    f"std_msgs/msg/{t}"
    for t in ("String", "Int8", "Int16", "Int32", "Int64", "UInt8", "UInt16", "UInt32", "UInt64")
)
DEPTH_ENCODINGS = ("16UC1", "mono16", "32FC1")
COLOR_ENCODINGS = ("rgb8", "bgr8")
#: REP 118: 16UC1 depth images are in millimetres.
DEFAULT_DEPTH_UNIT_M = 1e-3
#: Float depth is written to the session with this unit unless output.depth_unit_m says otherwise
#: (0.1 mm quantisation, 13.1 m range).
FLOAT_DEPTH_SESSION_UNIT_M = 2e-4
DEPTH_CHECK_FRAMES = 5
INSTALL_HINT = "reading bags needs the optional package 'rosbags': pip install graph_slam[bags]"

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
)
ROLE_TYPES: dict[str, frozenset[str]] = {
    "depth": frozenset({IMAGE}),
    "color": frozenset({IMAGE}),
    "camera_info": frozenset({CAMERA_INFO}),
    "imu": frozenset({IMU}),
    "accel": frozenset({IMU}),
    "gyro": frozenset({IMU}),
    "joint_states": frozenset({JOINT_STATE}),
    "gait_events": EVENT_TYPES,
    "depth_units": frozenset({FLOAT32}),
}


def _listing(topics: Mapping[str, str | None]) -> str:
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

    Depth ``/device_0/sensor_0/Depth_0/image/data``; accel and gyro are separate ``Accel_K`` and
    ``Gyro_K`` streams whose sensor index varies by device, so they are found by pattern on the
    same device. Colour is recorded unregistered to depth (its own intrinsics), so it is not used
    unless ``bag.color_registered_to_depth: true``. Depth units: the ``Depth Units`` option topic.
    """

    name = "realsense-sdk"
    depth_pattern = re.compile(r"^/device_(\d+)/sensor_(\d+)/Depth_\d+/image/data$")

    def depth_candidates(self, topics: Mapping[str, str | None]) -> list[str]:
        return sorted(t for t in topics if self.depth_pattern.match(t))

    def related(self, depth: str, topics: Mapping[str, str | None]) -> dict[str, Any]:
        match = self.depth_pattern.match(depth)
        if match is None:
            return {"color_registered": False}
        device, sensor = match.group(1), match.group(2)
        base = rf"^/device_{device}/sensor_\d+"
        info = depth.replace("/image/data", "/info/camera_info")
        return {
            "camera_info": info if info in topics else None,
            "color": _unique(rf"{base}/Color_\d+/image/data$", topics, "color"),
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

    Depth: ``<ns>/aligned_depth_to_color/image_raw`` (registered to colour, so colour is used),
    else ``<ns>/depth/image_rect_raw``; ``camera_info`` next to it; colour
    ``<ns>/color/image_raw``; IMU ``<ns>/imu`` (united) or ``<ns>/accel/sample`` +
    ``<ns>/gyro/sample``; joints ``/joint_states`` when present.
    """

    name = "realsense-ros"
    aligned = re.compile(r"^(.*)/aligned_depth_to_color/image_raw$")
    raw = re.compile(r"^(.*)/depth/image_rect_raw$")

    def depth_candidates(self, topics: Mapping[str, str | None]) -> list[str]:
        aligned = sorted(t for t in topics if self.aligned.match(t))
        return aligned or sorted(t for t in topics if self.raw.match(t))

    def related(self, depth: str, topics: Mapping[str, str | None]) -> dict[str, Any]:
        match = self.aligned.match(depth) or self.raw.match(depth)
        if match is None:
            return {"color_registered": False}
        ns = match.group(1)

        def present(topic: str) -> str | None:
            return topic if topic in topics else None

        return {
            "camera_info": present(depth.rsplit("/", 1)[0] + "/camera_info"),
            "color": present(f"{ns}/color/image_raw"),
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
    explicit = {
        "depth": cfg.depth_topic,
        "color": cfg.color_topic,
        "camera_info": cfg.camera_info_topic,
        "imu": cfg.imu_topic,
        "accel": cfg.accel_topic,
        "gyro": cfg.gyro_topic,
        "joint_states": cfg.joint_states_topic,
        "gait_events": cfg.gait_events_topic,
    }
    for role, topic in explicit.items():
        if topic is not None and topic not in topics:
            raise MissingStreamError(
                f"bag.{role}_topic = {topic!r} is not in the bag; topics found: {_listing(topics)}"
            )
    if cfg.preset == "auto":
        preset = next(
            (p for p in PRESETS.values() if p.depth_candidates(topics)), None
        )  # first preset that recognises a depth topic
        if cfg.depth_topic is not None:
            preset = next(
                (p for p in PRESETS.values() if cfg.depth_topic in p.depth_candidates(topics)),
                preset,
            )
    elif cfg.preset == "none":
        preset = None
    else:
        preset = PRESETS[cfg.preset]
    depth = cfg.depth_topic
    if depth is None:
        candidates = preset.depth_candidates(topics) if preset is not None else []
        if len(candidates) > 1:
            raise ConversionError(
                f"several depth topics: {candidates}; choose one with bag.depth_topic"
            )
        if not candidates:
            how = f"preset {preset.name!r}" if preset else f"preset {cfg.preset!r}"
            raise MissingStreamError(
                f"no depth topic found ({how}); set bag.depth_topic or another bag.preset. "
                f"Topics found: {_listing(topics)}"
            )
        depth = candidates[0]
    related = preset.related(depth, topics) if preset is not None else {}
    choice: dict[str, Any] = {"depth": depth}
    for role in ("color", "camera_info", "joint_states", "gait_events", "depth_units"):
        choice[role] = explicit.get(role) or related.get(role)
    notes: list[str] = []
    if cfg.imu_topic:
        choice["imu"] = cfg.imu_topic
    elif cfg.accel_topic:
        choice["accel"], choice["gyro"] = cfg.accel_topic, cfg.gyro_topic
    elif related.get("imu"):
        choice["imu"] = related["imu"]
    elif related.get("accel") and related.get("gyro"):
        choice["accel"], choice["gyro"] = related["accel"], related["gyro"]
    elif related.get("accel") or related.get("gyro"):
        notes.append(
            f"only one of accel/gyro found ({related.get('accel') or related.get('gyro')}): "
            "no IMU stream"
        )
    for role, topic in choice.items():
        if topic is None:
            continue
        msgtype = topics.get(topic)
        if msgtype not in ROLE_TYPES[role]:
            raise ConversionError(
                f"topic {topic} ({role}) has message type {msgtype}; expected one of "
                f"{sorted(ROLE_TYPES[role])}"
            )
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


# --------------------------------------------------------------------------- rosbags access
def _rosbags():
    """Import rosbags lazily; a clear error when the optional extra is missing."""
    try:
        from rosbags.highlevel import AnyReader
    except ImportError:
        raise ConversionError(INSTALL_HINT) from None
    return AnyReader


def _rosbag_errors() -> tuple[type[BaseException], ...]:
    import sqlite3
    import struct

    from rosbags.highlevel import AnyReaderError
    from rosbags.rosbag1 import ReaderError as Reader1Error
    from rosbags.rosbag2 import ReaderError as Reader2Error
    from rosbags.serde import SerdeError

    return (
        AnyReaderError,
        Reader1Error,
        Reader2Error,
        SerdeError,
        sqlite3.DatabaseError,
        struct.error,
        EOFError,
        # rosbags on random or damaged bytes (found by tests/test_faults_fuzz.py): a header
        # that is not UTF-8, a record length past the end, a field it does not know
        UnicodeDecodeError,
        ValueError,
        IndexError,
        KeyError,
        OverflowError,
        OSError,  # a seek to a negative offset (a damaged index position)
        AssertionError,  # rosbags' own consistency checks on a damaged chunk
    )


def _hint(message: str, path: Path) -> str:
    text = message.lower()
    if "not indexed" in text:
        return (
            "the bag has no index (an interrupted recording?); rebuild it with "
            f"`rosbag reindex {path.name}` (ROS 1 tools), then convert again"
        )
    if "malformed" in text or "not a database" in text:
        return (
            "the SQLite file is damaged or truncated; recover what is left with sqlite3's "
            "`.recover`, or re-record"
        )
    if "magic" in text and path.suffix != ".bag":
        return (
            "the MCAP file is truncated or damaged; `mcap recover IN.mcap -o OUT.mcap` "
            "rewrites what is readable"
        )
    if "magic" in text:
        return "this is not a ROS 1 bag (wrong file magic)"
    return (
        "the bag looks truncated or damaged; `rosbag reindex FILE` rebuilds the index of a "
        "truncated ROS 1 bag, `ros2 bag reindex DIR` the metadata of a ROS 2 bag"
    )


def _bag_error(path: Path, err: BaseException) -> BagError:
    message = " ".join(str(a) for a in err.args) or type(err).__name__
    if isinstance(err, UnicodeDecodeError):
        message = f"byte {err.start} is not text where the bag's header should be"
    message = message if len(message) <= 200 else message[:200] + "..."
    return BagError(f"{path}: cannot read the bag ({message}); {_hint(message, path)}")


def bag_path(path: Path) -> Path:
    """The path to give rosbags (a .bag file, a .db3/.mcap file, or a ROS 2 folder)."""
    path = Path(path)
    if path.is_file():
        if path.suffix in (".bag", ".db3", ".mcap"):
            return path
        if path.name.endswith(".bag.active"):
            raise BagError(
                f"{path}: an unfinished recording (.bag.active has no index); rebuild it with "
                f"`rosbag reindex {path.name}` (ROS 1 tools) and rename it to .bag"
            )
        raise ConversionError(f"{path}: not a bag (expected .bag, .db3, .mcap or a ROS 2 folder)")
    if path.is_dir():
        if (path / "metadata.yaml").is_file():
            return path
        storage = sorted(p.name for p in path.iterdir() if p.suffix in (".db3", ".mcap"))
        if storage:
            raise BagError(
                f"{path}: ROS 2 bag folder without metadata.yaml; `ros2 bag reindex {path}` "
                f"rebuilds it, or convert the storage file itself ({storage[0]})"
            )
        raise ConversionError(f"{path}: not a ROS 2 bag folder (no metadata.yaml)")
    raise MissingStreamError(f"{path}: no such file or folder")


class _Bag:
    """An open rosbags reader whose failures become :class:`BagError` with a hint."""

    def __init__(self, path: Path) -> None:
        self.path = path
        any_reader = _rosbags()
        self._errors = _rosbag_errors()
        try:
            self.reader = any_reader([bag_path(path)])
            self.reader.open()
        except FileNotFoundError as err:
            raise _bag_error(path, err) from None
        except self._errors as err:
            raise _bag_error(path, err) from None
        self.is_ros2 = bool(self.reader.is2)

    def close(self) -> None:
        if self.reader.stack is not None:
            self.reader.close()

    def __enter__(self) -> _Bag:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def topics(self) -> dict[str, str | None]:
        return {name: info.msgtype for name, info in self.reader.topics.items()}

    def counts(self) -> dict[str, int]:
        return {name: int(info.msgcount) for name, info in self.reader.topics.items()}

    def messages(self, topics: set[str]) -> Iterator[tuple[str, int, Any]]:
        """(topic, bag time ns, decoded message) in bag time order."""
        conns = [c for c in self.reader.connections if c.topic in topics]
        gen = self.reader.messages(connections=conns)
        while True:
            try:
                conn, bag_ns, raw = next(gen)
                msg = self.reader.deserialize(raw, conn.msgtype)
            except StopIteration:
                return
            except self._errors as err:
                raise _bag_error(self.path, err) from None
            yield conn.topic, int(bag_ns), msg


# --------------------------------------------------------------------------- decoding
def image_array(msg: Any, topic: str, index: int) -> np.ndarray:
    """A sensor_msgs/Image as an array: uint16 / float32 H×W, or uint8 H×W×3 in RGB order."""
    enc = str(msg.encoding)
    base: np.dtype
    if enc in ("16UC1", "mono16"):
        base, channels = np.dtype(np.uint16), 1
    elif enc == "32FC1":
        base, channels = np.dtype(np.float32), 1
    elif enc in COLOR_ENCODINGS:
        base, channels = np.dtype(np.uint8), 3
    else:
        raise ConversionError(
            f"topic {topic}, message {index}: image encoding {enc!r} is not supported "
            f"(depth: {', '.join(DEPTH_ENCODINGS)}; colour: {', '.join(COLOR_ENCODINGS)})"
        )
    dtype = base.newbyteorder(">" if msg.is_bigendian else "<")
    height, width, step = int(msg.height), int(msg.width), int(msg.step)
    row = width * channels * dtype.itemsize
    data = np.asarray(msg.data, dtype=np.uint8).ravel()
    if height <= 0 or width <= 0 or step < row or data.size < step * (height - 1) + row:
        raise ConversionError(
            f"topic {topic}, message {index}: {width}×{height} {enc} image with step {step} "
            f"needs {step * (height - 1) + row} bytes, the message holds {data.size}"
        )
    if data.size < step * height:
        data = np.concatenate([data, np.zeros(step * height - data.size, dtype=np.uint8)])
    rows = data[: step * height].reshape(height, step)[:, :row]
    array = np.ascontiguousarray(rows).view(dtype).reshape(height, width, channels)
    array = array.astype(base, copy=False)
    if channels == 1:
        return array[:, :, 0]
    return np.ascontiguousarray(array[:, :, ::-1]) if enc == "bgr8" else array


def _stamp_ns(msg: Any, bag_ns: int, use_header: bool) -> int:
    if not use_header:
        return bag_ns
    stamp = msg.header.stamp
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


@dataclass
class _Collected:
    """What the first pass over the bag gathered."""

    depth_ns: list[int] = field(default_factory=list)
    depth_format: tuple[str, int, int] | None = None
    depth_samples: list[np.ndarray] = field(default_factory=list)
    color_ns: list[int] = field(default_factory=list)
    color_format: tuple[str, int, int] | None = None
    camera_info: Any = None
    camera_info_count: int = 0
    depth_units: float | None = None
    imu: list[tuple[int, float, float, float, float, float, float]] = field(default_factory=list)
    accel: list[tuple[int, float, float, float]] = field(default_factory=list)
    gyro: list[tuple[int, float, float, float]] = field(default_factory=list)
    joints: list[tuple[int, float, float]] = field(default_factory=list)
    events: list[tuple[int, str]] = field(default_factory=list)


def _check_format(
    previous: tuple[str, int, int] | None,
    msg: Any,
    topic: str,
    index: int,
    encodings: tuple[str, ...],
) -> tuple[str, int, int]:
    """Encoding and size: supported, and the same in every message of the topic."""
    current = (str(msg.encoding), int(msg.width), int(msg.height))
    if current[0] not in encodings:
        raise ConversionError(
            f"topic {topic}, message {index}: image encoding {current[0]!r} is not supported "
            f"here (supported: {', '.join(encodings)})"
        )
    if previous is not None and current != previous:
        raise ConversionError(
            f"topic {topic}, message {index}: {current[0]} {current[1]}×{current[2]} differs "
            f"from the first message's {previous[0]} {previous[1]}×{previous[2]}"
        )
    return current


def _vec(v: Any) -> tuple[float, float, float]:
    return float(v.x), float(v.y), float(v.z)


def _first_pass(bag: _Bag, choice: TopicChoice, cfg: BagConfig, counts: Mapping[str, int]):
    topic_of = choice.topic_of()
    role_of: dict[str, list[str]] = {}
    for role, topic in topic_of.items():
        role_of.setdefault(topic, []).append(role)
    n_depth = counts.get(choice.depth, 0)
    sample_at = set(np.unique(np.linspace(0, max(n_depth - 1, 0), DEPTH_CHECK_FRAMES).astype(int)))
    out = _Collected()
    use_header = cfg.stamps == "header"
    index: dict[str, int] = {}
    k_names = (cfg.knee_joint, cfg.ankle_joint)
    for topic, bag_ns, msg in bag.messages(set(role_of)):
        i = index[topic] = index.get(topic, -1) + 1
        for role in role_of[topic]:
            if role == "depth":
                out.depth_format = _check_format(out.depth_format, msg, topic, i, DEPTH_ENCODINGS)
                out.depth_ns.append(_stamp_ns(msg, bag_ns, use_header))
                if i in sample_at:
                    out.depth_samples.append(image_array(msg, topic, i))
            elif role == "color":
                out.color_format = _check_format(out.color_format, msg, topic, i, COLOR_ENCODINGS)
                out.color_ns.append(_stamp_ns(msg, bag_ns, use_header))
            elif role == "camera_info":
                out.camera_info_count += 1
                if out.camera_info is None:
                    out.camera_info = msg
            elif role == "depth_units":
                if out.depth_units is None:  # a float32: keep its 7 significant digits
                    out.depth_units = float(f"{float(msg.data):.7g}")
            elif role == "imu":
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
                out.imu.append(
                    (
                        _stamp_ns(msg, bag_ns, use_header),
                        *_vec(msg.angular_velocity),
                        *_vec(msg.linear_acceleration),
                    )
                )
            elif role == "accel":
                out.accel.append(
                    (_stamp_ns(msg, bag_ns, use_header), *_vec(msg.linear_acceleration))
                )
            elif role == "gyro":
                out.gyro.append((_stamp_ns(msg, bag_ns, use_header), *_vec(msg.angular_velocity)))
            elif role == "joint_states":
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
                        _stamp_ns(msg, bag_ns, use_header),
                        float(position[names.index(k_names[0])]),
                        float(position[names.index(k_names[1])]),
                    )
                )
            elif role == "gait_events":
                out.events.append((bag_ns, str(msg.data).strip()))
    return out


def _zero_stamps(values: list[int] | np.ndarray, topic: str, cfg: BagConfig) -> None:
    zeros = int(np.count_nonzero(np.asarray(values, dtype=np.int64) == 0))
    if zeros and cfg.stamps == "header":
        raise ConversionError(
            f"topic {topic}: {zeros} message(s) have header.stamp = 0; set bag.stamps: bag to "
            "use the recording time instead"
        )


def _intrinsics_from_info(msg: Any, is_ros2: bool, topic: str) -> tuple[CameraIntrinsics, str]:
    k = np.asarray(msg.k if is_ros2 else msg.K, dtype=np.float64).reshape(3, 3)
    d = np.asarray(msg.d if is_ros2 else msg.D, dtype=np.float64)
    try:
        intrinsics = CameraIntrinsics(
            int(msg.width),
            int(msg.height),
            float(k[0, 0]),
            float(k[1, 1]),
            float(k[0, 2]),
            float(k[1, 2]),
        )
    except RecordError as err:
        raise ConversionError(f"topic {topic}: camera_info is not a valid camera ({err})") from None
    note = ""
    if d.size and np.any(d != 0):
        note = (
            f"camera_info distortion ({msg.distortion_model}, {d.size} coefficients) is not "
            "applied; the session assumes a rectified pinhole camera"
        )
    return intrinsics, note


def _ordered(
    items: list[tuple], width: int, stream: str, source: str
) -> tuple[np.ndarray, np.ndarray, StreamReport]:
    """``items`` = (stamp ns, ``width`` values) tuples → (int64 stamps, N×width values) with
    finite values, in stamp order, duplicate stamps dropped; the report counts both."""
    stamps = np.asarray([it[0] for it in items], dtype=np.int64)
    values = np.asarray([it[1:] for it in items], dtype=np.float64).reshape(-1, width)
    finite = np.isfinite(values).all(axis=1)
    order = order_stamps(stamps[finite])
    kept = np.flatnonzero(finite)[order.keep]
    report = StreamReport(
        stream,
        source,
        int(stamps.size),
        int(kept.size),
        {"NaN or inf": int((~finite).sum()), "duplicate stamp": order.duplicates},
    )
    if order.reordered:
        report.notes.append(f"{order.reordered} message(s) out of stamp order, sorted")
    return stamps[kept], values[kept], report


class RosbagAdapter:
    """ROS 1 and ROS 2 bags via rosbags."""

    name = "rosbag"
    summary = "ROS 1 .bag or ROS 2 bag (.db3, .mcap, folder); presets realsense-sdk/realsense-ros"

    def detect(self, path: Path) -> bool:
        if path.is_file():
            return path.suffix in (".bag", ".db3", ".mcap") or path.name.endswith(".bag.active")
        # A folder of .db3/.mcap files without metadata.yaml is claimed too, to say how to fix it.
        return path.is_dir() and (
            (path / "metadata.yaml").is_file()
            or any(p.suffix in (".db3", ".mcap") for p in path.iterdir())
        )

    def open(self, path: Path, config: ConvertConfig) -> Recording:
        path = Path(path)
        cfg = config.bag
        report = ConversionReport(adapter=self.name, source=str(path))
        with _Bag(path) as bag:
            topics, counts, is_ros2 = bag.topics(), bag.counts(), bag.is_ros2
            choice = resolve_topics(topics, cfg)
            if choice.camera_info is None and cfg.intrinsics is None:
                raise MissingStreamError(
                    f"{path}: no camera_info topic for {choice.depth}; set bag.camera_info_topic "
                    f"or bag.intrinsics. Topics found: {_listing(topics)}"
                )
            got = _first_pass(bag, choice, cfg, counts)
        report.notes.append(
            f"ROS {'2' if is_ros2 else '1'} bag; topics chosen by preset {choice.preset}"
        )
        report.notes.extend(choice.notes)
        for role, values in (("depth", got.depth_ns), ("color", got.color_ns)):
            topic = getattr(choice, role)
            if topic is not None:
                _zero_stamps(values, topic, cfg)

        # ---- camera
        if not got.depth_ns or got.depth_format is None:
            raise MissingStreamError(f"{path}: depth topic {choice.depth} holds no message")
        encoding, width, height = got.depth_format
        if cfg.intrinsics is not None:
            intrinsics = CameraIntrinsics(**cfg.intrinsics.model_dump())
            report.notes.append("intrinsics from bag.intrinsics")
        else:
            if got.camera_info is None:
                raise MissingStreamError(f"{path}: camera_info topic {choice.camera_info} is empty")
            intrinsics, note = _intrinsics_from_info(
                got.camera_info, is_ros2, str(choice.camera_info)
            )
            report.notes.append(
                f"intrinsics from {choice.camera_info} (first of {got.camera_info_count} message(s))"
            )
            if note:
                report.notes.append(note)
        if (intrinsics.width_px, intrinsics.height_px) != (width, height):
            raise ConversionError(
                f"{path}: depth images on {choice.depth} are {width}×{height} but the intrinsics "
                f"say {intrinsics.width_px}×{intrinsics.height_px}"
            )
        if encoding == "32FC1":
            unit_m = cfg.float_depth_unit_m
            unit_source = (
                "32FC1 depth is in metres (REP 118)" if unit_m == 1.0 else "bag.float_depth_unit_m"
            )
            session_unit = config.output.depth_unit_m or FLOAT_DEPTH_SESSION_UNIT_M
            fix = "set bag.float_depth_unit_m"
        else:
            if cfg.depth_unit_m is not None:
                unit_m, unit_source = cfg.depth_unit_m, "bag.depth_unit_m"
            elif got.depth_units is not None:
                unit_m, unit_source = got.depth_units, f"bag option {choice.depth_units}"
            else:
                unit_m, unit_source = DEFAULT_DEPTH_UNIT_M, "default for 16-bit depth (REP 118: mm)"
            session_unit = config.output.depth_unit_m or unit_m
            fix = "set bag.depth_unit_m"
        check_depth_units(
            got.depth_samples,
            unit_m,
            where=f"{path} topic {choice.depth}",
            unit_source=unit_source,
            fix=fix,
        )
        report.notes.append(f"depth {encoding}, {unit_m:g} m per value ({unit_source})")

        # ---- frames and colour
        depth_ns = np.asarray(got.depth_ns, dtype=np.int64)
        d_order = order_stamps(depth_ns)
        depth_kept = d_order.keep  # message positions, in stamp order
        frames_dropped = {"duplicate stamp": d_order.duplicates}
        color_pos: np.ndarray | None = None
        use_color = choice.color is not None and choice.color_registered
        if choice.color is not None:
            color_ns = np.asarray(got.color_ns, dtype=np.int64)
            if not use_color:
                report.add(
                    StreamReport(
                        "color",
                        choice.color,
                        color_ns.size,
                        0,
                        {
                            "not registered to depth (set bag.color_registered_to_depth: true "
                            "if it is)": color_ns.size
                        },
                    )
                )
            else:
                if got.color_format is not None and got.color_format[1:] != (width, height):
                    raise ConversionError(
                        f"{path}: colour on {choice.color} is {got.color_format[1]}×"
                        f"{got.color_format[2]}, depth is {width}×{height}; registered colour "
                        "must have the depth's size"
                    )
                c_order = order_stamps(color_ns)
                max_dt = config.association.max_color_dt_s
                ns0 = int(depth_ns.min())
                i_d, i_c = associate(
                    (depth_ns[depth_kept] - ns0) * 1e-9,
                    (color_ns[c_order.keep] - ns0) * 1e-9,
                    max_dt,
                )
                frames_dropped[f"no colour image within {max_dt} s"] = depth_kept.size - i_d.size
                depth_kept = depth_kept[i_d]
                color_pos = c_order.keep[i_c]
                report.add(
                    StreamReport(
                        "color",
                        choice.color,
                        color_ns.size,
                        color_pos.size,
                        {
                            "duplicate stamp": c_order.duplicates,
                            f"no depth frame within {max_dt} s": c_order.keep.size - color_pos.size,
                        },
                    )
                )
        frames_report = report.add(
            StreamReport("frames", choice.depth, depth_ns.size, depth_kept.size, frames_dropped)
        )
        frame_t = depth_ns[depth_kept] * 1e-9

        # ---- IMU
        imu = None
        if choice.imu is not None:
            ns, values, imu_report = _ordered(got.imu, 6, "imu", choice.imu)
            report.add(imu_report)
            _zero_stamps(ns, choice.imu, cfg)
            imu = ImuSeries(ns * 1e-9, values[:, 0:3], values[:, 3:6]) if ns.size else None
        elif choice.accel is not None and choice.gyro is not None:
            g_ns, gyro, g_report = _ordered(got.gyro, 3, "gyro", choice.gyro)
            a_ns, accel, a_report = _ordered(got.accel, 3, "accel", choice.accel)
            _zero_stamps(g_ns, choice.gyro, cfg)
            _zero_stamps(a_ns, choice.accel, cfg)
            # Interpolate on times relative to the first stamp: exact weights (absolute float
            # seconds near 1.7e9 s resolve only 0.24 µs).
            ns0 = int(min(g_ns[0] if g_ns.size else 0, a_ns[0] if a_ns.size else 0))
            imu_rel, merge = merge_accel_gyro(
                (g_ns - ns0) * 1e-9,
                gyro,
                (a_ns - ns0) * 1e-9,
                accel,
                time_base=cfg.imu.time_base,
                max_gap_s=cfg.imu.max_gap_s,
            )
            imu = ImuSeries(imu_rel.t_s + ns0 * 1e-9, imu_rel.gyro_rad_s, imu_rel.accel_m_s2)
            base, other = (
                (g_report, a_report) if cfg.imu.time_base == "gyro" else (a_report, g_report)
            )
            base.used = merge.base_used
            base.dropped.update(
                {
                    "before the other stream starts": merge.base_dropped_start,
                    "after the other stream ends": merge.base_dropped_end,
                    f"other stream gap > {cfg.imu.max_gap_s} s": merge.base_dropped_gap,
                }
            )
            other.used = merge.other_used
            other.dropped.update(
                {
                    "before the first kept base sample": merge.other_unused_start,
                    "after the last kept base sample": merge.other_unused_end,
                }
            )
            other.notes.append(f"interpolated linearly at the {cfg.imu.time_base} stamps")
            report.add(g_report)
            report.add(a_report)
            report.notes.append(
                f"IMU: {len(imu)} samples on the {cfg.imu.time_base} time base "
                f"({choice.gyro} + {choice.accel})"
            )
            if imu is not None and len(imu) == 0:
                imu = None

        # ---- joints and events
        joints = None
        if choice.joint_states is not None:
            ns, values, j_report = _ordered(got.joints, 2, "joints", choice.joint_states)
            report.add(j_report)
            _zero_stamps(ns, choice.joint_states, cfg)
            if ns.size:
                joints = JointSeries(ns * 1e-9, values[:, 0], values[:, 1])
        events = None
        if choice.gait_events is not None:
            events, e_report = _map_events(got.events, cfg, choice.gait_events)
            report.add(e_report)

        resolved = config.model_copy(
            update={
                "format": self.name,
                "bag": cfg.model_copy(
                    update={
                        "preset": choice.preset,
                        "depth_topic": choice.depth,
                        "color_topic": choice.color,
                        "camera_info_topic": choice.camera_info,
                        "imu_topic": choice.imu,
                        "accel_topic": choice.accel,
                        "gyro_topic": choice.gyro,
                        "joint_states_topic": choice.joint_states,
                        "gait_events_topic": choice.gait_events,
                        "depth_unit_m": None if encoding == "32FC1" else unit_m,
                        "color_registered_to_depth": choice.color_registered,
                        "intrinsics": IntrinsicsConfig(
                            width_px=intrinsics.width_px,
                            height_px=intrinsics.height_px,
                            fx_px=intrinsics.fx_px,
                            fy_px=intrinsics.fy_px,
                            cx_px=intrinsics.cx_px,
                            cy_px=intrinsics.cy_px,
                        ),
                    }
                ),
            }
        )
        frames = _frame_reader(
            path,
            choice,
            depth_kept,
            color_pos if use_color else None,
            frame_t,
            unit_m,
            frames_report,
        )
        return Recording(
            name=path.stem if path.is_file() else path.name,
            report=report,
            resolved=resolved,
            intrinsics=intrinsics,
            depth_unit_m=session_unit,
            frame_times_s=frame_t,
            frames=frames,
            imu=imu,
            joints=joints,
            events=events,
            camera_profile=choice.preset if choice.preset != "none" else "rosbag",
            imu_profile=choice.preset if choice.preset != "none" else "rosbag",
        )


def _map_events(
    items: list[tuple[int, str]], cfg: BagConfig, topic: str
) -> tuple[GaitEvents, StreamReport]:
    dropped: dict[str, int] = {}
    times: list[int] = []
    kinds: list[str] = []
    for bag_ns, value in items:
        if value in cfg.gait_event_values:
            times.append(bag_ns)
            kinds.append(cfg.gait_event_values[value])
        else:
            key = f"unmapped value {value!r}"
            dropped[key] = dropped.get(key, 0) + 1
    order = order_stamps(np.asarray(times, dtype=np.int64))
    dropped["duplicate stamp"] = order.duplicates
    report = StreamReport("events", topic, len(items), order.keep.size, dropped)
    report.notes.append("stamped with the bag's receive time (std_msgs carry no header)")
    t_s = np.asarray(times, dtype=np.int64)[order.keep] * 1e-9
    events = GaitEvents(
        t_s, tuple(kinds[i] for i in order.keep), (cfg.gait_events_source,) * order.keep.size
    )
    return events, report


def _frame_reader(
    path: Path,
    choice: TopicChoice,
    depth_pos: np.ndarray,
    color_pos: np.ndarray | None,
    frame_t: np.ndarray,
    unit_m: float,
    frames_report: StreamReport,
):
    """A callable yielding the frames in stamp order (second pass over the bag)."""
    frame_of_depth = {int(p): k for k, p in enumerate(depth_pos)}
    frame_of_color = {} if color_pos is None else {int(p): k for k, p in enumerate(color_pos)}
    n_frames = int(depth_pos.size)

    def frames() -> Iterator[RgbdFrame]:
        depth_ready: dict[int, np.ndarray] = {}
        color_ready: dict[int, np.ndarray] = {}
        next_frame = 0
        topics = {choice.depth}
        if color_pos is not None and choice.color is not None:
            topics.add(choice.color)
        position = dict.fromkeys(topics, -1)
        non_finite = 0
        scale = np.float32(unit_m)
        with _Bag(path) as bag:
            for topic, _, msg in bag.messages(topics):
                position[topic] += 1
                pos = position[topic]
                if topic == choice.depth and pos in frame_of_depth:
                    raw = image_array(msg, topic, pos)
                    if raw.dtype == np.float32:
                        bad = ~np.isfinite(raw) | (raw < 0)
                        non_finite += int(bad.sum())
                        depth_ready[frame_of_depth[pos]] = (
                            np.where(bad, 0.0, raw).astype(np.float32) * scale
                        )
                    else:
                        depth_ready[frame_of_depth[pos]] = raw.astype(np.float32) * scale
                if topic == choice.color and pos in frame_of_color:
                    color_ready[frame_of_color[pos]] = image_array(msg, topic, pos)
                while (
                    next_frame < n_frames
                    and next_frame in depth_ready
                    and (color_pos is None or next_frame in color_ready)
                ):
                    yield RgbdFrame(
                        t_s=float(frame_t[next_frame]),
                        depth_m=depth_ready.pop(next_frame),
                        color_rgb=color_ready.pop(next_frame, None),
                        index=next_frame,
                    )
                    next_frame += 1
        if non_finite:
            frames_report.notes.append(
                f"{non_finite} depth pixel(s) NaN, inf or negative written as 0 (no reading, REP 118)"
            )
        if next_frame != n_frames:
            raise BagError(
                f"{path}: the second pass found {next_frame} of {n_frames} frames; the bag "
                "changed or is damaged while converting"
            )

    return frames

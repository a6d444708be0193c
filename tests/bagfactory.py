"""Small ROS 1 / ROS 2 bags written with rosbags' own writers, with known contents.

Layouts: ``sdk`` (RealSense SDK recording topics, ``/device_0/sensor_N/...``) and ``ros``
(RealSense ROS wrapper, ``/camera/camera/...``). Everything is analytic so the tests know the
answer: depth raw values, colour patterns, accel linear in time (so its interpolation at the
gyro stamps is exact), joint angles, gait events.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

T0_NS = 1_700_000_000 * 10**9
W, H = 32, 24
FX, FY, CX, CY = 30.0, 30.5, 15.5, 11.5
FRAME_NS = 33_333_333
COLOR_DELAY_NS = 4_000_000
ACCEL_NS = 16_000_000  # 62.5 Hz
GYRO_NS = 5_000_000  # 200 Hz
JOINT_NS = 10_000_000  # 100 Hz
BAG_DELAY_NS = 1_000_000  # receive time = stamp + 1 ms
EVENT_TOPIC = "/prosthesis/gait_event"


def accel_at(t_s: np.ndarray) -> np.ndarray:
    """Linear in time, so linear interpolation reproduces it exactly."""
    return np.column_stack([0.1 + 0.5 * t_s, np.full_like(t_s, 9.81), -0.2 * t_s])


def gyro_at(t_s: np.ndarray) -> np.ndarray:
    return np.column_stack([0.01 + 0.1 * t_s, np.full_like(t_s, 0.02), -0.03 * t_s])


def knee_at(t_s: np.ndarray) -> np.ndarray:
    return 0.3 + 0.2 * np.sin(5.0 * t_s)


def ankle_at(t_s: np.ndarray) -> np.ndarray:
    return -0.1 + 0.05 * t_s


def depth_raw(k: int) -> np.ndarray:
    """uint16 raw depth of frame k: 1200 + 10 u + k (units), a 2×2 hole of zeros."""
    u = np.arange(W)[None, :].repeat(H, axis=0)
    raw = (1200 + 10 * u + k).astype(np.uint16)
    raw[:2, :2] = 0
    return raw


def color_rgb(k: int) -> np.ndarray:
    u, v = np.meshgrid(np.arange(W), np.arange(H))
    return np.stack([u * 7 % 256, v * 9 % 256, np.full_like(u, 20 * k % 256)], -1).astype(np.uint8)


@dataclass
class BagSpec:
    ros2: bool = False
    storage: str = "sqlite3"  # ROS 2 only: sqlite3 | mcap
    layout: str = "sdk"  # sdk | ros
    n_frames: int = 8
    depth_encoding: str = "16UC1"  # 16UC1 | mono16 | 32FC1
    depth_scale: float = 1.0  # raw value multiplier (for 32FC1: metres = raw * 1e-3 * scale)
    depth_units_option: float | None = 0.001  # SDK 'Depth Units' option (None: no topic)
    color_encoding: str = "rgb8"
    missing_color: tuple[int, ...] = (3,)  # frames without a colour image
    imu: str = "separate"  # separate | combined | none
    motion_sensor: int = 2  # SDK sensor index of Accel/Gyro
    joints: bool = True
    events: bool = True
    accel_span_s: tuple[float, float] = (-0.01, 0.30)
    gyro_span_s: tuple[float, float] = (-0.02, 0.32)


@dataclass
class BagTruth:
    path: Path
    topics: dict[str, str] = field(default_factory=dict)
    depth_ns: list[int] = field(default_factory=list)
    color_ns: list[int] = field(default_factory=list)
    accel_ns: np.ndarray | None = None  # int64 stamps
    gyro_ns: np.ndarray | None = None
    imu_ns: np.ndarray | None = None
    joint_ns: np.ndarray | None = None
    events: list[tuple[float, str]] = field(default_factory=list)


def _topics(spec: BagSpec) -> dict[str, str]:
    if spec.layout == "sdk":
        m = spec.motion_sensor
        t = {
            "depth": "/device_0/sensor_0/Depth_0/image/data",
            "info": "/device_0/sensor_0/Depth_0/info/camera_info",
            "color": "/device_0/sensor_1/Color_0/image/data",
            "accel": f"/device_0/sensor_{m}/Accel_0/imu/data",
            "gyro": f"/device_0/sensor_{m}/Gyro_0/imu/data",
            "units": "/device_0/sensor_0/option/Depth_Units/value",
            "joints": "/prosthesis/joint_states",
        }
    else:
        ns = "/camera/camera"
        t = {
            "depth": f"{ns}/aligned_depth_to_color/image_raw",
            "info": f"{ns}/aligned_depth_to_color/camera_info",
            "color": f"{ns}/color/image_raw",
            "accel": f"{ns}/accel/sample",
            "gyro": f"{ns}/gyro/sample",
            "imu": f"{ns}/imu",
            "joints": "/joint_states",
        }
    t["events"] = EVENT_TOPIC
    return t


def write_bag(path: Path, spec: BagSpec) -> BagTruth:
    """Write the bag described by ``spec`` to ``path`` (a .bag file or a ROS 2 folder)."""
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE if spec.ros2 else Stores.ROS1_NOETIC)
    T = ts.types
    Time = T["builtin_interfaces/msg/Time"]
    Header = T["std_msgs/msg/Header"]
    Vec3 = T["geometry_msgs/msg/Vector3"]
    Quat = T["geometry_msgs/msg/Quaternion"]
    truth = BagTruth(path)
    names = _topics(spec)
    out: list[tuple[int, str, str, object]] = []  # (bag ns, topic, msgtype, msg)

    def header(ns: int, frame: str = "camera"):
        stamp = Time(sec=ns // 10**9, nanosec=ns % 10**9)
        if spec.ros2:
            return Header(stamp=stamp, frame_id=frame)
        return Header(seq=0, stamp=stamp, frame_id=frame)

    def add(ns: int, role: str, msgtype: str, msg: object) -> None:
        truth.topics[names[role]] = msgtype
        out.append((ns + BAG_DELAY_NS, names[role], msgtype, msg))

    Image = T["sensor_msgs/msg/Image"]
    for k in range(spec.n_frames):
        ns = T0_NS + k * FRAME_NS
        raw = depth_raw(k)
        if spec.depth_encoding == "32FC1":
            arr = (raw.astype(np.float32) * np.float32(1e-3 * spec.depth_scale)).astype("<f4")
            arr[:2, :2] = np.nan
            step = W * 4
        else:
            arr = (raw * spec.depth_scale).astype("<u2")
            step = W * 2
        data = np.frombuffer(arr.tobytes(), dtype=np.uint8)
        add(ns, "depth", Image.__msgtype__, Image(header=header(ns), height=H, width=W,
            encoding=spec.depth_encoding, is_bigendian=0, step=step, data=data))  # fmt: skip
        truth.depth_ns.append(ns)
        if k not in spec.missing_color:
            cns = ns + COLOR_DELAY_NS
            rgb = color_rgb(k)
            if spec.color_encoding == "bgr8":
                rgb = rgb[:, :, ::-1]
            cdata = np.frombuffer(np.ascontiguousarray(rgb).tobytes(), dtype=np.uint8)
            add(cns, "color", Image.__msgtype__, Image(header=header(cns), height=H, width=W,
                encoding=spec.color_encoding, is_bigendian=0, step=W * 3, data=cdata))  # fmt: skip
            truth.color_ns.append(cns)

    Info = T["sensor_msgs/msg/CameraInfo"]
    Roi = T["sensor_msgs/msg/RegionOfInterest"]
    k_mat = np.array([FX, 0, CX, 0, FY, CY, 0, 0, 1], dtype=np.float64)
    cam = dict(
        header=header(T0_NS), height=H, width=W, distortion_model="plumb_bob",
        binning_x=0, binning_y=0,
        roi=Roi(x_offset=0, y_offset=0, height=0, width=0, do_rectify=False),
    )  # fmt: skip
    mats = {"d": np.zeros(5), "k": k_mat, "r": np.eye(3).ravel(), "p": np.zeros(12)}
    cam.update({(key if spec.ros2 else key.upper()): v for key, v in mats.items()})
    add(T0_NS, "info", Info.__msgtype__, Info(**cam))

    if spec.layout == "sdk" and spec.depth_units_option is not None:
        F32 = T["std_msgs/msg/Float32"]
        add(T0_NS, "units", F32.__msgtype__, F32(data=spec.depth_units_option))

    Imu = T["sensor_msgs/msg/Imu"]
    zero9 = np.zeros(9)

    def imu_msg(ns: int, gyro: np.ndarray, accel: np.ndarray, frame: str):
        return Imu(
            header=header(ns, frame), orientation=Quat(x=0.0, y=0.0, z=0.0, w=1.0),
            orientation_covariance=np.r_[-1.0, np.zeros(8)],
            angular_velocity=Vec3(x=gyro[0], y=gyro[1], z=gyro[2]),
            angular_velocity_covariance=zero9,
            linear_acceleration=Vec3(x=accel[0], y=accel[1], z=accel[2]),
            linear_acceleration_covariance=zero9,
        )  # fmt: skip

    def times(span: tuple[float, float], period_ns: int) -> np.ndarray:
        start = T0_NS + round(span[0] * 1e9)
        stop = T0_NS + round(span[1] * 1e9)
        return np.arange(start, stop + 1, period_ns, dtype=np.int64)

    def rel(ns: np.ndarray) -> np.ndarray:
        return (ns - T0_NS) * 1e-9

    if spec.imu == "separate":
        a_ns, g_ns = times(spec.accel_span_s, ACCEL_NS), times(spec.gyro_span_s, GYRO_NS)
        for ns, acc in zip(a_ns, accel_at(rel(a_ns)), strict=True):
            add(int(ns), "accel", Imu.__msgtype__, imu_msg(int(ns), np.zeros(3), acc, "accel"))
        for ns, gyr in zip(g_ns, gyro_at(rel(g_ns)), strict=True):
            add(int(ns), "gyro", Imu.__msgtype__, imu_msg(int(ns), gyr, np.zeros(3), "gyro"))
        truth.accel_ns, truth.gyro_ns = a_ns, g_ns
    elif spec.imu == "combined":
        i_ns = times((0.0, 0.25), GYRO_NS)
        for ns, gyr, acc in zip(i_ns, gyro_at(rel(i_ns)), accel_at(rel(i_ns)), strict=True):
            add(int(ns), "imu", Imu.__msgtype__, imu_msg(int(ns), gyr, acc, "imu"))
        truth.imu_ns = i_ns

    if spec.joints:
        JS = T["sensor_msgs/msg/JointState"]
        j_ns = times((0.0, 0.25), JOINT_NS)
        for ns in j_ns:
            t = np.array([rel(np.array([ns]))[0]])
            pos = np.array([ankle_at(t)[0], knee_at(t)[0], 0.5])
            add(int(ns), "joints", JS.__msgtype__, JS(header=header(int(ns)),
                name=["ankle", "knee", "hip"], position=pos, velocity=np.zeros(3),
                effort=np.zeros(0)))  # fmt: skip
        truth.joint_ns = j_ns

    if spec.events:
        S = T["std_msgs/msg/String"]
        for t_rel, value in ((0.05, "foot_strike"), (0.10, "mid_stance"), (0.15, "toe_off"),
                             (0.25, "heel_strike")):  # fmt: skip
            ns = T0_NS + round(t_rel * 1e9)
            out.append((ns, names["events"], S.__msgtype__, S(data=value)))
            truth.topics[names["events"]] = S.__msgtype__
            truth.events.append((ns * 1e-9, value))

    out.sort(key=lambda item: item[0])
    if spec.ros2:
        from rosbags.rosbag2 import StoragePlugin, Writer

        plugin = StoragePlugin.MCAP if spec.storage == "mcap" else StoragePlugin.SQLITE3
        with Writer(path, version=9, storage_plugin=plugin) as writer:
            conns = {}
            for _, topic, msgtype, _ in out:
                if topic not in conns:
                    conns[topic] = writer.add_connection(topic, msgtype, typestore=ts)
            for ns, topic, msgtype, msg in out:
                writer.write(conns[topic], ns, ts.serialize_cdr(msg, msgtype))
    else:
        from rosbags.rosbag1 import Writer

        with Writer(path) as writer:
            conns = {}
            for _, topic, msgtype, _ in out:
                if topic not in conns:
                    conns[topic] = writer.add_connection(topic, msgtype, typestore=ts)
            for ns, topic, msgtype, msg in out:
                writer.write(conns[topic], ns, ts.serialize_ros1(msg, msgtype))
    return truth

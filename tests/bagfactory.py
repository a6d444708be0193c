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

# Unaligned colour (``BagSpec.color_mode = "unaligned"``): its own camera, and a textured plane
# seen by both, so the colour each depth pixel must get is known analytically.
CW, CH = 40, 30
CFX, CFY, CCX, CCY = 36.0, 36.5, 19.5, 14.5
#: depth camera → colour camera: a small rotation and a 15 mm baseline (maps depth points)
COLOR_T_DEPTH_ROTVEC = np.array([0.01, -0.02, 0.015])
COLOR_T_DEPTH_T = np.array([0.015, -0.002, 0.001])
#: the depth camera → IMU (accel and gyro share it): camera_T_imu
CAMERA_T_IMU_ROTVEC = np.array([0.02, 0.01, -0.03])
CAMERA_T_IMU_T = np.array([0.005, -0.006, 0.012])
#: the SDK's extrinsics reference stream, deliberately not the depth: depth_T_ref
DEPTH_T_REF_ROTVEC = np.array([0.0, 0.05, 0.0])
DEPTH_T_REF_T = np.array([-0.02, 0.0, 0.003])
#: the plane n·p = d in the depth frame
PLANE_N = np.array([0.1, -0.2, 1.0]) / np.linalg.norm([0.1, -0.2, 1.0])
PLANE_D = 1.3
#: colour encodes the depth pixel it shows: R = 7 u_depth, G = 9 v_depth
U_CODE, V_CODE = 7.0, 9.0
IMU_INTRINSIC = np.arange(12, dtype=np.float64).reshape(3, 4) * 0.01 + np.c_[np.eye(3), np.zeros(3)]
IMU_INTRINSIC_MSG = """float32[12] data
float32[3] noise_variances
float32[3] bias_variances
"""
TF_MESSAGE_MSG = "geometry_msgs/TransformStamped[] transforms\n"


def pose(rotvec: np.ndarray, t: np.ndarray) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    out = np.eye(4)
    out[:3, :3] = Rotation.from_rotvec(rotvec).as_matrix()
    out[:3, 3] = t
    return out


def color_T_depth() -> np.ndarray:
    return pose(COLOR_T_DEPTH_ROTVEC, COLOR_T_DEPTH_T)


def camera_T_imu() -> np.ndarray:
    return pose(CAMERA_T_IMU_ROTVEC, CAMERA_T_IMU_T)


def plane_depth_m() -> np.ndarray:
    """Depth (m) of the plane at every depth pixel centre (pinhole depth camera)."""
    v, u = np.mgrid[0:H, 0:W]
    rays = np.stack([(u - CX) / FX, (v - CY) / FY, np.ones((H, W))], -1)
    return PLANE_D / (rays @ PLANE_N)


def _distort(x: np.ndarray, y: np.ndarray, k: tuple[float, ...]) -> tuple[np.ndarray, np.ndarray]:
    k1, k2, p1, p2, k3 = (tuple(k) + (0.0,) * 5)[:5]
    r2 = x * x + y * y
    f = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
    return x * f + 2 * p1 * x * y + p2 * (r2 + 2 * x * x), y * f + 2 * p2 * x * y + p1 * (
        r2 + 2 * y * y
    )


def unaligned_color(k: int, distortion: tuple[float, ...] = ()) -> np.ndarray:
    """The colour camera's image of the plane: each colour pixel's ray meets the plane at a
    point whose depth-camera pixel (u, v) is encoded as R = 7u, G = 9v (B = frame number)."""
    cv, cu = np.mgrid[0:CH, 0:CW]
    xd, yd = (cu - CCX) / CFX, (cv - CCY) / CFY
    x, y = xd.copy(), yd.copy()
    for _ in range(50):  # invert the plumb_bob distortion (fixed point)
        px, py = _distort(x, y, distortion)
        x, y = x + xd - px, y + yd - py
    rays = np.stack([x, y, np.ones_like(x)], -1)
    c_T_d = color_T_depth()
    n_c = c_T_d[:3, :3] @ PLANE_N
    d_c = PLANE_D + n_c @ c_T_d[:3, 3]
    p_c = rays * (d_c / (rays @ n_c))[..., None]
    p_d = (p_c - c_T_d[:3, 3]) @ c_T_d[:3, :3]  # R^T (p_c - t), row-wise
    u = FX * p_d[..., 0] / p_d[..., 2] + CX
    v = FY * p_d[..., 1] / p_d[..., 2] + CY
    rgb = np.stack(
        [np.clip(np.rint(u * U_CODE), 0, 255), np.clip(np.rint(v * V_CODE), 0, 255),
         np.full_like(u, 100 + 10 * k)], -1
    )  # fmt: skip
    return rgb.astype(np.uint8)


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
    color_mode: str = "registered"  # registered (same size) | unaligned (CW×CH, own camera)
    color_distortion: tuple[float, ...] = ()  # plumb_bob k1 k2 p1 p2 k3 of the unaligned colour
    extrinsics: bool = False  # SDK tf topics + imu_intrinsic, or the wrapper's /tf_static
    compressed_color: str | None = None  # ros layout: png | jpeg on <ns>/color/image_raw/compressed
    compressed_depth: bool = False  # ros layout: 16UC1 compressedDepth png
    corrupt_color_message: int | None = None  # cut this compressed colour message in half
    odd_size_color_message: int | None = None  # this compressed colour message 2 rows shorter
    depth_distortion: tuple[float, ...] = ()  # plumb_bob k1 k2 p1 p2 k3 in the depth camera_info


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
            "color_info": "/device_0/sensor_1/Color_0/info/camera_info",
            "accel": f"/device_0/sensor_{m}/Accel_0/imu/data",
            "gyro": f"/device_0/sensor_{m}/Gyro_0/imu/data",
            "units": "/device_0/sensor_0/option/Depth_Units/value",
            "joints": "/prosthesis/joint_states",
        }
    else:
        ns = "/camera/camera"
        d = (
            "depth/image_rect_raw"
            if spec.color_mode == "unaligned"
            else "aligned_depth_to_color/image_raw"
        )
        t = {
            "depth": f"{ns}/{d}" + ("/compressedDepth" if spec.compressed_depth else ""),
            "info": f"{ns}/{d.rsplit('/', 1)[0]}/camera_info",
            "color_info": f"{ns}/color/camera_info",
            "tf_static": "/tf_static",
            "color": f"{ns}/color/image_raw" + ("/compressed" if spec.compressed_color else ""),
            "accel": f"{ns}/accel/sample",
            "gyro": f"{ns}/gyro/sample",
            "imu": f"{ns}/imu",
            "joints": "/joint_states",
        }
    t["events"] = EVENT_TOPIC
    return t


def write_bag(path: Path, spec: BagSpec) -> BagTruth:
    """Write the bag described by ``spec`` to ``path`` (a .bag file or a ROS 2 folder)."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE if spec.ros2 else Stores.ROS1_NOETIC)
    extra_types = get_types_from_msg(IMU_INTRINSIC_MSG, "realsense_msgs/msg/ImuIntrinsic")
    if "tf2_msgs/msg/TFMessage" not in ts.types:
        extra_types.update(get_types_from_msg(TF_MESSAGE_MSG, "tf2_msgs/msg/TFMessage"))
    ts.register(extra_types)
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

    def add(ns: int, role: str, msgtype: str, msg: object, literal: bool = False) -> None:
        topic = role if literal else names[role]
        truth.topics[topic] = msgtype
        out.append((ns + BAG_DELAY_NS, topic, msgtype, msg))

    Image = T["sensor_msgs/msg/Image"]
    Compressed = T["sensor_msgs/msg/CompressedImage"]
    unaligned = spec.color_mode == "unaligned"
    ros_frames = spec.layout == "ros"
    depth_frame = "camera_depth_optical_frame" if ros_frames else "camera"
    color_frame = "camera_color_optical_frame" if ros_frames else "camera"
    if ros_frames and not unaligned:
        depth_frame = color_frame  # aligned_depth_to_color is in the colour frame
    for k in range(spec.n_frames):
        ns = T0_NS + k * FRAME_NS
        raw = np.rint(plane_depth_m() * 1000).astype(np.uint16) if unaligned else depth_raw(k)
        if spec.depth_encoding == "32FC1":
            arr = (raw.astype(np.float32) * np.float32(1e-3 * spec.depth_scale)).astype("<f4")
            arr[:2, :2] = np.nan
            step = W * 4
        else:
            arr = (raw * spec.depth_scale).astype("<u2")
            step = W * 2
        data = np.frombuffer(arr.tobytes(), dtype=np.uint8)
        if spec.compressed_depth:
            payload = bytes(12) + _png(arr.astype(np.uint16))  # ConfigHeader, then the PNG
            add(ns, "depth", Compressed.__msgtype__, Compressed(header=header(ns, depth_frame),
                format="16UC1; compressedDepth png", data=np.frombuffer(payload, np.uint8)))  # fmt: skip
        else:
            add(ns, "depth", Image.__msgtype__, Image(header=header(ns, depth_frame), height=H,
                width=W, encoding=spec.depth_encoding, is_bigendian=0, step=step, data=data))  # fmt: skip
        truth.depth_ns.append(ns)
        if k not in spec.missing_color:
            cns = ns + COLOR_DELAY_NS
            rgb = unaligned_color(k, spec.color_distortion) if unaligned else color_rgb(k)
            if spec.compressed_color:
                payload = _encode(rgb, spec.compressed_color)
                n_color = len(truth.color_ns)
                if n_color == spec.odd_size_color_message:
                    payload = _encode(np.ascontiguousarray(rgb[:-2]), spec.compressed_color)
                if n_color == spec.corrupt_color_message:
                    payload = payload[: len(payload) // 2]
                add(cns, "color", Compressed.__msgtype__, Compressed(header=header(cns, color_frame),
                    format=f"rgb8; {spec.compressed_color} compressed bgr8",
                    data=np.frombuffer(payload, np.uint8)))  # fmt: skip
                truth.color_ns.append(cns)
                continue
            if spec.color_encoding == "bgr8":
                rgb = rgb[:, :, ::-1]
            cdata = np.frombuffer(np.ascontiguousarray(rgb).tobytes(), dtype=np.uint8)
            ch, cw = rgb.shape[:2]
            add(cns, "color", Image.__msgtype__, Image(header=header(cns, color_frame), height=ch,
                width=cw, encoding=spec.color_encoding, is_bigendian=0, step=cw * 3, data=cdata))  # fmt: skip
            truth.color_ns.append(cns)

    Info = T["sensor_msgs/msg/CameraInfo"]
    Roi = T["sensor_msgs/msg/RegionOfInterest"]
    k_mat = np.array([FX, 0, CX, 0, FY, CY, 0, 0, 1], dtype=np.float64)
    cam = dict(
        header=header(T0_NS), height=H, width=W, distortion_model="plumb_bob",
        binning_x=0, binning_y=0,
        roi=Roi(x_offset=0, y_offset=0, height=0, width=0, do_rectify=False),
    )  # fmt: skip
    d_depth = np.zeros(5)
    d_depth[: len(spec.depth_distortion)] = spec.depth_distortion
    mats = {"d": d_depth, "k": k_mat, "r": np.eye(3).ravel(), "p": np.zeros(12)}
    cam.update({(key if spec.ros2 else key.upper()): v for key, v in mats.items()})
    add(T0_NS, "info", Info.__msgtype__, Info(**cam))
    if unaligned:
        c_k = np.array([CFX, 0, CCX, 0, CFY, CCY, 0, 0, 1], dtype=np.float64)
        d = np.zeros(5)
        d[: len(spec.color_distortion)] = spec.color_distortion
        model = "plumb_bob" if ros_frames else "Brown Conrady"  # the SDK writes its own names
        ccam = dict(cam, height=CH, width=CW, distortion_model=model)
        mats = {"d": d, "k": c_k, "r": np.eye(3).ravel(), "p": np.zeros(12)}
        ccam.update({(key if spec.ros2 else key.upper()): v for key, v in mats.items()})
        add(T0_NS, "color_info", Info.__msgtype__, Info(**ccam))
    if spec.extrinsics:
        _write_extrinsics(spec, ts, add, header)

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
            add(int(ns), "accel", Imu.__msgtype__,
                imu_msg(int(ns), np.zeros(3), acc, "camera_accel_optical_frame"))  # fmt: skip
        for ns, gyr in zip(g_ns, gyro_at(rel(g_ns)), strict=True):
            add(int(ns), "gyro", Imu.__msgtype__,
                imu_msg(int(ns), gyr, np.zeros(3), "camera_gyro_optical_frame"))  # fmt: skip
        truth.accel_ns, truth.gyro_ns = a_ns, g_ns
    elif spec.imu == "combined":
        i_ns = times((0.0, 0.25), GYRO_NS)
        for ns, gyr, acc in zip(i_ns, gyro_at(rel(i_ns)), accel_at(rel(i_ns)), strict=True):
            add(
                int(ns),
                "imu",
                Imu.__msgtype__,
                imu_msg(int(ns), gyr, acc, "camera_imu_optical_frame"),
            )
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


def _png(array: np.ndarray) -> bytes:
    import io

    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(array).save(buf, format="PNG")
    return buf.getvalue()


def _encode(rgb: np.ndarray, kind: str) -> bytes:
    import io

    from PIL import Image

    buf = io.BytesIO()
    if kind == "jpeg":
        Image.fromarray(rgb).save(buf, format="JPEG", quality=95, subsampling=0)
    else:
        Image.fromarray(rgb).save(buf, format="PNG")
    return buf.getvalue()


#: x right, y down, z forward (optical) in a body frame x forward, y left, z up: body_T_optical
OPTICAL = np.array([[0, 0, 1, 0], [-1, 0, 0, 0], [0, -1, 0, 0], [0, 0, 0, 1]], dtype=float)


def _transform(T, pose4: np.ndarray):
    from scipy.spatial.transform import Rotation

    q = Rotation.from_matrix(pose4[:3, :3]).as_quat()  # x y z w
    Vec3, Quat = T["geometry_msgs/msg/Vector3"], T["geometry_msgs/msg/Quaternion"]
    return T["geometry_msgs/msg/Transform"](
        translation=Vec3(x=pose4[0, 3], y=pose4[1, 3], z=pose4[2, 3]),
        rotation=Quat(x=q[0], y=q[1], z=q[2], w=q[3]),
    )


def _write_extrinsics(spec: BagSpec, ts, add_role, header) -> None:
    """SDK: ``<stream>/tf/0`` = stream_T_ref for depth, colour, accel, gyro (reference: a
    frame that is not the depth) and ``imu_intrinsic``; wrapper: a ``/tf_static`` tree rooted
    at camera_link whose optical frames give the same color_T_depth and camera_T_imu."""
    T = ts.types
    inv = np.linalg.inv
    d_T_ref = pose(DEPTH_T_REF_ROTVEC, DEPTH_T_REF_T)
    c_T_d, d_T_i = color_T_depth(), camera_T_imu()
    if spec.layout == "sdk":
        m = spec.motion_sensor
        streams = {
            "/device_0/sensor_0/Depth_0": d_T_ref,
            "/device_0/sensor_1/Color_0": c_T_d @ d_T_ref,
            f"/device_0/sensor_{m}/Accel_0": inv(d_T_i) @ d_T_ref,
            f"/device_0/sensor_{m}/Gyro_0": inv(d_T_i) @ d_T_ref,
        }
        for stream, s_T_ref in streams.items():
            add_raw(add_role, f"{stream}/tf/0", T["geometry_msgs/msg/Transform"].__msgtype__,
                    _transform(T, s_T_ref))  # fmt: skip
        Intr = T["realsense_msgs/msg/ImuIntrinsic"]
        for stream in ("Accel_0", "Gyro_0"):
            msg = Intr(data=IMU_INTRINSIC.ravel().astype(np.float32),
                       noise_variances=np.full(3, 1e-4, np.float32),
                       bias_variances=np.full(3, 2e-6, np.float32))  # fmt: skip
            add_raw(add_role, f"/device_0/sensor_{m}/{stream}/imu_intrinsic", Intr.__msgtype__, msg)
        return
    link_T_dframe = pose(np.array([0.0, 0.0, 0.01]), np.array([0.0, 0.0, 0.0]))
    link_T_dopt = link_T_dframe @ OPTICAL
    link_T_copt = link_T_dopt @ inv(c_T_d)
    link_T_iopt = link_T_dopt @ d_T_i
    edges = [
        ("camera_link", "camera_depth_frame", link_T_dframe),
        ("camera_depth_frame", "camera_depth_optical_frame", OPTICAL),
        ("camera_link", "camera_color_frame", link_T_copt @ inv(OPTICAL)),
        ("camera_color_frame", "camera_color_optical_frame", OPTICAL),
        ("camera_link", "camera_gyro_frame", link_T_iopt @ inv(OPTICAL)),
        ("camera_gyro_frame", "camera_gyro_optical_frame", OPTICAL),
        ("camera_gyro_frame", "camera_imu_optical_frame", OPTICAL),
        ("camera_link", "camera_accel_frame", link_T_iopt @ inv(OPTICAL)),
        ("camera_accel_frame", "camera_accel_optical_frame", OPTICAL),
    ]
    Stamped = T["geometry_msgs/msg/TransformStamped"]
    msg = T["tf2_msgs/msg/TFMessage"](
        transforms=[
            Stamped(
                header=header(T0_NS, parent),
                child_frame_id=child,
                transform=_transform(T, parent_T_child),
            )
            for parent, child, parent_T_child in edges
        ]
    )
    add_role(T0_NS, "tf_static", msg.__msgtype__, msg)


def add_raw(add_role, topic: str, msgtype: str, msg) -> None:
    add_role(T0_NS, topic, msgtype, msg, literal=True)

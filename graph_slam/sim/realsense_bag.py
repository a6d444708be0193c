"""Writing a ROS 1 bag in the RealSense SDK's layout (what the RealSense Viewer and
``rs-record`` write), with rosbags' own writer: the messages, the topics, the calibration.

The topics are the ones ``graph_slam.session.adapters`` reads with the ``realsense-sdk`` preset
(docs/adapters.md):

```
/device_0/sensor_0/Depth_0/image/data          sensor_msgs/Image 16UC1 (value × depth unit)
/device_0/sensor_0/Depth_0/info/camera_info    sensor_msgs/CameraInfo (once)
/device_0/sensor_0/Depth_0/tf/0                geometry_msgs/Transform: depth_T_ref (identity)
/device_0/sensor_0/option/Depth Units/value    std_msgs/Float32 (metres per value)
/device_0/sensor_1/Color_0/image/data          sensor_msgs/Image rgb8, NOT aligned to depth
/device_0/sensor_1/Color_0/info/camera_info    its own size and intrinsics
/device_0/sensor_1/Color_0/tf/0                color_T_ref
/device_0/sensor_2/Accel_0/imu/data            sensor_msgs/Imu (linear_acceleration)
/device_0/sensor_2/Gyro_0/imu/data             sensor_msgs/Imu (angular_velocity)
/device_0/sensor_2/{Accel,Gyro}_0/tf/0         imu_T_ref
/device_0/sensor_2/{Accel,Gyro}_0/imu_intrinsic  realsense_msgs/ImuIntrinsic
```

The reference stream of the extrinsics is the depth stream (librealsense's choice for a D4xx).
Messages are written in time order as they come (:meth:`SdkBagWriter.write`), so a long
recording is never held in memory; rosbags is the optional ``bags`` extra.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from graph_slam.errors import SimulationError
from graph_slam.session.records import CameraIntrinsics

DEVICE = "/device_0"
DEPTH = f"{DEVICE}/sensor_0/Depth_0"
COLOR = f"{DEVICE}/sensor_1/Color_0"
ACCEL = f"{DEVICE}/sensor_2/Accel_0"
GYRO = f"{DEVICE}/sensor_2/Gyro_0"
DEPTH_UNITS = f"{DEVICE}/sensor_0/option/Depth Units/value"
IMU_INTRINSIC_MSG = "float32[12] data\nfloat32[3] noise_variances\nfloat32[3] bias_variances\n"


def _typestore():
    try:
        from rosbags.typesys import Stores, get_types_from_msg, get_typestore
    except ImportError:
        raise SimulationError(
            "writing a bag needs rosbags: pip install 'graph_slam[bags]'"
        ) from None
    store = get_typestore(Stores.ROS1_NOETIC)
    store.register(get_types_from_msg(IMU_INTRINSIC_MSG, "realsense_msgs/msg/ImuIntrinsic"))
    return store


class SdkBagWriter:
    """A ROS 1 bag in the SDK layout; use as a context manager, write messages in time order.

    Times are integer nanoseconds on the camera clock; the bag's receive time is the stamp.
    """

    def __init__(self, path: str | Path) -> None:
        from rosbags.rosbag1 import Writer

        self.path = Path(path)
        self.ts = _typestore()
        self._T = self.ts.types
        self._writer = Writer(self.path)
        self._conns: dict[str, Any] = {}
        self.counts: dict[str, int] = {}
        self._last_ns = -1

    def __enter__(self) -> SdkBagWriter:
        self._writer.open()
        return self

    def __exit__(self, *exc: object) -> None:
        self._writer.close()

    # ------------------------------------------------------------------ low level
    def _write(self, ns: int, topic: str, msg: Any) -> None:
        if ns < self._last_ns:
            raise SimulationError(f"{self.path}: {topic} written out of time order")
        self._last_ns = ns
        msgtype = msg.__msgtype__
        if topic not in self._conns:
            self._conns[topic] = self._writer.add_connection(topic, msgtype, typestore=self.ts)
        self._writer.write(self._conns[topic], ns, self.ts.serialize_ros1(msg, msgtype))
        self.counts[topic] = self.counts.get(topic, 0) + 1

    def _header(self, ns: int, frame: str = "0"):
        T = self._T
        stamp = T["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9)
        return T["std_msgs/msg/Header"](seq=0, stamp=stamp, frame_id=frame)

    # ------------------------------------------------------------------ calibration
    def write_calibration(
        self,
        ns: int,
        depth: CameraIntrinsics,
        color: CameraIntrinsics,
        color_T_depth: np.ndarray,
        camera_T_imu: np.ndarray,
        depth_unit_m: float,
        imu_noise_variances: tuple[np.ndarray, np.ndarray],
    ) -> None:
        """Camera infos, the depth-units option, the streams' ``tf`` (reference: depth) and
        the IMU intrinsics (identity scale, zero bias; the noise variances given, accel then
        gyro). Written once, at the start."""
        T = self._T
        self._write(ns, f"{DEPTH}/info/camera_info", self._info(ns, depth))
        self._write(ns, f"{COLOR}/info/camera_info", self._info(ns, color))
        self._write(ns, DEPTH_UNITS, T["std_msgs/msg/Float32"](data=float(depth_unit_m)))
        imu_T_depth = np.linalg.inv(camera_T_imu)
        for stream, s_T_ref in (
            (DEPTH, np.eye(4)),
            (COLOR, color_T_depth),
            (ACCEL, imu_T_depth),
            (GYRO, imu_T_depth),
        ):
            self._write(ns, f"{stream}/tf/0", self._transform(s_T_ref))
        scale_bias = np.c_[np.eye(3), np.zeros(3)].ravel().astype(np.float32)
        for stream, variances in zip((ACCEL, GYRO), imu_noise_variances, strict=True):
            msg = T["realsense_msgs/msg/ImuIntrinsic"](
                data=scale_bias,
                noise_variances=np.asarray(variances, np.float32),
                bias_variances=np.zeros(3, np.float32),
            )
            self._write(ns, f"{stream}/imu_intrinsic", msg)

    def _info(self, ns: int, k: CameraIntrinsics):
        T = self._T
        roi = T["sensor_msgs/msg/RegionOfInterest"](
            x_offset=0, y_offset=0, height=0, width=0, do_rectify=False
        )
        K = np.array([k.fx_px, 0, k.cx_px, 0, k.fy_px, k.cy_px, 0, 0, 1], np.float64)
        P = np.array([k.fx_px, 0, k.cx_px, 0, 0, k.fy_px, k.cy_px, 0, 0, 0, 1, 0], np.float64)
        return T["sensor_msgs/msg/CameraInfo"](
            header=self._header(ns), height=k.height_px, width=k.width_px,
            distortion_model="Brown Conrady", D=np.zeros(5), K=K, R=np.eye(3).ravel(), P=P,
            binning_x=0, binning_y=0, roi=roi,
        )  # fmt: skip

    def _transform(self, pose4: np.ndarray):
        from scipy.spatial.transform import Rotation

        T = self._T
        q = Rotation.from_matrix(pose4[:3, :3]).as_quat()  # x y z w
        Vec3, Quat = T["geometry_msgs/msg/Vector3"], T["geometry_msgs/msg/Quaternion"]
        return T["geometry_msgs/msg/Transform"](
            translation=Vec3(x=pose4[0, 3], y=pose4[1, 3], z=pose4[2, 3]),
            rotation=Quat(x=q[0], y=q[1], z=q[2], w=q[3]),
        )

    # ------------------------------------------------------------------ streams
    def write_depth(self, ns: int, raw: np.ndarray) -> None:
        """A 16UC1 depth image (values × the depth unit = metres; 0 = no reading)."""
        self._write(ns, f"{DEPTH}/image/data", self._image(ns, raw.astype("<u2"), "16UC1", 2))

    def write_color(self, ns: int, rgb: np.ndarray) -> None:
        """An rgb8 colour image (its own size; not aligned to depth)."""
        self._write(ns, f"{COLOR}/image/data", self._image(ns, rgb.astype(np.uint8), "rgb8", 3))

    def _image(self, ns: int, array: np.ndarray, encoding: str, bytes_per_px: int):
        h, w = array.shape[:2]
        data = np.frombuffer(np.ascontiguousarray(array).tobytes(), dtype=np.uint8)
        return self._T["sensor_msgs/msg/Image"](
            header=self._header(ns), height=h, width=w, encoding=encoding, is_bigendian=0,
            step=w * bytes_per_px, data=data,
        )  # fmt: skip

    def write_accel(self, ns: int, accel_m_s2: np.ndarray) -> None:
        self._write(ns, f"{ACCEL}/imu/data", self._imu(ns, np.zeros(3), accel_m_s2))

    def write_gyro(self, ns: int, gyro_rad_s: np.ndarray) -> None:
        self._write(ns, f"{GYRO}/imu/data", self._imu(ns, gyro_rad_s, np.zeros(3)))

    def _imu(self, ns: int, gyro: np.ndarray, accel: np.ndarray):
        T = self._T
        Vec3, Quat = T["geometry_msgs/msg/Vector3"], T["geometry_msgs/msg/Quaternion"]
        return T["sensor_msgs/msg/Imu"](
            header=self._header(ns), orientation=Quat(x=0.0, y=0.0, z=0.0, w=1.0),
            orientation_covariance=np.r_[-1.0, np.zeros(8)],
            angular_velocity=Vec3(x=gyro[0], y=gyro[1], z=gyro[2]),
            angular_velocity_covariance=np.zeros(9),
            linear_acceleration=Vec3(x=accel[0], y=accel[1], z=accel[2]),
            linear_acceleration_covariance=np.zeros(9),
        )  # fmt: skip

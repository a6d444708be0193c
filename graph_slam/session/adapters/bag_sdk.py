"""The RealSense SDK's own texts in its recordings (docs/adapters.md, "RealSense SDK layout").

librealsense 2.5x writes ROS 2 ``.db3`` files whose calibration and per-frame metadata are
``std_msgs/String`` key=value texts, ``;``-separated:

- ``<stream>/tf/ref_<g>``: ``rotation=r0,…,r8;translation=x,y,z``, the extrinsics *from* the
  reference stream of group ``g`` *to* the stream (``p_stream = R p_ref + t``, ``R`` stored
  column-major as librealsense's ``rs2_extrinsics``), i.e. ``stream_T_ref``;
- ``<stream>/image/metadata``, ``<stream>/imu/metadata``: ``Frame number=…;timestamp_domain=…;
  system_time=…;timestamp=<ms>;…``, one per frame, written right after the frame: the frame's
  own time (the device clock). The messages' ``header.stamp`` is the recording's time instead;
- ``<stream>/imu_intrinsic``: ``data=<12>;bias_variances=<3>;noise_variances=<3>``;
- ``/device_<d>/info``: ``Name=…;Serial Number=…;Firmware Version=…;…``.

ROS 1 SDK bags (librealsense before 2.5x) carry typed messages instead (``geometry_msgs/
Transform``, ``realsense_msgs/ImuIntrinsic``, ``diagnostic_msgs/KeyValue``); both are read here.
"""

from __future__ import annotations

import re
from typing import Any

import numpy as np

from graph_slam.errors import ConversionError

STRING = "std_msgs/msg/String"
KEY_VALUE = "diagnostic_msgs/msg/KeyValue"
#: ``/device_<d>/info`` (the device) or its sensors' info
SDK_DEVICE_INFO = re.compile(r"^/device_\d+/info$")
#: the device info keys reported, with the name they get in the conversion report
DEVICE_KEYS = {
    "Name": "product",
    "Serial Number": "serial",
    "Firmware Version": "firmware",
    "Product Id": "product_id",
    "Usb Type Descriptor": "usb",
}


def key_values(text: str) -> dict[str, str]:
    """``a=1;b=x,y`` → ``{"a": "1", "b": "x,y"}`` (empty items ignored)."""
    out = {}
    for item in str(text).split(";"):
        if "=" in item:
            key, value = item.split("=", 1)
            out[key.strip()] = value.strip()
    return out


def _floats(text: str, n: int, where: str, key: str) -> np.ndarray:
    try:
        values = np.array([float(v) for v in text.split(",")], dtype=np.float64)
    except ValueError:
        raise ConversionError(f"{where}: {key}={text!r} is not {n} numbers") from None
    if values.size != n or not np.all(np.isfinite(values)):
        raise ConversionError(f"{where}: {key} must hold {n} finite numbers, found {text!r}")
    return values


def string_transform(text: str, where: str) -> np.ndarray:
    """An SDK ``tf`` text → ``stream_T_ref`` (4×4); the rotation must be orthonormal."""
    kv = key_values(text)
    missing = [k for k in ("rotation", "translation") if k not in kv]
    if missing:
        raise ConversionError(f"{where}: extrinsics text {text!r} lacks {missing}")
    rot = _floats(kv["rotation"], 9, where, "rotation").reshape(3, 3).T  # column-major
    if not np.allclose(rot @ rot.T, np.eye(3), atol=1e-4) or np.linalg.det(rot) < 0:
        raise ConversionError(f"{where}: the rotation {kv['rotation']} is not a rotation")
    pose = np.eye(4)
    pose[:3, :3] = rot
    pose[:3, 3] = _floats(kv["translation"], 3, where, "translation")
    return pose


def metadata_stamp_ns(text: str, where: str) -> int:
    """A frame metadata text → the frame's timestamp in integer nanoseconds."""
    kv = key_values(text)
    if "timestamp" not in kv:
        raise ConversionError(f"{where}: frame metadata {text[:80]!r} has no timestamp")
    try:
        ms = float(kv["timestamp"])
    except ValueError:
        raise ConversionError(f"{where}: timestamp={kv['timestamp']!r} is not a number") from None
    if not np.isfinite(ms):
        raise ConversionError(f"{where}: timestamp={kv['timestamp']!r} is not finite")
    # ms with 6 decimals: exact to the nanosecond through Python's decimal parse of the text
    whole, _, frac = kv["timestamp"].partition(".")
    if whole.lstrip("-").isdigit() and (not frac or frac.isdigit()):
        sign = -1 if whole.startswith("-") else 1
        return sign * (abs(int(whole)) * 1_000_000 + int((frac + "000000")[:6]))
    return round(ms * 1e6)


def imu_intrinsic_values(msg: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(3×4 scale|bias, noise variances, bias variances) of a ``realsense_msgs/ImuIntrinsic``
    (ROS 1) or of the SDK's text (ROS 2)."""
    if msg.__msgtype__ == STRING:
        kv = key_values(msg.data)
        where = "imu_intrinsic"
        return (
            _floats(kv.get("data", ""), 12, where, "data").reshape(3, 4),
            _floats(kv.get("noise_variances", ""), 3, where, "noise_variances"),
            _floats(kv.get("bias_variances", ""), 3, where, "bias_variances"),
        )
    return (
        np.asarray(msg.data, dtype=np.float64).reshape(3, 4),
        np.asarray(msg.noise_variances, dtype=np.float64),
        np.asarray(msg.bias_variances, dtype=np.float64),
    )


def device_info(messages: list[tuple[str | None, Any]]) -> dict[str, str]:
    """The device's product, serial and firmware from ``/device_<d>/info`` messages
    (``(msgtype, msg)``): one SDK text (ROS 2) or one ``diagnostic_msgs/KeyValue`` per key
    (ROS 1)."""
    found: dict[str, str] = {}
    for msgtype, msg in messages:
        if msgtype == STRING:
            found.update(key_values(msg.data))
        elif msgtype == KEY_VALUE:
            found[str(msg.key)] = str(msg.value)
    return {DEVICE_KEYS[k]: v for k, v in found.items() if k in DEVICE_KEYS}

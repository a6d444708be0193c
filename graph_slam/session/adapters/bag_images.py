"""Decoding image messages: raw ``sensor_msgs/Image`` and, in ROS-wrapper bags,
``sensor_msgs/CompressedImage`` (jpeg / png colour, ``compressedDepth`` PNG depth), strictly: a
damaged image is an error naming the topic and the message index, never a zero frame."""

from __future__ import annotations

from typing import Any

import numpy as np

from graph_slam.errors import ConversionError

DEPTH_ENCODINGS = ("16UC1", "mono16", "32FC1")
COLOR_ENCODINGS = ("rgb8", "bgr8")


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


def check_format(
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

"""Decoding image messages: raw ``sensor_msgs/Image`` and, in ROS-wrapper bags,
``sensor_msgs/CompressedImage`` (jpeg / png colour, ``compressedDepth`` PNG depth), strictly: a
damaged image is an error naming the topic and the message index, never a zero frame."""

from __future__ import annotations

from typing import Any

import numpy as np

from graph_slam.errors import CompressedImageError, ConversionError
from graph_slam.session.adapters.bag_topics import COMPRESSED

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


# --------------------------------------------------------------------------- compressed images
#: compressed_depth_image_transport's ConfigHeader: int32 format, float32 depthParam[2]
COMPRESSED_DEPTH_HEADER_BYTES = 12
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def _pil_decode(data: bytes, where: str, formats: tuple[str, ...]) -> Any:
    """Decode with Pillow, strictly: a PNG's chunks and CRCs are verified first; a truncated
    JPEG or PNG is an error (Pillow's LOAD_TRUNCATED_IMAGES is never set)."""
    import io

    from PIL import Image, UnidentifiedImageError

    try:
        with Image.open(io.BytesIO(data)) as probe:
            if probe.format not in formats:
                raise CompressedImageError(
                    f"{where}: expected {' or '.join(formats)} data, found {probe.format}"
                )
            if probe.format == "PNG":
                probe.verify()
        img = Image.open(io.BytesIO(data))
        img.load()
        return img
    except CompressedImageError:
        raise
    except (UnidentifiedImageError, OSError, SyntaxError, ValueError, EOFError) as err:
        raise CompressedImageError(f"{where}: corrupt or truncated image ({err})") from None


def compressed_array(msg: Any, topic: str, index: int, role: str) -> np.ndarray:
    """A ``sensor_msgs/CompressedImage`` → uint8 H×W×3 RGB (``role`` colour: jpeg or png) or
    uint16 H×W (``role`` depth: image_transport's ``compressedDepth``, 16UC1 as PNG after its
    12-byte header). RVL and 32FC1 (inverse-depth) compressedDepth are refused, named."""
    fmt = str(msg.format).strip()
    where = f"topic {topic}, message {index} (format {fmt!r})"
    data = bytes(np.asarray(msg.data, dtype=np.uint8).tobytes())
    if role == "depth":
        lowered = fmt.lower()
        if "compresseddepth" not in lowered:
            raise CompressedImageError(
                f"{where}: a depth topic must be image_transport's compressedDepth "
                "('16UC1; compressedDepth png')"
            )
        if "rvl" in lowered:
            raise CompressedImageError(
                f"{where}: RVL compressedDepth is not supported; record with the png "
                "compressedDepth format or raw depth"
            )
        if not lowered.startswith(("16uc1", "mono16")):
            raise CompressedImageError(
                f"{where}: only 16UC1 compressedDepth is supported (32FC1 is stored as "
                "quantised inverse depth)"
            )
        if data[: len(PNG_MAGIC)] != PNG_MAGIC:  # current transports prefix a ConfigHeader
            data = data[COMPRESSED_DEPTH_HEADER_BYTES:]
        img = _pil_decode(data, where, ("PNG",))
        if img.mode not in ("I;16", "I;16B", "I;16L"):
            raise CompressedImageError(f"{where}: depth PNG must be 16-bit, found {img.mode!r}")
        return np.array(img, dtype=np.uint16)
    img = _pil_decode(data, where, ("JPEG", "PNG"))
    if img.mode == "RGBA":
        img = img.convert("RGB")
    if img.mode != "RGB":
        raise CompressedImageError(f"{where}: colour must be 8-bit RGB, found mode {img.mode!r}")
    return np.array(img, dtype=np.uint8)


def decode_image(msg: Any, msgtype: str, topic: str, index: int, role: str) -> np.ndarray:
    """Raw or compressed image message → array (see :func:`image_array`, :func:`compressed_array`)."""
    if msgtype == COMPRESSED:
        return compressed_array(msg, topic, index, role)
    return image_array(msg, topic, index)

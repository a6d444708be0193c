"""A PNG encoder for the session's two image kinds (16-bit grey depth, 8-bit RGB colour).

Each row is stored with PNG's *Up* filter (the difference to the row above, byte by byte)
and deflated with zlib's run-length strategy: on depth and colour images of a walk this is
as small as Pillow's default encoder at ``compress_level=1`` (its adaptive per-row filter)
and takes about half its CPU time, most of it in zlib, which runs without Python's global
interpreter lock (a live run writes its session on a thread beside the estimator's).
``level=0`` stores the rows unfiltered and uncompressed (the size of the raw image; the
fastest). Any PNG reader decodes the files (PNG 1.2, one IDAT chunk, no interlace).
"""

from __future__ import annotations

import struct
import zlib

import numpy as np

SIGNATURE = b"\x89PNG\r\n\x1a\n"
FILTER_NONE, FILTER_UP = 0, 2


def _chunk(tag: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data))


def _rows(array: np.ndarray) -> tuple[np.ndarray, int, int]:
    """The image as bytes per row (big-endian for 16 bits), its bit depth and colour type."""
    if array.dtype == np.uint16 and array.ndim == 2:
        return array.astype(">u2").view(np.uint8), 16, 0  # greyscale
    if array.dtype == np.uint8 and array.ndim == 3 and array.shape[2] == 3:
        return np.ascontiguousarray(array).reshape(array.shape[0], -1), 8, 2  # RGB
    raise ValueError(
        f"encode_png: unsupported array {array.dtype} {array.shape} "
        "(uint16 H×W depth or uint8 H×W×3 colour)"
    )


def encode_png(array: np.ndarray, level: int = 1) -> bytes:
    """PNG bytes of a uint16 H×W or uint8 H×W×3 array; ``level`` 0–9 (zlib's level; 0 stores
    the rows as they are)."""
    if not 0 <= int(level) <= 9:
        raise ValueError(f"encode_png: level must be 0..9, got {level}")
    raw, bit_depth, colour_type = _rows(array)
    h, w = array.shape[:2]
    if h == 0 or w == 0:
        raise ValueError(f"encode_png: empty image {array.shape}")
    rows = np.empty((h, raw.shape[1] + 1), np.uint8)
    rows[:, 1:] = raw
    if level == 0:
        rows[:, 0] = FILTER_NONE
        data = zlib.compress(rows.tobytes(), 0)
    else:
        rows[:, 0] = FILTER_UP
        np.subtract(raw[1:], raw[:-1], out=rows[1:, 1:])  # bytes wrap modulo 256, as PNG's
        rows[0, 0] = FILTER_NONE  # (Up on the first row is the row itself)
        packer = zlib.compressobj(int(level), zlib.DEFLATED, 15, 9, zlib.Z_RLE)
        data = packer.compress(rows.tobytes()) + packer.flush()
    header = struct.pack(">IIBBBBB", w, h, bit_depth, colour_type, 0, 0, 0)
    return SIGNATURE + _chunk(b"IHDR", header) + _chunk(b"IDAT", data) + _chunk(b"IEND", b"")

"""Messages between the live process and its helper processes (the viewer's, the session
writer's): two 4-byte big-endian lengths (the header's, the arrays'), a JSON header (UTF-8)
naming the arrays that follow (name, dtype, shape), then their bytes. No pickle.

:func:`pack` builds one message as bytes; :func:`send` writes one to a file descriptor without
copying the arrays first (the system call runs without Python's interpreter lock, so a large
frame is handed to the pipe beside the estimator's work); :func:`read_message` reads them back.
"""

from __future__ import annotations

import json
import os
import struct
import threading
from collections.abc import Callable
from typing import BinaryIO

import numpy as np


def _head(header: dict, arrays: dict[str, np.ndarray]) -> tuple[bytes, int]:
    spec = [[name, a.dtype.str, list(a.shape)] for name, a in arrays.items()]
    head = json.dumps({**header, "arrays": spec}).encode()
    return head, sum(a.nbytes for a in arrays.values())


def pack(header: dict, arrays: dict[str, np.ndarray] | None = None) -> bytes:
    """One message: ``header`` (JSON-able) and the named arrays."""
    arrays = {k: np.ascontiguousarray(a) for k, a in (arrays or {}).items()}
    head, n_body = _head(header, arrays)
    body = b"".join(a.tobytes() for a in arrays.values())
    return struct.pack(">II", len(head), n_body) + head + body


def send(fd: int, header: dict, arrays: dict[str, np.ndarray] | None = None) -> None:
    """Write one message to the file descriptor ``fd`` (blocking until all of it is written;
    ``BrokenPipeError`` / ``OSError`` when the reader is gone)."""
    arrays = {k: np.ascontiguousarray(a) for k, a in (arrays or {}).items()}
    head, n_body = _head(header, arrays)
    _write_all(fd, memoryview(struct.pack(">II", len(head), n_body) + head))
    for a in arrays.values():
        if a.nbytes:
            _write_all(fd, memoryview(a.reshape(-1)).cast("B"))


def _write_all(fd: int, view: memoryview) -> None:
    while view.nbytes:
        view = view[os.write(fd, view) :]


def read_message(stream: BinaryIO) -> tuple[dict, dict[str, np.ndarray]] | None:
    """The next message from ``stream``; None at its end (a message cut short ends it too)."""
    lengths = stream.read(8)
    if len(lengths) < 8:
        return None
    n_head, n_body = struct.unpack(">II", lengths)
    head, body = stream.read(n_head), stream.read(n_body)
    if len(head) < n_head or len(body) < n_body:
        return None
    return unpack(head, body)


def unpack(head: bytes, body: bytes) -> tuple[dict, dict[str, np.ndarray]]:
    header = json.loads(head)
    arrays, at = {}, 0
    for name, dtype, shape in header.pop("arrays"):
        dt = np.dtype(dtype)
        n = int(np.prod(shape, dtype=np.int64)) * dt.itemsize
        arrays[name] = np.frombuffer(body, dt, count=n // dt.itemsize, offset=at).reshape(shape)
        at += n
    return header, arrays


def read_line(stream: BinaryIO, timeout_s: float) -> bytes:
    """One line of ``stream`` within ``timeout_s`` (b"" when none came)."""
    return read_within(stream.readline, timeout_s)


def read_within(read: Callable[[], bytes], timeout_s: float) -> bytes:
    """What ``read()`` returns within ``timeout_s`` (b"" when it has not returned by then; the
    reading thread is left to end with the stream)."""
    got: list[bytes] = []
    reader = threading.Thread(target=lambda: got.append(read()), daemon=True)
    reader.start()
    reader.join(timeout_s)
    return got[0] if got else b""

"""Point clouds (:class:`~graph_slam.session.records.Cloud`) as PLY: ``x y z`` (double) and
optional ``red green blue`` (uchar).

Written with numpy alone (ASCII, or binary little-endian), read back symmetrically. The reader
also takes what other tools write: float or double coordinates, normals ``nx ny nz``, any other
scalar vertex properties (ignored, logged), binary big-endian, and elements after the vertices
(ignored). The vertex element must come first; list properties on it are refused.
"""

from __future__ import annotations

import io as _io
import logging
from contextlib import contextmanager
from pathlib import Path
from typing import BinaryIO

import numpy as np

from graph_slam.errors import RecordError, StreamError
from graph_slam.session.records import Cloud

logger = logging.getLogger(__name__)

PLY_TYPES: dict[str, str] = {
    "char": "i1",
    "int8": "i1",
    "uchar": "u1",
    "uint8": "u1",
    "short": "i2",
    "int16": "i2",
    "ushort": "u2",
    "uint16": "u2",
    "int": "i4",
    "int32": "i4",
    "uint": "u4",
    "uint32": "u4",
    "float": "f4",
    "float32": "f4",
    "double": "f8",
    "float64": "f8",
}
FORMATS = {"ascii": None, "binary_little_endian": "<", "binary_big_endian": ">"}


@contextmanager
def _binary(target: str | Path | BinaryIO, mode: str):
    if isinstance(target, str | Path):
        with Path(target).open(mode) as f:
            yield f, str(target)
    else:
        yield target, str(getattr(target, "name", "<stream>"))


def write_ply(
    cloud: Cloud, dest: str | Path | BinaryIO, *, binary: bool = True, dtype: str = "float64"
) -> None:
    """Write a point cloud as PLY (binary little-endian by default, or ASCII): points as double
    (``dtype`` "float32": float), colours as uchar (``Cloud.colors_rgb``); normals are not
    written."""
    if dtype not in ("float64", "float32"):
        raise ValueError(f"write_ply: dtype must be 'float64' or 'float32', got {dtype!r}")
    ply_type, np_type = ("double", "<f8") if dtype == "float64" else ("float", "<f4")
    n = len(cloud)
    colors_rgb = cloud.colors_rgb
    has_color = colors_rgb is not None
    header = [
        "ply",
        f"format {'binary_little_endian' if binary else 'ascii'} 1.0",
        "comment written by graph_slam",
        f"element vertex {n}",
        f"property {ply_type} x",
        f"property {ply_type} y",
        f"property {ply_type} z",
    ]
    if has_color:
        header += ["property uchar red", "property uchar green", "property uchar blue"]
    header.append("end_header")
    fields = [("x", np_type), ("y", np_type), ("z", np_type)]
    if has_color:
        fields += [("red", "u1"), ("green", "u1"), ("blue", "u1")]
    rec = np.empty(n, dtype=np.dtype(fields))
    for i, axis in enumerate("xyz"):
        rec[axis] = cloud.points_m[:, i]
    if colors_rgb is not None:
        for i, ch in enumerate(("red", "green", "blue")):
            rec[ch] = colors_rgb[:, i]
    with _binary(dest, "wb") as (handle, _):
        handle.write(("\n".join(header) + "\n").encode("ascii"))
        if binary:
            handle.write(rec.tobytes())
        else:
            text = _io.StringIO()
            fmt = ["%.17g"] * 3 + (["%d"] * 3 if has_color else [])
            np.savetxt(text, rec.tolist() if n else np.zeros((0, len(fmt))), fmt=fmt)
            handle.write(text.getvalue().encode("ascii"))


def _parse_header(handle: BinaryIO, name: str) -> tuple[str, list[tuple[str, int, list]]]:
    magic = handle.readline()
    if magic.strip() != b"ply":
        raise StreamError(f"{name}: not a PLY file (first line {magic[:20]!r})")
    fmt = None
    elements: list[tuple[str, int, list]] = []
    line_no = 1
    while True:
        raw = handle.readline()
        line_no += 1
        if not raw:
            raise StreamError(f"{name}: header has no 'end_header'")
        words = raw.decode("ascii", errors="replace").split()
        if not words or words[0] in ("comment", "obj_info"):
            continue
        if words[0] == "end_header":
            break
        if words[0] == "format":
            if len(words) != 3 or words[1] not in FORMATS:
                raise StreamError(
                    f"{name}: header line {line_no}: format must be one of {sorted(FORMATS)}"
                )
            fmt = words[1]
        elif words[0] == "element":
            try:
                elements.append((words[1], int(words[2]), []))
            except (IndexError, ValueError):
                raise StreamError(f"{name}: header line {line_no}: bad element line") from None
        elif words[0] == "property":
            if not elements:
                raise StreamError(f"{name}: header line {line_no}: property before any element")
            elements[-1][2].append(words[1:])
        else:
            raise StreamError(f"{name}: header line {line_no}: unknown keyword {words[0]!r}")
    if fmt is None:
        raise StreamError(f"{name}: header has no 'format' line")
    return fmt, elements


def read_ply(src: str | Path | BinaryIO) -> Cloud:
    """Read the vertices of a PLY file: ``x y z`` and, when present, ``red green blue`` (uchar,
    as colours in [0, 1]) and ``nx ny nz``. Other vertex properties are ignored and logged."""
    try:
        with _binary(src, "rb") as (handle, name):
            fmt, elements = _parse_header(handle, name)
            if not elements or elements[0][0] != "vertex":
                raise StreamError(f"{name}: the first element must be 'vertex'")
            _, count, props = elements[0]
            fields = []
            for prop in props:
                if prop[0] == "list":
                    raise StreamError(
                        f"{name}: list property {prop[-1]!r} on vertices is not supported"
                    )
                if len(prop) != 2 or prop[0] not in PLY_TYPES:
                    raise StreamError(
                        f"{name}: vertex property {' '.join(prop)!r} has an unknown type"
                    )
                fields.append((prop[1], PLY_TYPES[prop[0]]))
            names = [f[0] for f in fields]
            for axis in "xyz":
                if axis not in names:
                    raise StreamError(f"{name}: vertex property {axis!r} is missing")
            order = FORMATS[fmt]
            color_types = {n: t for n, t in fields if n in ("red", "green", "blue")}
            if any(t != "u1" for t in color_types.values()):
                raise StreamError(f"{name}: colour properties must be uchar, found {color_types}")
            dtype = np.dtype([(n, (order or "<") + t) for n, t in fields])
            if order is None:
                rows = []
                for i in range(count):
                    line = handle.readline()
                    values = line.split()
                    if len(values) < len(fields):
                        raise StreamError(
                            f"{name}: vertex {i}: {len(values)} values, expected {len(fields)}"
                            + (" (file truncated)" if not line else "")
                        )
                    rows.append(tuple(float(v) for v in values[: len(fields)]))
                data = np.array(rows, dtype=[(n, "f8") for n in names]) if rows else None
            else:
                blob = handle.read(dtype.itemsize * count)
                if len(blob) != dtype.itemsize * count:
                    raise StreamError(
                        f"{name}: {count} vertices need {dtype.itemsize * count} bytes, "
                        f"found {len(blob)} (file truncated)"
                    )
                data = np.frombuffer(blob, dtype=dtype, count=count)
    except FileNotFoundError:
        raise StreamError(f"{src}: file is missing") from None
    except ValueError as err:
        raise StreamError(f"{src}: not a number in the vertex data ({err})") from None
    if data is None:
        _log_ignored(name, [n for n in names if n not in "xyz"])
        return Cloud(np.zeros((0, 3)))
    points = np.column_stack([data[a].astype(np.float64) for a in "xyz"])
    colors = normals = None
    color_names, normal_names = ("red", "green", "blue"), ("nx", "ny", "nz")
    if all(c in names for c in color_names):
        values = np.column_stack([data[c] for c in color_names])
        if np.any(values < 0) or np.any(values > 255) or np.any(values % 1):
            raise StreamError(f"{name}: colours must be integers 0..255")
        colors = values.astype(np.uint8) / 255.0
    if all(c in names for c in normal_names):
        normals = np.column_stack([data[c].astype(np.float64) for c in normal_names])
    used = (
        "x", "y", "z",
        *(color_names if colors is not None else ()),
        *(normal_names if normals is not None else ()),
    )  # fmt: skip
    _log_ignored(name, [n for n in names if n not in used])
    try:
        return Cloud(points, colors, normals)
    except RecordError as err:
        raise StreamError(f"{name}: {err}") from None


def _log_ignored(name: str, ignored: list[str]) -> None:
    if ignored:
        logger.info("%s: vertex properties ignored: %s", name, ", ".join(ignored))

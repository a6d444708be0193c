"""Low-level readers and writers of the session's files: strict PNG, CSV streams, TUM poses.

Every reader takes the path it reads and names it, with the row (data row, 0-based, and the
file's line number) and the rule, in each error. Nothing is repaired: a bad sample is an error.
Every ``read_x`` has a ``write_x``.
"""

from __future__ import annotations

import io
import math
import warnings
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import TextIO

import numpy as np

from graph_slam.errors import ImageError, NonFiniteError, StreamError, TimestampError

# --------------------------------------------------------------------------- PNG


def read_png(
    path: Path, *, expect_mode: str, expect_hw: tuple[int, int] | None = None
) -> np.ndarray:
    """Decode a PNG strictly: a missing, corrupt or truncated file is an :class:`ImageError`.

    ``expect_mode`` is ``"depth16"`` (16-bit grayscale → uint16 H×W) or ``"rgb8"``
    (→ uint8 H×W×3). The chunk structure and CRCs are verified before decoding, so a file cut
    anywhere (even in its last bytes) is rejected instead of being zero-filled.
    """
    from PIL import Image, UnidentifiedImageError

    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise ImageError(f"{path}: image file is missing") from None
    except OSError as err:
        raise ImageError(f"{path}: cannot read image ({err.strerror})") from None
    try:
        with Image.open(io.BytesIO(data)) as probe:
            if probe.format != "PNG":
                raise ImageError(f"{path}: not a PNG file (found {probe.format})")
            probe.verify()
        with Image.open(io.BytesIO(data)) as img:
            img.load()
            mode = img.mode
            if expect_mode == "depth16":
                if mode not in ("I;16", "I;16B", "I;16L"):
                    raise ImageError(
                        f"{path}: depth PNG must be 16-bit grayscale, found mode {mode!r}"
                    )
                array = np.array(img, dtype=np.uint16)
            elif expect_mode == "rgb8":
                if mode != "RGB":
                    raise ImageError(f"{path}: colour PNG must be 8-bit RGB, found mode {mode!r}")
                array = np.array(img, dtype=np.uint8)
            else:  # pragma: no cover - programming error
                raise ValueError(f"unknown expect_mode {expect_mode!r}")
    except ImageError:
        raise
    except (UnidentifiedImageError, OSError, SyntaxError, ValueError) as err:
        raise ImageError(f"{path}: corrupt or truncated PNG ({err})") from None
    if expect_hw is not None and array.shape[:2] != expect_hw:
        raise ImageError(
            f"{path}: image is {array.shape[1]}×{array.shape[0]} px (W×H) but the intrinsics say "
            f"{expect_hw[1]}×{expect_hw[0]}"
        )
    return array


def write_png(path: Path, array: np.ndarray, *, compress_level: int = 1) -> None:
    """Write uint16 H×W (16-bit grayscale) or uint8 H×W×3 (RGB) as PNG
    (:func:`graph_slam.session.png.encode_png`)."""
    from graph_slam.session.png import encode_png

    Path(path).write_bytes(encode_png(array, compress_level))


# --------------------------------------------------------------------------- CSV


MAX_ABS_TIME_S = 1e10
"""Largest plausible timestamp magnitude (s): about 317 years, past any Unix time in seconds."""


def _line_of(row: int) -> int:
    """File line number (1-based) of data row ``row`` (0-based) in a file with one header line."""
    return row + 2


@contextmanager
def text_errors(path: Path) -> Iterator[None]:
    """A text file that is not UTF-8 (or a binary file) becomes a :class:`StreamError`."""
    try:
        yield
    except UnicodeDecodeError as err:
        raise StreamError(
            f"{path}: not UTF-8 text (byte {err.start} cannot be decoded); streams are CSV text"
        ) from None


def read_header(path: Path, columns: Sequence[str]) -> None:
    """Check that the first line of ``path`` is exactly the expected comma-separated header."""
    try:
        with path.open("r", encoding="utf-8") as handle:
            header = handle.readline().strip()
    except FileNotFoundError:
        raise StreamError(f"{path}: file is missing") from None
    except (OSError, UnicodeDecodeError) as err:
        raise StreamError(f"{path}: cannot read ({err})") from None
    found = [c.strip() for c in header.split(",")] if header else []
    if found != list(columns):
        raise StreamError(f"{path}: header must be {','.join(columns)!r}, found {header!r}")


def read_numeric_csv(path: Path, columns: Sequence[str]) -> np.ndarray:
    """Read a numeric CSV with exactly ``columns`` (header line required) into N×C float64.

    Errors: a wrong header, a row with the wrong number of fields or a non-number (named by row
    and column), NaN or inf (:class:`NonFiniteError`, with the count and the first row).
    """
    read_header(path, columns)
    with text_errors(path):
        return _read_numeric_rows(path, columns)


def _read_numeric_rows(path: Path, columns: Sequence[str]) -> np.ndarray:
    try:
        with warnings.catch_warnings():  # a header-only file: counted by the caller, not warned
            warnings.filterwarnings("ignore", "loadtxt: input contained no data")
            data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2, dtype=np.float64)
    except ValueError:
        _raise_first_bad_row(path, columns)
        raise  # pragma: no cover - _raise_first_bad_row always raises
    if data.size == 0:
        data = np.zeros((0, len(columns)))
    if data.shape[1] != len(columns):
        raise StreamError(f"{path}: rows must have {len(columns)} fields, found {data.shape[1]}")
    bad = ~np.isfinite(data)
    if bad.any():
        rows = np.flatnonzero(bad.any(axis=1))
        col = columns[int(np.flatnonzero(bad[rows[0]])[0])]
        raise NonFiniteError(
            f"{path}: {rows.size} row(s) hold NaN or inf; first at data row {rows[0]} "
            f"(line {_line_of(int(rows[0]))}), column {col!r}; every value must be finite"
        )
    return data


def _raise_first_bad_row(path: Path, columns: Sequence[str]) -> None:
    with path.open("r", encoding="utf-8") as handle:
        next(handle)
        for row, line in enumerate(handle):
            fields = line.strip().split(",")
            if fields == [""]:
                raise StreamError(f"{path}: data row {row} (line {_line_of(row)}) is empty")
            if len(fields) != len(columns):
                raise StreamError(
                    f"{path}: data row {row} (line {_line_of(row)}) has {len(fields)} fields, "
                    f"the header has {len(columns)}"
                )
            for name, text in zip(columns, fields, strict=True):
                try:
                    float(text)
                except ValueError:
                    raise StreamError(
                        f"{path}: data row {row} (line {_line_of(row)}), column {name!r}: "
                        f"{text!r} is not a number"
                    ) from None
    raise StreamError(f"{path}: cannot parse as CSV")  # pragma: no cover


def check_times(path: Path, t_s: np.ndarray, column: str = "t_s") -> None:
    """Timestamps must be seconds below :data:`MAX_ABS_TIME_S` in magnitude and strictly
    increasing: count the offenders, name the first row."""
    big = np.flatnonzero(np.abs(t_s) > MAX_ABS_TIME_S)
    if big.size:
        first = int(big[0])
        raise TimestampError(
            f"{path}: column {column!r}: {big.size} value(s) beyond ±{MAX_ABS_TIME_S:g} s, first "
            f"at data row {first} (line {_line_of(first)}): {float(t_s[first])!r}; times must "
            "be seconds (nanoseconds? divide by 1e9)"
        )
    if t_s.size < 2:
        return
    step = np.diff(t_s)
    bad = np.flatnonzero(step <= 0.0) + 1
    if bad.size:
        dup = int(np.count_nonzero(step == 0.0))
        first = int(bad[0])
        raise TimestampError(
            f"{path}: column {column!r} must be strictly increasing; {bad.size} offending row(s) "
            f"({dup} duplicate, {bad.size - dup} going back), first at data row {first} "
            f"(line {_line_of(first)}): {float(t_s[first - 1])!r} then {float(t_s[first])!r}"
        )


def write_numeric_csv(path: Path, columns: Sequence[str], data: np.ndarray) -> None:
    """Write N×C floats with a header; ``repr``-exact (17 significant digits)."""
    data = np.asarray(data, dtype=np.float64).reshape(-1, len(columns))
    with path.open("w", encoding="utf-8", newline="\n") as handle:
        handle.write(",".join(columns) + "\n")
        np.savetxt(handle, data, delimiter=",", fmt="%.17g")


# --------------------------------------------------------------------------- TUM poses


def _quat_xyzw_from_matrix(rot: np.ndarray) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    return Rotation.from_matrix(rot).as_quat()  # x, y, z, w


def write_tum(path: Path | TextIO, t_s: np.ndarray, parent_T_child: np.ndarray) -> None:
    """TUM trajectory format: ``t tx ty tz qx qy qz qw`` per line, ``#`` comment header.

    ``path`` is a file path or an open text file.
    """
    quats = _quat_xyzw_from_matrix(parent_T_child[:, :3, :3]) if len(t_s) else np.zeros((0, 4))
    if not isinstance(path, Path | str):
        _write_tum_rows(path, t_s, parent_T_child, quats)
        return
    with Path(path).open("w", encoding="utf-8", newline="\n") as handle:
        _write_tum_rows(handle, t_s, parent_T_child, quats)


def _write_tum_rows(
    handle: TextIO, t_s: np.ndarray, parent_T_child: np.ndarray, quats: np.ndarray
) -> None:
    handle.write("# timestamp tx ty tz qx qy qz qw\n")
    for t, pose, q in zip(t_s, parent_T_child, quats, strict=True):
        x, y, z = pose[:3, 3]
        handle.write(
            f"{t:.9f} {x:.9f} {y:.9f} {z:.9f} {q[0]:.9f} {q[1]:.9f} {q[2]:.9f} {q[3]:.9f}\n"
        )


def read_text(
    path: Path,
    missing: type[Exception] = StreamError,
    unreadable: type[Exception] = StreamError,
) -> str:
    """The UTF-8 text of ``path``; ``missing`` when the file is absent, ``unreadable`` for any
    other OS or decoding error, each naming the path."""
    try:
        return path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise missing(f"{path}: file is missing") from None
    except (OSError, UnicodeDecodeError) as err:
        raise unreadable(f"{path}: cannot read ({err})") from None


def read_tum(path: Path | TextIO) -> tuple[np.ndarray, np.ndarray]:
    """Read a TUM trajectory file → (t_s, N×4×4). Quaternions are normalised only if their
    norm is within 1e-3 of one; otherwise the row is an error (nothing silently repaired).

    ``path`` is a file path or an open text file (named in errors by its ``name``).
    """
    from scipy.spatial.transform import Rotation

    if isinstance(path, Path | str):
        path = Path(path)
        lines = read_text(path).splitlines()
    else:
        lines = path.read().splitlines()
        path = Path(str(getattr(path, "name", "<stream>")))
    rows: list[list[float]] = []
    for line_no, line in enumerate(lines, start=1):
        text = line.strip()
        if not text or text.startswith("#"):
            continue
        fields = text.replace(",", " ").split()
        if len(fields) != 8:
            raise StreamError(
                f"{path}: line {line_no}: TUM rows must have 8 entries "
                f"(t tx ty tz qx qy qz qw), found {len(fields)}"
            )
        try:
            values = [float(f) for f in fields]
        except ValueError:
            raise StreamError(f"{path}: line {line_no}: not all entries are numbers") from None
        if not all(math.isfinite(v) for v in values):
            raise NonFiniteError(f"{path}: line {line_no}: NaN or inf; every value must be finite")
        norm = math.sqrt(sum(v * v for v in values[4:]))
        if abs(norm - 1.0) > 1e-3:
            raise StreamError(
                f"{path}: line {line_no}: quaternion norm {norm:.6f} is not 1 (tolerance 1e-3)"
            )
        rows.append(values)
    data = np.array(rows, dtype=np.float64).reshape(-1, 8)
    poses = np.tile(np.eye(4), (data.shape[0], 1, 1))
    if data.shape[0]:
        poses[:, :3, :3] = Rotation.from_quat(data[:, 4:8]).as_matrix()
        poses[:, :3, 3] = data[:, 1:4]
    check_times(path, data[:, 0], column="timestamp")
    return data[:, 0].copy(), poses

"""Trajectories in the formats evaluation tools read: TUM and KITTI (read/write pairs).

- TUM: ``t tx ty tz qx qy qz qw`` per line (seconds, metres, Hamilton quaternion, w last).
- KITTI: 12 numbers per line, the first three rows of ``parent_T_child`` row by row; no time
  (KITTI keeps stamps in a separate ``times.txt``, one per line: ``times=`` on both sides).

Every function takes a path or an open text file. Rotations read from KITTI files (often
written with ~7 significant digits) are accepted when within 1e-4 of orthonormal and are then
projected onto SO(3) (SVD); the count of projected rows is logged. Worse rows are errors.
"""

from __future__ import annotations

import logging
from contextlib import contextmanager
from pathlib import Path
from typing import TextIO

import numpy as np

from graph_slam.errors import RecordError, StreamError
from graph_slam.session import io
from graph_slam.session.records import PoseTrajectory

logger = logging.getLogger(__name__)

#: A KITTI rotation further than this from orthonormal (max |RᵀR − I|, |det − 1|) is an error.
KITTI_ORTHONORMAL_TOL = 1e-4
#: Below this, a rotation is taken as it is (the records' own rigidity tolerance).
_EXACT_TOL = 1e-6


@contextmanager
def _text(target: str | Path | TextIO, mode: str):
    if isinstance(target, str | Path):
        with Path(target).open(mode, encoding="utf-8", newline="\n" if mode == "w" else None) as f:
            yield f, str(target)
    else:
        yield target, str(getattr(target, "name", "<stream>"))


def write_trajectory_tum(trajectory: PoseTrajectory, dest: str | Path | TextIO) -> None:
    """Write ``parent_T_child`` with its stamps in TUM format (9 decimals)."""
    io.write_tum(
        dest if not isinstance(dest, str) else Path(dest),
        trajectory.t_s,
        trajectory.parent_T_child,
    )


def read_trajectory_tum(
    src: str | Path | TextIO, *, parent: str = "world", child: str = "camera"
) -> PoseTrajectory:
    """Read a TUM trajectory (``#`` comments; 8 fields; quaternion norm within 1e-3)."""
    t_s, poses = io.read_tum(src if not isinstance(src, str) else Path(src))
    try:
        return PoseTrajectory(t_s, poses, parent=parent, child=child)
    except RecordError as err:
        raise StreamError(f"{getattr(src, 'name', src)}: {err}") from None


def write_trajectory_kitti(
    trajectory: PoseTrajectory,
    dest: str | Path | TextIO,
    *,
    times: str | Path | TextIO | None = None,
) -> None:
    """Write the 3×4 top of each pose, row-major, 17 significant digits; stamps to ``times``."""
    with _text(dest, "w") as (handle, _):
        for pose in trajectory.parent_T_child:
            handle.write(" ".join(f"{v:.17g}" for v in pose[:3, :4].ravel()) + "\n")
    if times is not None:
        with _text(times, "w") as (handle, _):
            for t in trajectory.t_s:
                handle.write(f"{t:.9f}\n")


def _read_rows(src: str | Path | TextIO, width: int, what: str) -> tuple[np.ndarray, str]:
    try:
        with _text(src, "r") as (handle, name):
            lines = handle.read().splitlines()
    except FileNotFoundError:
        raise StreamError(f"{src}: file is missing") from None
    rows: list[list[float]] = []
    for line_no, line in enumerate(lines, start=1):
        text = line.strip()
        if not text:
            continue
        fields = text.split()
        if len(fields) != width:
            raise StreamError(
                f"{name}: line {line_no}: {what} rows must have {width} entries, found {len(fields)}"
            )
        try:
            values = [float(f) for f in fields]
        except ValueError:
            raise StreamError(f"{name}: line {line_no}: not all entries are numbers") from None
        if not np.isfinite(values).all():
            raise StreamError(f"{name}: line {line_no}: NaN or inf; every value must be finite")
        rows.append(values)
    return np.asarray(rows, dtype=np.float64).reshape(-1, width), name


def read_trajectory_kitti(
    src: str | Path | TextIO,
    *,
    times: str | Path | TextIO | np.ndarray | None = None,
    parent: str = "world",
    child: str = "camera",
) -> PoseTrajectory:
    """Read a KITTI pose file. ``times``: a times file, an array, or None (then ``t_s`` is the
    row index 0, 1, 2, … — KITTI pose files carry no time)."""
    data, name = _read_rows(src, 12, "KITTI")
    poses = np.tile(np.eye(4), (data.shape[0], 1, 1))
    poses[:, :3, :4] = data.reshape(-1, 3, 4)
    rot = poses[:, :3, :3]
    err = np.maximum(
        np.abs(np.einsum("nji,njk->nik", rot, rot) - np.eye(3)).max(axis=(1, 2), initial=0.0),
        np.abs(np.linalg.det(rot) - 1.0) if rot.size else np.zeros(0),
    )
    bad = np.flatnonzero(err > KITTI_ORTHONORMAL_TOL)
    if bad.size:
        raise StreamError(
            f"{name}: line {int(bad[0]) + 1}: rotation is {err[bad[0]]:.2g} from orthonormal "
            f"(tolerance {KITTI_ORTHONORMAL_TOL}); {bad.size} row(s)"
        )
    fix = np.flatnonzero(err > _EXACT_TOL)
    if fix.size:
        u, _, vt = np.linalg.svd(rot[fix])
        poses[fix, :3, :3] = u @ vt
        logger.warning(
            "%s: %d rotation(s) within %g of orthonormal projected onto SO(3) (max error %.2g)",
            name,
            fix.size,
            KITTI_ORTHONORMAL_TOL,
            float(err[fix].max()),
        )
    if times is None:
        t_s = np.arange(data.shape[0], dtype=np.float64)
    elif isinstance(times, np.ndarray):
        t_s = np.asarray(times, dtype=np.float64)
    else:
        t_s = _read_rows(times, 1, "times")[0][:, 0]
    if t_s.size != data.shape[0]:
        raise StreamError(f"{name}: {data.shape[0]} poses but {t_s.size} times")
    try:
        return PoseTrajectory(t_s, poses, parent=parent, child=child)
    except RecordError as err_:
        raise StreamError(f"{name}: {err_}") from None

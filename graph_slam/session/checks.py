"""The rules every record checks on construction, shared by the records and their users.

A record that exists is well-formed: its arrays are float64 of the declared shape, finite and
read-only; its times strictly increase; its poses are rigid. Each check raises
:class:`RecordError` naming the record, the field and the rule.
"""

from __future__ import annotations

import numpy as np

from graph_slam.errors import RecordError
from kinematics.conversions import not_rigid

__all__ = ["check_increasing", "check_pose", "float_array", "frozen_array", "pose_array"]


def frozen_array(array: np.ndarray) -> np.ndarray:
    """``array`` contiguous and read-only."""
    array = np.ascontiguousarray(array)
    array.setflags(write=False)
    return array


def float_array(record: str, name: str, value: object, shape: tuple[int | None, ...]) -> np.ndarray:
    """Convert to float64 and check shape (``None`` = any length) and finiteness."""
    try:
        array = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise RecordError(f"{record}.{name}: not numeric ({err})") from None
    if array.ndim != len(shape) or any(
        want is not None and got != want for got, want in zip(array.shape, shape, strict=True)
    ):
        want_txt = "×".join("N" if s is None else str(s) for s in shape)
        raise RecordError(f"{record}.{name}: shape {array.shape} does not match {want_txt}")
    bad = ~np.isfinite(array)
    if bad.any():
        bad_rows = np.flatnonzero(bad.reshape(bad.shape[0], -1).any(axis=1)) if array.ndim else [0]
        raise RecordError(
            f"{record}.{name}: {len(bad_rows)} row(s) hold NaN or inf, first at row {bad_rows[0]}"
        )
    return frozen_array(array)


def check_increasing(record: str, t_s: np.ndarray) -> None:
    """Timestamps must strictly increase; report the count and the first offending row."""
    if t_s.size < 2:
        return
    bad = np.flatnonzero(np.diff(t_s) <= 0.0) + 1
    if bad.size:
        first = int(bad[0])
        kind = "duplicate" if t_s[first] == t_s[first - 1] else "decreasing"
        raise RecordError(
            f"{record}.t_s: {bad.size} timestamp(s) not strictly increasing, first at row {first} "
            f"({kind}: {float(t_s[first - 1])!r} then {float(t_s[first])!r})"
        )


def check_pose(record: str, name: str, pose: np.ndarray, tol: float = 1e-6) -> None:
    """A 4×4 (or N×4×4) homogeneous rigid transform: finite, orthonormal rotation with det +1,
    last row 0 0 0 1 (:func:`kinematics.conversions.not_rigid`)."""
    bad = np.flatnonzero(not_rigid(pose, tol))
    if bad.size:
        raise RecordError(
            f"{record}.{name}: {bad.size} transform(s) are not rigid (not finite, rotation not "
            f"orthonormal with det +1, or last row not 0 0 0 1), first at index {int(bad[0])}"
        )


def pose_array(record: str, name: str, value: object) -> np.ndarray:
    """A 4×4 rigid transform as a read-only float64 array (:func:`check_pose`)."""
    pose = float_array(record, name, value, (4, 4))
    check_pose(record, name, pose)
    return pose

"""Real thigh-IMU recordings for the gait detectors: Xsens MT text exports, reference events,
and the 24 right-handed axis arrangements used to test that a detector is mounting-blind.

:func:`read_xsens_txt` reads an Xsens MT Manager text export (``//`` header lines, then a tab
separated table with ``Counter`` or ``PacketCounter``, ``Acc_X..Z`` in m/s² and either
``Gyr_X..Z`` in rad/s or the orientation matrix ``Mat[i][j]``). Time is the counter divided by
the rate stated in the header (``Sample rate`` or ``Update Rate``), so dropped packets stay gaps.
Without a gyro, the angular velocity in the sensor frame is derived from consecutive
orientations, ``ω_k = Log(global_R_sensor_kᵀ · global_R_sensor_k+1) / Δt`` (the export lists the
matrix column by column: ``Mat[1][1], Mat[2][1], Mat[3][1], Mat[1][2], ...``), stamped at the
midpoint of the two samples and resampled to the sample times. :func:`read_xsens_orientation`
gives the orientation matrices themselves (a two-thigh walk's contact reference,
:mod:`kinematics.gait_two_legs`).
"""

from __future__ import annotations

import itertools
import re
from pathlib import Path

import numpy as np

from kinematics.errors import GaitInputError
from kinematics.imu import ImuSeries


def read_xsens_txt(path: str | Path) -> ImuSeries:
    """An Xsens MT text export as an :class:`ImuSeries` (see the module docstring)."""
    path = Path(path)
    t, accel, gyro, global_R_sensor = _read_xsens(path)
    if gyro is None:
        gyro = _gyro_from_orientation(t, global_R_sensor)
    return ImuSeries(t_s=t, gyro_rad_s=gyro, accel_m_s2=accel, source=str(path))


def read_xsens_orientation(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """``(t_s, global_R_sensor)`` of an Xsens MT text export with the orientation matrix
    (N×3×3; the same times as :func:`read_xsens_txt`)."""
    path = Path(path)
    t, _, _, global_R_sensor = _read_xsens(path, need_orientation=True)
    return t, global_R_sensor


def _read_xsens(path: Path, need_orientation: bool = False):
    """(t_s, accel, gyro or None, global_R_sensor or None) of an Xsens text export."""
    try:
        lines = path.read_text(encoding="utf-8", errors="strict").splitlines()
    except (OSError, UnicodeDecodeError) as err:
        raise GaitInputError(f"{path}: cannot read Xsens text export ({err})") from None
    body = next((i for i, line in enumerate(lines) if not line.startswith("//")), len(lines))
    rate = None
    for line in lines[:body]:
        found = re.search(r"(?:Sample rate|Update Rate):\s*([0-9.]+)\s*Hz", line)
        if found:
            rate = float(found.group(1))
    if body >= len(lines):
        raise GaitInputError(f"{path}: no table after the header lines")
    if rate is None or rate <= 0:
        raise GaitInputError(f"{path}: no 'Sample rate' or 'Update Rate' header line")
    header = lines[body].split("\t")
    header = [h.strip() for h in header]
    counter = next((c for c in ("Counter", "PacketCounter") if c in header), None)
    if counter is None:
        raise GaitInputError(f"{path}: line {body + 1}: no Counter or PacketCounter column")
    need = [counter, "Acc_X", "Acc_Y", "Acc_Z"]
    gyro_cols = ["Gyr_X", "Gyr_Y", "Gyr_Z"]
    mat_cols = [f"Mat[{i}][{j}]" for j in (1, 2, 3) for i in (1, 2, 3)]
    has_gyro = all(c in header for c in gyro_cols)
    has_mat = all(c in header for c in mat_cols)
    if need_orientation and not has_mat:
        raise GaitInputError(f"{path}: line {body + 1}: no orientation matrix Mat[i][j]")
    if not has_gyro and not has_mat:
        raise GaitInputError(
            f"{path}: line {body + 1}: need Gyr_X..Z or the orientation matrix Mat[i][j]"
        )
    cols = need + (gyro_cols if has_gyro else []) + (mat_cols if has_mat else [])
    index = [header.index(c) for c in cols]
    rows = []
    for line_no, line in enumerate(lines[body + 1 :], start=body + 2):
        if not line.strip():
            continue
        parts = line.split("\t")
        try:
            rows.append([float(parts[j]) for j in index])
        except (ValueError, IndexError):
            raise GaitInputError(
                f"{path}: line {line_no}: a value of {cols} is missing or not a number"
            ) from None
    data = np.asarray(rows, dtype=float)
    if data.shape[0] < 3:
        raise GaitInputError(f"{path}: fewer than 3 samples")
    t = (data[:, 0] - data[0, 0]) / rate
    accel = data[:, 1:4]
    gyro = data[:, 4:7] if has_gyro else None
    start = 7 if has_gyro else 4
    global_R_sensor = (
        data[:, start : start + 9].reshape(-1, 3, 3).transpose(0, 2, 1) if has_mat else None
    )
    return t, accel, gyro, global_R_sensor


def _gyro_from_orientation(t_s: np.ndarray, global_R_sensor: np.ndarray) -> np.ndarray:
    """Sensor-frame angular velocity from consecutive orientations (see the module docstring)."""
    from scipy.spatial.transform import Rotation

    r = Rotation.from_matrix(global_R_sensor)
    rel = (r[:-1].inv() * r[1:]).as_rotvec() / np.diff(t_s)[:, None]
    t_mid = 0.5 * (t_s[1:] + t_s[:-1])
    return np.column_stack([np.interp(t_s, t_mid, rel[:, i]) for i in range(3)])


def read_reference_strikes(path: str | Path) -> np.ndarray:
    """Foot-strike times of a ``t_s,kind`` reference file (``#`` comment lines allowed)."""
    path = Path(path)
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except OSError as err:
        raise GaitInputError(f"{path}: cannot read ({err.strerror})") from None
    out = []
    for line_no, line in enumerate(lines, start=1):
        if not line.strip() or line.startswith("#") or line.startswith("t_s"):
            continue
        t_text, _, kind = line.partition(",")
        if kind.strip() == "foot_strike":
            try:
                out.append(float(t_text))
            except ValueError:
                raise GaitInputError(
                    f"{path}: line {line_no}: {t_text!r} is not a number"
                ) from None
    return np.asarray(out)


def right_handed_arrangements() -> list[np.ndarray]:
    """The 24 signed permutation matrices with determinant +1 (every way to lay a sensor's
    axes along another right-handed frame's axes)."""
    out = []
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product((1.0, -1.0), repeat=3):
            m = np.zeros((3, 3))
            for row, (col, s) in enumerate(zip(perm, signs, strict=True)):
                m[row, col] = s
            if np.linalg.det(m) > 0:
                out.append(m)
    return out


def rearranged(imu: ImuSeries, new_R_old: np.ndarray) -> ImuSeries:
    """The same recording seen by a sensor whose axes are ``new_R_old`` times the old ones."""
    r = np.asarray(new_R_old, dtype=float)
    return ImuSeries(
        t_s=imu.t_s,
        gyro_rad_s=np.asarray(imu.gyro_rad_s) @ r.T,
        accel_m_s2=np.asarray(imu.accel_m_s2) @ r.T,
        source=imu.source,
    )

"""Gait recordings in and events out: the IMU CSV (strict reader, writer, the checks of a gait
recording) and the ``t_s,kind`` events CSV."""

from __future__ import annotations

import csv
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from kinematics.errors import GaitInputError
from kinematics.gait_event_config import EVENT_KINDS, DetectedEvents
from kinematics.imu import IMU_COLUMNS, LEGACY_IMU_COLUMNS, ImuSeries

MIN_RATE_HZ, MAX_RATE_HZ = 50.0, 1000.0
MAX_GYRO_RAD_S = 35.0  # 2000 deg/s: the largest common MEMS range
MAX_ACCEL_M_S2 = 16 * 9.81


def read_imu_csv(path: str | Path) -> ImuSeries:
    """Read an IMU CSV strictly: header :data:`~kinematics.imu.IMU_COLUMNS` (the session
    format's ``imu.csv``) or the unit-less :data:`~kinematics.imu.LEGACY_IMU_COLUMNS`, any
    column order; s, rad/s, m/s².

    Errors (:class:`GaitInputError`) name the file, the line, the column (as the file names
    it) and the rule.
    """
    path = Path(path)
    try:
        fh = path.open(newline="", encoding="utf-8")
    except OSError as err:
        raise GaitInputError(f"{path}: cannot read IMU CSV ({err.strerror})") from None
    try:
        with fh:
            return _read_imu_rows(path, csv.reader(fh))
    except UnicodeDecodeError as err:
        raise GaitInputError(
            f"{path}: not a UTF-8 text CSV (byte {err.start} cannot be decoded); expected "
            f"header {','.join(IMU_COLUMNS)}"
        ) from None


def _read_imu_rows(path: Path, reader) -> ImuSeries:
    """The header and rows of :func:`read_imu_csv` (``reader``: a csv.reader)."""
    try:
        header = [h.strip() for h in next(reader)]
    except StopIteration:
        raise GaitInputError(f"{path}: empty file (need header {','.join(IMU_COLUMNS)})") from None
    # the schema the header is closest to names what is missing
    columns = max((IMU_COLUMNS, LEGACY_IMU_COLUMNS), key=lambda cols: len(set(cols) & set(header)))
    missing = [c for c in columns if c not in header]
    extra = [c for c in header if c not in columns]
    if missing or extra or len(header) != len(columns):
        raise GaitInputError(
            f"{path}: line 1: header must be exactly {','.join(IMU_COLUMNS)} (or the "
            f"legacy {','.join(LEGACY_IMU_COLUMNS)}), any order; missing {missing}, "
            f"unexpected {extra}"
        )
    index = [header.index(c) for c in columns]
    rows: list[list[float]] = []
    for line_no, row in enumerate(reader, start=2):
        if not row or all(not x.strip() for x in row):
            continue
        if len(row) != len(header):
            raise GaitInputError(
                f"{path}: line {line_no}: has {len(row)} fields, the header has {len(header)}"
            )
        values = []
        for col, j in zip(columns, index, strict=True):
            text = row[j].strip()
            try:
                value = float(text)
            except ValueError:
                raise GaitInputError(
                    f"{path}: line {line_no}, column {col}: {text!r} is not a number"
                ) from None
            if not math.isfinite(value):
                raise GaitInputError(
                    f"{path}: line {line_no}, column {col}: {text!r} is not finite "
                    "(NaN/inf samples are not allowed; drop or mark them upstream)"
                )
            values.append(value)
        rows.append(values)
    data = np.asarray(rows, dtype=float).reshape(-1, len(columns))
    imu = ImuSeries(
        t_s=data[:, 0], gyro_rad_s=data[:, 1:4], accel_m_s2=data[:, 4:7], source=str(path)
    )
    validate_imu(imu, first_line=2, columns=columns)
    return imu


def validate_imu(
    imu: ImuSeries, first_line: int | None = None, columns: Sequence[str] = IMU_COLUMNS
) -> float:
    """Check an IMU series (shapes, finite, time, rate 50-1000 Hz, ranges); return its rate.

    ``first_line``: file line of sample 0, to name lines in messages (else sample indices);
    ``columns``: the names of t, gyro x/y/z, accel x/y/z in messages.
    """

    def where(k: int) -> str:
        return f"line {k + first_line}" if first_line is not None else f"sample {k}"

    src = imu.source
    t, g, a = (np.asarray(x, dtype=float) for x in (imu.t_s, imu.gyro_rad_s, imu.accel_m_s2))
    if t.ndim != 1 or g.shape != (t.size, 3) or a.shape != (t.size, 3):
        raise GaitInputError(f"{src}: need t_s (N,), gyro (N, 3), accel (N, 3)")
    if t.size < 2:
        raise GaitInputError(f"{src}: need at least 2 samples, got {t.size}")
    for first, arr in ((0, t[:, None]), (1, g), (4, a)):
        bad = ~np.isfinite(arr)
        if bad.any():
            k, j = np.argwhere(bad)[0]
            col = columns[first + j]
            raise GaitInputError(f"{src}: {where(int(k))}, column {col}: not finite")
    dt = np.diff(t)
    if np.any(dt <= 0):
        k = int(np.flatnonzero(dt <= 0)[0]) + 1
        raise GaitInputError(f"{src}: {where(k)}, column t_s: time must increase strictly")
    rate = 1.0 / float(np.median(dt))
    if not MIN_RATE_HZ * 0.95 <= rate <= MAX_RATE_HZ * 1.05:
        raise GaitInputError(
            f"{src}: column t_s: median sample rate {rate:.1f} Hz is outside "
            f"{MIN_RATE_HZ:.0f}-{MAX_RATE_HZ:.0f} Hz (are the times in seconds?)"
        )
    gaps = np.flatnonzero(dt > 5.0 / rate)
    if gaps.size:
        k = int(gaps[0]) + 1
        raise GaitInputError(
            f"{src}: {where(k)}, column t_s: gap of {dt[k - 1]:.3f} s (more than 5 sample "
            "periods); split the recording at gaps"
        )
    for first, arr, limit, unit in (
        (1, g, MAX_GYRO_RAD_S, "rad/s"),
        (4, a, MAX_ACCEL_M_S2, "m/s²"),
    ):
        big = np.abs(arr) > limit
        if big.any():
            k, j = np.argwhere(big)[0]
            raise GaitInputError(
                f"{src}: {where(int(k))}, column {columns[first + j]}: {arr[k, j]:.4g} exceeds the "
                f"plausible range ±{limit:.4g} {unit} (units must be rad/s and m/s²)"
            )
    return rate


def write_imu_csv(path: str | Path, imu: ImuSeries) -> Path:
    """Write an IMU series with the header :data:`~kinematics.imu.IMU_COLUMNS` (the session
    format's ``imu.csv``), as :func:`read_imu_csv` reads it."""
    path = Path(path)
    data = np.column_stack([imu.t_s, imu.gyro_rad_s, imu.accel_m_s2])
    with path.open("w", newline="", encoding="utf-8") as fh:
        fh.write(",".join(IMU_COLUMNS) + "\n")
        for row in data:
            fh.write(f"{row[0]:.6f}," + ",".join(f"{x:.6g}" for x in row[1:]) + "\n")
    return path


def write_events_csv(path: str | Path, events: DetectedEvents) -> Path:
    """Write ``t_s,kind`` rows sorted by time."""
    path = Path(path)
    with path.open("w", newline="", encoding="utf-8") as fh:
        fh.write("t_s,kind\n")
        for t, kind in events.rows():
            fh.write(f"{t:.6f},{kind}\n")
    return path


def read_events_csv(path: str | Path) -> dict[str, np.ndarray]:
    """Read ``t_s,kind`` rows: ``{"foot_strike": times, "toe_off": times}``."""
    path = Path(path)
    out: dict[str, list[float]] = {k: [] for k in EVENT_KINDS}
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except OSError as err:
        raise GaitInputError(f"{path}: cannot read events CSV ({err.strerror})") from None
    if not lines or lines[0].strip() != "t_s,kind":
        raise GaitInputError(f"{path}: line 1: header must be 't_s,kind'")
    for line_no, line in enumerate(lines[1:], start=2):
        if not line.strip():
            continue
        t_text, _, kind = line.partition(",")
        kind = kind.strip()
        if kind not in out:
            raise GaitInputError(
                f"{path}: line {line_no}, column kind: {kind!r} is not one of {EVENT_KINDS}"
            )
        try:
            t = float(t_text)
        except ValueError:
            raise GaitInputError(
                f"{path}: line {line_no}, column t_s: {t_text!r} is not a number"
            ) from None
        if not math.isfinite(t):
            raise GaitInputError(f"{path}: line {line_no}, column t_s: not finite")
        out[kind].append(t)
    return {k: np.asarray(v) for k, v in out.items()}

"""Prosthesis controller logs: a CSV of joint angles and either gait events or a load cell.

The column mapping is part of the conversion config (``prosthesis_log:`` in the YAML)::

    prosthesis_log:
      time: {column: time_ms, unit: ms}
      time_offset_s: null                # added to the log's times (to the camera clock);
                                         # null: estimated from foot strikes when merged
      knee: {column: knee_deg, unit: deg, scale: 1.0, offset: 0.0}   # rad = to_rad(v*scale+offset)
      ankle: {column: ankle_deg, unit: deg, scale: -1.0}              # a sign flip
      events: {column: event, values: {HS: foot_strike, TO: toe_off}, ignore: [MS]}
      # or, instead of events, a load cell (hysteresis thresholds in newtons):
      # load: {column: load_raw, scale: 0.5, foot_strike_above_n: 50, toe_off_below_n: 20}

A log on its own converts into a session without a camera (joints and events); with
``prosthesis_log.path`` set it is merged into the conversion of a bag or TUM folder.
Load-cell events are placed at the linearly interpolated crossing time of the threshold.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from graph_slam.errors import ConversionError, MissingStreamError
from graph_slam.session.adapters.base import ConversionReport, Recording, StreamReport
from graph_slam.session.adapters.config import (
    AngleColumn,
    ConvertConfig,
    LoadColumn,
    ProsthesisLogConfig,
)
from graph_slam.session.adapters.log_checks import (
    TIME_UNITS_S,
    check_clock,
    check_joint_units,
    check_load,
)
from graph_slam.session.adapters.timing import order_stamps
from graph_slam.session.records import GaitEvents, JointSeries


def _read_table(path: Path, delimiter: str) -> tuple[list[str], list[list[str]]]:
    try:
        with path.open("r", encoding="utf-8", newline="") as handle:
            rows = list(csv.reader(handle, delimiter=delimiter))
    except FileNotFoundError:
        raise MissingStreamError(f"{path}: prosthesis log is missing") from None
    except (OSError, UnicodeDecodeError, csv.Error) as err:
        raise ConversionError(f"{path}: cannot read as CSV ({err})") from None
    if not rows:
        raise ConversionError(f"{path}: empty file; the first line must be the column names")
    header = [h.strip() for h in rows[0]]
    body = [r for r in rows[1:] if any(c.strip() for c in r)]
    return header, body


def _column(path: Path, header: list[str], name: str, field: str) -> int:
    if name not in header:
        raise MissingStreamError(
            f"{path}: column {name!r} (prosthesis_log.{field}) not found; columns: {header}"
        )
    return header.index(name)


def _numbers(path: Path, body: list[list[str]], col: int, name: str) -> np.ndarray:
    out = np.empty(len(body), dtype=np.float64)
    for row, fields in enumerate(body):
        text = fields[col].strip() if col < len(fields) else ""
        try:
            out[row] = float(text)
        except ValueError:
            raise ConversionError(
                f"{path}: data row {row} (line {row + 2}), column {name!r}: {text!r} is not a number"
            ) from None
    return out


def _angle_rad(path: Path, values: np.ndarray, spec: AngleColumn, joint: str) -> np.ndarray:
    scaled = values * spec.scale + spec.offset
    check_joint_units(path, scaled, spec.unit, joint)
    return np.deg2rad(scaled) if spec.unit == "deg" else scaled


def load_cell_events(
    t_s: np.ndarray, load_n: np.ndarray, spec: LoadColumn
) -> tuple[np.ndarray, tuple[str, ...]]:
    """Foot strikes (load rises through ``foot_strike_above_n``) and toe-offs (falls through
    ``toe_off_below_n``), hysteresis between them; crossing times interpolated linearly.
    The state at the first sample is taken from its load; no event is made for it."""
    times: list[float] = []
    kinds: list[str] = []
    if load_n.size == 0:
        return np.zeros(0), ()
    stance = bool(load_n[0] >= spec.foot_strike_above_n)
    for i in range(1, load_n.size):
        a, b = load_n[i - 1], load_n[i]
        if not stance and b >= spec.foot_strike_above_n:
            thr, kind, stance = spec.foot_strike_above_n, "foot_strike", True
        elif stance and b < spec.toe_off_below_n:
            thr, kind, stance = spec.toe_off_below_n, "toe_off", False
        else:
            continue
        frac = 1.0 if b == a else float(np.clip((thr - a) / (b - a), 0.0, 1.0))
        times.append(float(t_s[i - 1] + frac * (t_s[i] - t_s[i - 1])))
        kinds.append(kind)
    return np.asarray(times, dtype=np.float64), tuple(kinds)


def read_prosthesis_log(
    path: Path, spec: ProsthesisLogConfig
) -> tuple[JointSeries, GaitEvents | None, list[StreamReport]]:
    """Read a controller log with its column mapping → joints, events (or None), reports."""
    header, body = _read_table(path, spec.delimiter)
    t_col = _column(path, header, spec.time.column, "time.column")
    k_col = _column(path, header, spec.knee.column, "knee.column")
    a_col = _column(path, header, spec.ankle.column, "ankle.column")
    t_s = _numbers(path, body, t_col, spec.time.column) * TIME_UNITS_S[spec.time.unit]
    check_clock(path, t_s, spec.time.column)
    t_s = t_s + (spec.time_offset_s or 0.0)  # None (estimate it later) reads on the log's clock
    knee = _angle_rad(path, _numbers(path, body, k_col, spec.knee.column), spec.knee, "knee")
    ankle = _angle_rad(path, _numbers(path, body, a_col, spec.ankle.column), spec.ankle, "ankle")
    finite = np.isfinite(t_s) & np.isfinite(knee) & np.isfinite(ankle)
    order = order_stamps(t_s[finite])
    kept = np.flatnonzero(finite)[order.keep]
    joints_report = StreamReport(
        "joints",
        f"{path.name} [{spec.knee.column}, {spec.ankle.column}]",
        len(body),
        kept.size,
        {"NaN or inf": int((~finite).sum()), "duplicate stamp": order.duplicates},
    )
    if order.reordered:
        joints_report.notes.append(f"{order.reordered} row(s) out of time order, sorted")
    joints = JointSeries(t_s[kept], knee[kept], ankle[kept])
    reports = [joints_report]

    events = None
    if spec.events is not None:
        e_col = _column(path, header, spec.events.column, "events.column")
        raw = [(r[e_col].strip() if e_col < len(r) else "") for r in body]
        marked = [i for i, v in enumerate(raw) if v]
        dropped: dict[str, int] = {}
        ev_t: list[float] = []
        ev_kind: list[str] = []
        for i in marked:
            value = raw[i]
            if value in spec.events.values and np.isfinite(t_s[i]):
                ev_t.append(float(t_s[i]))
                ev_kind.append(spec.events.values[value])
            elif value in spec.events.ignore:
                dropped["ignored value"] = dropped.get("ignored value", 0) + 1
            elif value in spec.events.values:
                dropped["time not finite"] = dropped.get("time not finite", 0) + 1
            else:
                key = f"unmapped value {value!r}"
                dropped[key] = dropped.get(key, 0) + 1
        ev_times = np.asarray(ev_t, dtype=np.float64)
        ev_order = order_stamps(ev_times)
        if ev_order.duplicates:
            dropped["duplicate stamp"] = ev_order.duplicates
        report = StreamReport(
            "events",
            f"{path.name} [{spec.events.column}]",
            len(marked),
            ev_order.keep.size,
            dropped,
        )
        reports.append(report)
        events = GaitEvents(
            ev_times[ev_order.keep],
            tuple(ev_kind[i] for i in ev_order.keep),
            (spec.events_source or "log",) * ev_order.keep.size,
        )
    elif spec.load is not None:
        l_col = _column(path, header, spec.load.column, "load.column")
        load_n = _numbers(path, body, l_col, spec.load.column) * spec.load.scale
        check_load(path, load_n, spec.load.column, spec.load.scale)
        ok = finite & np.isfinite(load_n)
        ok_idx = np.flatnonzero(ok)[order_stamps(t_s[ok]).keep]
        ev_times, kinds = load_cell_events(t_s[ok_idx], load_n[ok_idx], spec.load)
        reports.append(
            StreamReport(
                "events",
                f"{path.name} [{spec.load.column}] load-cell thresholds "
                f"{spec.load.foot_strike_above_n:g}/{spec.load.toe_off_below_n:g} N",
                ev_times.size,
                ev_times.size,
                notes=[f"detected from {ok_idx.size} load sample(s)"],
            )
        )
        events = GaitEvents(ev_times, kinds, (spec.events_source or "load_cell",) * len(kinds))
    return joints, events, reports


class ProsthesisLogAdapter:
    """A prosthesis controller's CSV log, on its own (joints and events; no camera)."""

    name = "prosthesis-log"
    summary = "prosthesis controller CSV (joint angles + events or load cell); mapping in config"

    def detect(self, path: Path) -> bool:
        if not (path.is_file() and path.suffix.lower() == ".csv"):
            return False
        with path.open("r", encoding="utf-8", errors="replace") as handle:
            first = handle.readline()
        return not first.startswith("#")  # EuRoC/ASL CSVs start with a '#timestamp' header

    def open(self, path: Path, config: ConvertConfig) -> Recording:
        path = Path(path)
        report = ConversionReport(adapter=self.name, source=str(path))
        joints, events, reports = read_prosthesis_log(path, config.prosthesis_log)
        for r in reports:
            report.add(r)
        report.notes.append("no camera: a session of joints and events only")
        return Recording(
            name=path.stem,
            report=report,
            resolved=config.model_copy(update={"format": self.name}),
            joints=joints,
            events=events,
        )

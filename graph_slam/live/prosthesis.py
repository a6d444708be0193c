"""The prosthesis's streams while running live: joint angles, load and gait events, on the
camera's clock, released as they become known (never ahead of the camera's time).

Two sources behind one interface (:meth:`until`: everything known at a camera time):

- :class:`LogReplay`: a controller's CSV log (``prosthesis_log`` of the conversion config),
  replayed on its own clock shifted by a known offset (camera time = log time + offset): a
  sample is known from its time on, a load-cell event from the sample that crossed the
  threshold;
- :class:`UdpStream`: datagrams from a controller in any language on a UDP socket (loopback
  by default), one JSON object each (docs/recording.md, "Live")::

      {"seq": 17, "t_s": 12.345, "knee_rad": 0.31, "ankle_rad": -0.05,
       "load_n": 612.0, "event": "foot_strike"}

  ``seq`` (an increasing integer) and ``t_s`` (seconds on the controller's clock; camera
  time = t_s + offset) are required, the rest optional (``event``: ``foot_strike`` or
  ``toe_off``). Counted, never fatal: **malformed** (not JSON, a field missing or not a
  number), **duplicate** (a ``seq`` already seen), **out of order** (a ``seq`` lower than one
  already seen, kept when not late), **late** (stamped at or before what was already given
  to the estimator: dropped). Each poll reads at most ``max_datagrams`` and never blocks.
"""

from __future__ import annotations

import json
import math
import socket
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from graph_slam.session.adapters.config import LoadColumn, ProsthesisLogConfig


@dataclass
class Known:
    """What became known up to a camera time: joint samples and gait events."""

    joints_t_s: list[float] = field(default_factory=list)
    knee_rad: list[float] = field(default_factory=list)
    ankle_rad: list[float] = field(default_factory=list)
    #: (event time s, kind) in time order
    events: list[tuple[float, str]] = field(default_factory=list)


class NoProsthesis:
    """No prosthesis streams (the camera and its IMU only)."""

    def __init__(self) -> None:
        self.counts: dict[str, int] = {}

    def until(self, t_s: float) -> Known:
        return Known()

    def close(self) -> None:
        pass


class LoadEvents:
    """Foot strikes and toe-offs from load samples, online (hysteresis; the crossing time
    interpolated between the two samples around it)."""

    def __init__(self, spec: LoadColumn) -> None:
        self.spec = spec
        self._prev: tuple[float, float] | None = None
        self._stance: bool | None = None

    def add(self, t_s: float, load_n: float) -> tuple[float, str] | None:
        spec, prev = self.spec, self._prev
        self._prev = (t_s, load_n)
        if prev is None or self._stance is None:
            self._stance = load_n >= spec.foot_strike_above_n
            return None
        if not self._stance and load_n >= spec.foot_strike_above_n:
            thr, kind, self._stance = spec.foot_strike_above_n, "foot_strike", True
        elif self._stance and load_n < spec.toe_off_below_n:
            thr, kind, self._stance = spec.toe_off_below_n, "toe_off", False
        else:
            return None
        a = prev[1]
        frac = 1.0 if load_n == a else min(max((thr - a) / (load_n - a), 0.0), 1.0)
        return prev[0] + frac * (t_s - prev[0]), kind


class LogReplay:
    """A prosthesis log replayed on its clock (camera time = log time + ``offset_s``)."""

    def __init__(self, path: str | Path, spec: ProsthesisLogConfig, offset_s: float) -> None:
        from graph_slam.session.adapters.prosthesis_log import (
            TIME_UNITS_S,
            _column,
            _numbers,
            _read_table,
            read_prosthesis_log,
        )

        path = Path(path)
        joints, _, _ = read_prosthesis_log(
            path, spec.model_copy(update={"time_offset_s": offset_s, "load": None, "events": None})
        )
        self.t_s, self.knee, self.ankle = joints.t_s, joints.knee_rad, joints.ankle_rad
        self.load: tuple[np.ndarray, np.ndarray] | None = None
        if spec.load is not None:
            header, body = _read_table(path, spec.delimiter)
            t_col = _column(path, header, spec.time.column, "time.column")
            l_col = _column(path, header, spec.load.column, "load.column")
            t = _numbers(path, body, t_col, spec.time.column) * TIME_UNITS_S[spec.time.unit]
            load = _numbers(path, body, l_col, spec.load.column) * spec.load.scale
            ok = np.isfinite(t) & np.isfinite(load)
            self.load = (t[ok] + offset_s, load[ok])
            self._events = LoadEvents(spec.load)
        self._i = self._j = 0
        self.counts = {"joints": 0, "events": 0}

    def until(self, t_s: float) -> Known:
        """Samples (joints and load) stamped up to and including the first at or after
        ``t_s`` (the frame's time is covered, as a replay delivers them) and the events they
        made known (a load crossing is known from the sample after it: an event stamped at or
        before ``t_s`` is known by then)."""
        out = Known()
        j = min(int(np.searchsorted(self.t_s, t_s, side="left")) + 1, self.t_s.size)
        if j > self._i:
            sl = slice(self._i, j)
            out.joints_t_s, out.knee_rad = self.t_s[sl].tolist(), self.knee[sl].tolist()
            out.ankle_rad = self.ankle[sl].tolist()
            self.counts["joints"] += j - self._i
            self._i = j
        if self.load is not None:
            lt, lv = self.load
            k = min(int(np.searchsorted(lt, t_s, side="left")) + 1, lt.size)
            for i in range(self._j, k):
                event = self._events.add(float(lt[i]), float(lv[i]))
                if event is not None:
                    out.events.append(event)
                    self.counts["events"] += 1
            self._j = max(self._j, k)
        return out

    def close(self) -> None:
        pass


class UdpStream:
    """Joints, load and events from JSON datagrams (module docstring); non-blocking."""

    def __init__(
        self,
        port: int = 0,
        host: str = "127.0.0.1",
        *,
        offset_s: float = 0.0,
        load: LoadColumn | None = None,
        max_datagrams: int = 1000,
    ) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind((host, port))
        self.sock.setblocking(False)
        self.address = self.sock.getsockname()
        self.offset_s = offset_s
        self.max_datagrams = max_datagrams
        self._load = LoadEvents(load) if load is not None else None
        self._seen: set[int] = set()
        self._max_seq = -1
        self._pending: list[tuple[float, dict]] = []
        self._given_s = -math.inf
        self.counts = {"received": 0, "used": 0, "malformed": 0, "duplicate": 0,
                       "out of order": 0, "late": 0}  # fmt: skip

    def _parse(self, data: bytes) -> tuple[int, float, dict] | None:
        try:
            msg = json.loads(data.decode("utf-8"))
            seq, t = msg["seq"], float(msg["t_s"])
            if not isinstance(msg, dict) or not isinstance(seq, int) or not math.isfinite(t):
                return None
            for key in ("knee_rad", "ankle_rad", "load_n"):
                if key in msg and not math.isfinite(float(msg[key])):
                    return None
            if "event" in msg and msg["event"] not in ("foot_strike", "toe_off"):
                return None
        except (ValueError, KeyError, TypeError, UnicodeDecodeError):
            return None
        return seq, t + self.offset_s, msg

    def _read(self) -> None:
        for _ in range(self.max_datagrams):
            try:
                data = self.sock.recv(65536)
            except (BlockingIOError, InterruptedError):
                return
            self.counts["received"] += 1
            parsed = self._parse(data)
            if parsed is None:
                self.counts["malformed"] += 1
                continue
            seq, t, msg = parsed
            if seq in self._seen:
                self.counts["duplicate"] += 1
                continue
            self._seen.add(seq)
            if seq < self._max_seq:
                self.counts["out of order"] += 1
            self._max_seq = max(self._max_seq, seq)
            if t <= self._given_s:
                self.counts["late"] += 1
                continue
            self._pending.append((t, msg))

    def until(self, t_s: float) -> Known:
        """Everything received with a camera time at or before ``t_s`` (and one sample after
        it, when it has arrived), in time order."""
        self._read()
        self._pending.sort(key=lambda p: p[0])
        out = Known()
        k = 0
        while k < len(self._pending) and self._pending[k][0] <= t_s:
            k += 1
        if k < len(self._pending):
            k += 1  # the first sample after the frame covers it
        for t, msg in self._pending[:k]:
            self.counts["used"] += 1
            if "knee_rad" in msg and "ankle_rad" in msg:
                out.joints_t_s.append(t)
                out.knee_rad.append(float(msg["knee_rad"]))
                out.ankle_rad.append(float(msg["ankle_rad"]))
            if "event" in msg:
                out.events.append((t, str(msg["event"])))
            elif self._load is not None and "load_n" in msg:
                event = self._load.add(t, float(msg["load_n"]))
                if event is not None:
                    out.events.append(event)
        if k:
            self._given_s = max(self._given_s, self._pending[k - 1][0])
        del self._pending[:k]
        return out

    def close(self) -> None:
        self.sock.close()

"""Plausibility of a prosthesis controller log's *values* in the units its mapping declares.

The reader (:mod:`.prosthesis_log`) checks the form; these checks catch a mapping that names
the wrong unit, which would otherwise convert silently and end in a confident wrong answer
downstream (a gyro blamed for radians read as degrees, a clock offset fitted to a load in kg,
an offset of decades for milliseconds read as seconds). Each raises a
:class:`~graph_slam.errors.ConversionError` naming the log, the mapping field and the fix, or
returns a caveat (a line for the conversion report). Thresholds are the named constants below.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from graph_slam.errors import ConversionError

MIN_SAMPLES = 10
"""Fewer samples than this: too few to judge a range (no check)."""
KNEE_MIN_RANGE_DEG = 3.0
"""A walking knee flexes ~60° a stride; a range (1st-99th percentile) below this in a log
declared in degrees is radians read as degrees."""
JOINT_MAX_RAD = 2.0 * math.pi
"""|knee| or |ankle| above a full turn in a log declared in radians: the values are degrees."""
LOAD_PEAK_N = (200.0, 10_000.0)
"""The load cell's stance peak (99th percentile) must lie in this range of newtons: at least
the body weight of a 20 kg person, at most ten times that of a 100 kg one. Below it the unit
is kg or lbf; above it raw counts."""
MAX_BACKWARD_S = 0.1
"""A log's time may step back by at most this (rows out of order, sorted); a larger step back
is a clock reset or a wrap, and the rows around it cannot be put in order."""
SPAN_FIT = 100.0
"""The log's span may differ from the camera's by this factor (a log kept longer) ..."""
SPAN_OTHER_UNIT_FIT = 3.0
"""... unless another time unit makes the two spans agree within this factor: then the
declared unit is wrong (fatal); a log off by more with no unit that fits is a caveat."""
TIME_UNITS_S = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}


def check_joint_units(path: Path, values: np.ndarray, unit: str, joint: str) -> None:
    """``values``: the joint's column after its scale and offset, in the declared ``unit``."""
    v = values[np.isfinite(values)]
    if v.size < MIN_SAMPLES:
        return
    if unit == "rad" and float(np.max(np.abs(v))) > JOINT_MAX_RAD:
        raise ConversionError(
            f"{path}: prosthesis_log.{joint}.unit is rad but |{joint}| reaches "
            f"{float(np.max(np.abs(v))):.4g} (> 2π): the values are degrees; set "
            f"prosthesis_log.{joint}.unit: deg"
        )
    if unit == "deg" and joint == "knee":
        lo, hi = np.percentile(v, [1.0, 99.0])
        if hi - lo < KNEE_MIN_RANGE_DEG:
            raise ConversionError(
                f"{path}: prosthesis_log.knee.unit is deg but the knee moves only "
                f"{hi - lo:.3g}° (1st-99th percentile; a walking knee flexes ~60°): the values "
                "look like radians; set prosthesis_log.knee.unit: rad (and ankle.unit too if "
                "it is the same)"
            )


def check_load(path: Path, load_n: np.ndarray, column: str, scale: float) -> None:
    """``load_n``: the load column × ``load.scale``, meant to be newtons."""
    v = load_n[np.isfinite(load_n)]
    if v.size < MIN_SAMPLES:
        return
    peak = float(np.percentile(v, 99.0))
    lo, hi = LOAD_PEAK_N
    if peak < lo:
        raise ConversionError(
            f"{path}: the load cell ({column!r} × load.scale {scale:g}) peaks at {peak:.4g} N "
            f"(99th percentile), less than any adult's body weight (>= {lo:g} N): is the column "
            "in kg (set prosthesis_log.load.scale: 9.80665) or lbf (4.44822)?"
        )
    if peak > hi:
        raise ConversionError(
            f"{path}: the load cell ({column!r} × load.scale {scale:g}) peaks at {peak:.4g} N "
            f"(99th percentile), more than {hi:g} N (ten body weights): the column is not in "
            "newtons (raw counts?); set prosthesis_log.load.scale to newtons per unit"
        )


def check_clock(path: Path, t_s: np.ndarray, column: str) -> None:
    """The log's time (in seconds, file order) never steps back by more than
    :data:`MAX_BACKWARD_S` (a clock reset); smaller reorderings are sorted by the reader."""
    finite = np.flatnonzero(np.isfinite(t_s))
    if finite.size < 2:
        return
    steps = np.diff(t_s[finite])
    worst = int(np.argmin(steps))
    if -steps[worst] > MAX_BACKWARD_S:
        row = int(finite[worst + 1])
        raise ConversionError(
            f"{path}: column {column!r} steps back by {-steps[worst]:.4g} s at data row {row} "
            f"(line {row + 2}): the log's clock was reset or wrapped, and its rows cannot be put "
            f"in order; split the log at line {row + 2} and convert the part that overlaps the "
            "camera"
        )


def check_span(path: Path, log_t_s: np.ndarray, camera_t_s: np.ndarray, unit: str) -> str | None:
    """The log's time span against the camera's (both in seconds, the log's in its declared
    ``unit``): a :class:`ConversionError` when another unit makes them agree, a caveat (the
    returned line) when they differ by more than :data:`SPAN_FIT` and no unit fits."""
    log_t = log_t_s[np.isfinite(log_t_s)]
    cam_t = camera_t_s[np.isfinite(camera_t_s)]
    if log_t.size < 2 or cam_t.size < 2:
        return None
    log_span = float(log_t.max() - log_t.min())
    cam_span = float(cam_t.max() - cam_t.min())
    if log_span <= 0 or cam_span <= 0 or 1 / SPAN_FIT <= log_span / cam_span <= SPAN_FIT:
        return None
    ratio = {u: log_span * s / TIME_UNITS_S[unit] / cam_span for u, s in TIME_UNITS_S.items()}
    best = min(ratio, key=lambda u: abs(math.log(ratio[u])))
    said = f"the log spans {log_span:.4g} s (time.unit: {unit}) but the camera {cam_span:.4g} s"
    if best != unit and 1 / SPAN_OTHER_UNIT_FIT <= ratio[best] <= SPAN_OTHER_UNIT_FIT:
        raise ConversionError(
            f"{path}: {said}: the log's time is in {best}, not {unit}; set "
            f"prosthesis_log.time.unit: {best}"
        )
    return f"{path}: {said}; check prosthesis_log.time.unit and that the log covers the walk"

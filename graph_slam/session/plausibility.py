"""Plausibility of a session's streams: caveats for the report, or an error when meaningless.

The session reader checks each file's *form* (header, numbers, finite, increasing times). This
module checks that the *values* are plausible for a thigh-mounted RGB-D camera, IMU and knee/
ankle encoders, and what the pipelines need:

- :func:`session_findings` returns :class:`Finding` s. A finding with ``fatal=True`` makes any
  result meaningless (an accelerometer in g, a gyro in deg/s, joints in degrees, a principal
  point outside the image, a stream with only its header, ground truth not at the frame times,
  no foot strike inside the recording): ``compare`` stops before any work and ``validate``
  reports it. The others are caveats that ``compare`` writes into report.md and metrics.json
  (``warnings``): gaps, clipped samples, an unusual gravity magnitude or depth range.
- :func:`variant_findings` says which variants miss one of their inputs (``icp+imu`` without
  an IMU is fatal: the variant would run without its IMU factors under its own name).

Every threshold is a named constant below, stated in the message.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from graph_slam.errors import GraphSlamError, SessionError

G_M_S2 = 9.80665
ACCEL_NORM_WARN_M_S2 = (7.5, 12.5)
"""Median |accel| outside this (m/s²): gravity looks wrong (a caveat)."""
ACCEL_NORM_FATAL_M_S2 = (3.0, 40.0)
"""Median |accel| outside this (m/s²): the unit is not m/s² (g gives ≈ 1)."""
GYRO_FATAL_RAD_S = 35.0
"""99th percentile |gyro| above this (2000 °/s, a common full scale): the unit is °/s."""
JOINT_FATAL_RAD = 2.0 * np.pi
"""|knee| or |ankle| above a full turn: the unit is degrees."""
GAP_WARN_S = {"imu": 0.05, "joints": 0.05, "frames": 0.2}
"""Intervals longer than this (s) in a stream are reported as gaps."""
CLIP_MIN_SAMPLES = 3
"""Samples exactly at an axis' extreme value, at least this many and two in a row: clipped."""
DEPTH_WARN_M = (0.25, 6.0)
"""Median valid depth outside this (m) for a thigh camera: the depth unit may be off."""
MIN_STRIDE_S = 0.3
"""Foot strikes closer than this (s) are implausible as strides (a caveat)."""
PRINCIPAL_POINT_WARN = 0.25
"""Principal point farther than this fraction of the image size from the centre (a caveat)."""


@dataclass(frozen=True)
class Finding:
    """One caveat (or, ``fatal``, one reason the result would be meaningless)."""

    code: str
    """Machine-readable kind: ``imu_gap``, ``accel_units``, ``strides_dropped``, ..."""
    file: str
    message: str
    fatal: bool = False

    def __str__(self) -> str:
        return f"{self.file}: {self.message}"

    def to_dict(self) -> dict[str, object]:
        return asdict(self)


def _name(session, field: str) -> str:
    rel = getattr(session.manifest.files, field)
    return str(Path(session.path) / rel) if rel else str(session.path)


def _gap(stream: str, file: str, t_s: np.ndarray) -> list[Finding]:
    if t_s.size < 2:
        return []
    step = np.diff(t_s)
    gaps = step > GAP_WARN_S[stream]
    if not gaps.any():
        return []
    i = int(np.argmax(step))
    return [
        Finding(
            f"{stream}_gap",
            file,
            f"{int(gaps.sum())} gap(s) longer than {GAP_WARN_S[stream]:g} s; the longest "
            f"{float(step[i]):.3f} s after t={float(t_s[i]):.3f} s",
        )
    ]


def _empty(stream: str, file: str, n: int, need: int = 2) -> list[Finding]:
    if n >= need:
        return []
    return [
        Finding(
            f"{stream}_empty",
            file,
            f"{n} sample(s) (only the header?); a stream needs at least {need}; remove it from "
            "session.yaml 'files' if the session has none",
            fatal=True,
        )
    ]


def imu_findings(session) -> list[Finding]:
    """Sample count, gaps, accelerometer and gyro units, clipping."""
    imu = session.imu
    if imu is None:
        return []
    file = _name(session, "imu")
    t = np.asarray(imu.t_s)
    out = _empty("imu", file, t.size)
    if out:
        return out
    out += _gap("imu", file, t)
    accel = np.asarray(imu.accel_m_s2)
    norm = float(np.median(np.linalg.norm(accel, axis=1)))
    lo, hi = ACCEL_NORM_FATAL_M_S2
    if not lo <= norm <= hi:
        hint = " (looks like g: multiply by 9.80665)" if 0.5 <= norm <= 2.0 else ""
        out.append(
            Finding(
                "accel_units",
                file,
                f"columns accel_*_m_s2: median |accel| {norm:.3g} m/s² is not gravity "
                f"(expected {lo:g}-{hi:g}){hint}",
                fatal=True,
            )
        )
    elif not ACCEL_NORM_WARN_M_S2[0] <= norm <= ACCEL_NORM_WARN_M_S2[1]:
        out.append(
            Finding(
                "accel_gravity",
                file,
                f"median |accel| {norm:.2f} m/s², far from g = {G_M_S2} (scale or bias?)",
            )
        )
    gyro_p99 = float(np.percentile(np.linalg.norm(imu.gyro_rad_s, axis=1), 99))
    if gyro_p99 > GYRO_FATAL_RAD_S:
        out.append(
            Finding(
                "gyro_units",
                file,
                f"columns gyro_*_rad_s: 99th percentile |gyro| {gyro_p99:.1f} rad/s is above "
                f"{GYRO_FATAL_RAD_S:g} rad/s (2000 °/s); the unit looks like °/s: convert to rad/s",
                fatal=True,
            )
        )
    out += _clipped(file, "accel", accel) + _clipped(file, "gyro", np.asarray(imu.gyro_rad_s))
    return out


def _clipped(file: str, what: str, data: np.ndarray) -> list[Finding]:
    out = []
    for axis, name in enumerate("xyz"):
        col = np.abs(data[:, axis])
        peak = float(col.max(initial=0.0))
        at_peak = (col == peak) & (peak > 0)
        n = int(np.count_nonzero(at_peak))
        if n >= CLIP_MIN_SAMPLES and bool((at_peak[1:] & at_peak[:-1]).any()):
            out.append(
                Finding(
                    f"{what}_clipped",
                    file,
                    f"column {what}_{name}: {n} samples at ±{peak:.3g} (saturated sensor?)",
                )
            )
    return out


def joint_findings(session) -> list[Finding]:
    joints = session.joints
    if joints is None:
        return []
    file = _name(session, "joints")
    t = np.asarray(joints.t_s)
    out = _empty("joints", file, t.size)
    if out:
        return out
    out += _gap("joints", file, t)
    q = np.abs(np.asarray(joints.q_rad))
    for k, col in enumerate(("knee_rad", "ankle_rad")):
        peak = float(q[:, k].max())
        if peak > JOINT_FATAL_RAD:
            out.append(
                Finding(
                    "joint_units",
                    file,
                    f"column {col}: |angle| up to {peak:.1f}, more than a full turn "
                    f"({JOINT_FATAL_RAD:.2f} rad); the unit looks like degrees: convert to radians",
                    fatal=True,
                )
            )
    return out


def camera_findings(session, depth_samples: int = 3) -> list[Finding]:
    """Frames present, principal point inside the image, frame gaps, median depth."""
    k = session.intrinsics
    if k is None:
        return []
    file = _name(session, "frames")
    manifest = str(Path(session.path) / "session.yaml")
    out = _empty("frames", file, session.n_frames)
    w, h = k.width_px, k.height_px
    for axis, c, size in (("cx_px", k.cx_px, w), ("cy_px", k.cy_px, h)):
        off = abs(c - (size - 1) / 2.0) / size
        if not 0.0 <= c <= size:
            out.append(
                Finding(
                    "principal_point",
                    manifest,
                    f"field 'sensors.camera.intrinsics.{axis}' = {c:g} lies outside the image "
                    f"(0-{size} px)",
                    fatal=True,
                )
            )
        elif off > PRINCIPAL_POINT_WARN:
            out.append(
                Finding(
                    "principal_point",
                    manifest,
                    f"field 'sensors.camera.intrinsics.{axis}' = {c:g} is {off:.0%} of the "
                    "image size from the centre",
                )
            )
    if out and any(f.fatal for f in out):
        return out
    out += _gap("frames", file, session.frame_times_s)
    depths = []
    sampled = np.unique(np.linspace(0, session.n_frames - 1, depth_samples).round().astype(int))
    images = [session.frame(int(i)).depth_m for i in sampled]
    for d in images:
        if (d > 0).any():
            depths.append(float(np.median(d[d > 0])))
    out += _depth_content(file, sampled, images)
    if depths:
        median = float(np.median(depths))
        lo, hi = DEPTH_WARN_M
        if not lo <= median <= hi:
            out.append(
                Finding(
                    "depth_range",
                    manifest,
                    f"median depth {median:.3g} m is outside {lo:g}-{hi:g} m for a thigh camera; "
                    f"is 'sensors.camera.depth_unit_m' ({session.depth_unit_m:g}) right?",
                )
            )
    return out


def _depth_content(file: str, sampled: np.ndarray, images: list[np.ndarray]) -> list[Finding]:
    """The sampled depth images all empty (no valid pixel), or all the same image: no
    registration can be trusted (a frozen stream would read as zero motion)."""
    frames = ", ".join(str(int(i)) for i in sampled)
    if images and not any((d > 0).any() for d in images):
        return [
            Finding(
                "depth_empty",
                file,
                f"no valid depth pixel (every value 0) in frames {frames}: the camera recorded "
                "no depth, nothing can be registered",
                fatal=True,
            )
        ]
    if len(images) >= 2 and all(np.array_equal(images[0], d) for d in images[1:]):
        return [
            Finding(
                "depth_frozen",
                file,
                f"frames {frames} hold the same depth image, pixel for pixel: a frozen or "
                "repeated depth stream (every registration would read zero motion)",
                fatal=True,
            )
        ]
    return []


def timing_findings(session, *, events_cut_strides: bool = True) -> list[Finding]:
    """Foot strikes inside the recording (when events.csv cuts the strides); ground truth at
    the frame times."""
    out: list[Finding] = []
    t = session.frame_times_s
    if t.size < 2:
        return out
    events = session.events
    if events is not None and events_cut_strides:
        strikes = np.asarray(events.t_s)[np.asarray(events.kind) == "foot_strike"]
        inside = strikes[(strikes >= t[0]) & (strikes <= t[-1])]
        close = np.flatnonzero(np.diff(np.sort(strikes)) < MIN_STRIDE_S)
        if close.size:
            out.append(
                Finding(
                    "stride_time",
                    _name(session, "events"),
                    f"{close.size} foot strike(s) less than {MIN_STRIDE_S:g} s after the previous "
                    "one (a stride takes about 1 s); such strides have too few frames and are "
                    "not scored",
                )
            )
        if inside.size == 0:
            out.append(
                Finding(
                    "no_foot_strike",
                    _name(session, "events"),
                    f"no foot strike inside the recording (frames {t[0]:.3f}-{t[-1]:.3f} s; "
                    f"{strikes.size} foot strike(s) in the file, {len(events.t_s)} events); "
                    "strides start at foot strikes",
                    fatal=True,
                )
            )
    gt = session.ground_truth
    if gt is not None and len(gt.t_s):
        t_gt = np.asarray(gt.t_s)
        covered = t[(t >= t_gt[0] - 1e-6) & (t <= t_gt[-1] + 1e-6)]
        hi = np.clip(np.searchsorted(t_gt, covered), 0, t_gt.size - 1)
        lo = np.clip(hi - 1, 0, t_gt.size - 1)
        off = np.minimum(np.abs(t_gt[hi] - covered), np.abs(t_gt[lo] - covered))
        if covered.size and float(off.max()) > 1e-6:
            j = int(np.argmax(off))
            out.append(
                Finding(
                    "ground_truth_times",
                    _name(session, "ground_truth"),
                    f"not at the frame times: frame t={covered[j]:.6f} s is {off[j] * 1e3:.3f} ms "
                    "from the nearest pose (tolerance 1 µs); write the ground truth at the "
                    "frame times (groundtruth_hf.txt holds a high-rate one)",
                    fatal=True,
                )
            )
    return out


def session_findings(
    session, *, depth: bool = True, events_cut_strides: bool = True
) -> list[Finding]:
    """Every static finding on ``session`` (an open :class:`graph_slam.session.Session`).
    ``events_cut_strides=False``: the strides come from elsewhere (the causal IMU estimator),
    so events.csv need not hold a foot strike inside the recording."""
    out = imu_findings(session) + joint_findings(session)
    out += timing_findings(session, events_cut_strides=events_cut_strides)
    if depth:
        out = camera_findings(session) + out
    return out


def variant_findings(
    session, variants: list[str], *, events_cut_strides: bool = True
) -> list[Finding]:
    """A variant whose factors need a stream the session lacks is fatal (never mislabelled).
    ``events_cut_strides=False``: the strides come from the thigh IMU, which is then needed
    instead of events.csv."""
    out = []
    for v in variants:
        parts = v.split("+")
        needs = [("imu", "imu", "IMU factors")] if "imu" in parts else []
        needs += [("joints", "joints", "leg-kinematic factors")] if "kin" in parts else []
        for attr, field, what in needs:
            if getattr(session, attr) is None:
                out.append(
                    Finding(
                        "variant_input",
                        str(Path(session.path) / "session.yaml"),
                        f"variant {v!r} needs {what} but field 'files.{field}' is absent; "
                        "choose variants without it (--variants)",
                        fatal=True,
                    )
                )
    if session.intrinsics is None:
        out.append(
            Finding(
                "variant_input",
                str(Path(session.path) / "session.yaml"),
                "every variant registers depth frames but field 'sensors.camera' is null (a "
                "session without a camera)",
                fatal=True,
            )
        )
    need, what = ("events", "foot strikes") if events_cut_strides else ("imu", "IMU gait events")
    if getattr(session, need) is None:
        out.append(
            Finding(
                "variant_input",
                str(Path(session.path) / "session.yaml"),
                f"every variant cuts strides at {what} but field 'files.{need}' is absent",
                fatal=True,
            )
        )
    return out


def raise_fatal(findings: list[Finding]) -> list[Finding]:
    """Raise the first fatal finding as a :class:`SessionError`; return the caveats."""
    fatal = [f for f in findings if f.fatal]
    if fatal:
        more = f" (and {len(fatal) - 1} more problem(s); graph-slam validate lists them)"
        raise SessionError(str(fatal[0]) + (more if len(fatal) > 1 else ""))
    return [f for f in findings if not f.fatal]


def safe_findings(session, **kwargs) -> list[Finding | GraphSlamError]:
    """:func:`session_findings`, with a stream that cannot be read returned as its error."""
    try:
        return list(session_findings(session, **kwargs))
    except GraphSlamError as err:
        return [err]

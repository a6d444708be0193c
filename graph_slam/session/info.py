"""Summaries of a session: per-stream counts, rates, durations, gaps, and strides."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from graph_slam.session.reader import Session

#: A gap is an interval longer than this multiple of the stream's median sample interval.
GAP_FACTOR = 2.0


@dataclass(frozen=True)
class StreamInfo:
    """Timing of one stream."""

    name: str
    count: int
    start_s: float | None
    duration_s: float
    mean_rate_hz: float | None
    median_rate_hz: float | None
    gaps: int
    longest_gap_s: float

    @classmethod
    def from_times(cls, name: str, t_s: np.ndarray) -> StreamInfo:
        count = int(t_s.size)
        if count < 2:
            return cls(name, count, float(t_s[0]) if count else None, 0.0, None, None, 0, 0.0)
        dt = np.diff(t_s)
        median_dt = float(np.median(dt))
        gap_mask = dt > GAP_FACTOR * median_dt
        duration = float(t_s[-1] - t_s[0])
        return cls(
            name=name,
            count=count,
            start_s=float(t_s[0]),
            duration_s=duration,
            mean_rate_hz=(count - 1) / duration,
            median_rate_hz=1.0 / median_dt,
            gaps=int(gap_mask.sum()),
            longest_gap_s=float(dt.max()) if gap_mask.any() else 0.0,
        )


@dataclass(frozen=True)
class StrideInfo:
    """Strides cut at consecutive foot strikes."""

    foot_strikes: int
    toe_offs: int
    strides: int
    mean_stride_s: float | None
    min_stride_s: float | None
    max_stride_s: float | None
    frames_per_stride: tuple[int, ...] = ()
    source: str | None = None
    """The events' source that cut them (None: every source in events.csv)."""


@dataclass(frozen=True)
class SessionInfo:
    """What ``graph-slam info`` prints."""

    name: str
    path: str
    schema_version: int
    camera_profile: str | None  # None: a session without a camera
    image_size: tuple[int, int] | None
    has_color: bool
    depth_unit_m: float | None
    streams: tuple[StreamInfo, ...]
    strides: StrideInfo | None
    provenance: dict[str, object] = field(default_factory=dict)


def session_info(session: Session, event_source: str | None = None) -> SessionInfo:
    """Summarise a session (reads the small streams; decodes no frame). Strides are cut at the
    foot strikes of ``event_source`` (None: every source), the pipelines' rule
    (:meth:`GaitEvents.of_source`)."""
    streams = [StreamInfo.from_times("frames", session.frame_times_s)]
    for name in ("imu", "joints", "ground_truth", "ground_truth_hf"):
        series = getattr(session, name)
        if series is not None:
            streams.append(StreamInfo.from_times(name, series.t_s))
    strides = None
    events = session.events
    if events is not None:
        events = events.of_source(event_source, f"{session.path}/events.csv")
        strikes = events.foot_strikes_s
        durations = np.diff(strikes)
        frames = tuple(int(n) for n in np.diff(np.searchsorted(session.frame_times_s, strikes)))
        strides = StrideInfo(
            foot_strikes=int(strikes.size),
            toe_offs=int(events.toe_offs_s.size),
            strides=int(durations.size),
            mean_stride_s=float(durations.mean()) if durations.size else None,
            min_stride_s=float(durations.min()) if durations.size else None,
            max_stride_s=float(durations.max()) if durations.size else None,
            frames_per_stride=frames,
            source=event_source,
        )
    cam = session.manifest.sensors.camera
    return SessionInfo(
        name=session.name,
        path=str(session.path),
        schema_version=session.manifest.schema_version,
        camera_profile=None if cam is None else cam.profile,
        image_size=None if cam is None else (cam.intrinsics.width_px, cam.intrinsics.height_px),
        has_color=False if cam is None else cam.has_color,
        depth_unit_m=None if cam is None else cam.depth_unit_m,
        streams=tuple(streams),
        strides=strides,
        provenance=session.manifest.provenance.model_dump(exclude_none=True),
    )

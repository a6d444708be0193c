"""What every source adapter provides: the :class:`SourceAdapter` protocol, the
:class:`Recording` it opens, and the :class:`ConversionReport` that counts every sample.

An adapter's ``open()`` reads a foreign recording's metadata and small streams (IMU, joints,
events, ground truth) and checks them; frames stay in the source and are decoded one at a time
by ``Recording.frames()`` while the session is written.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from graph_slam.session.adapters.config import ConvertConfig
from graph_slam.session.records import (
    Calibration,
    CameraIntrinsics,
    GaitEvents,
    ImuSeries,
    JointSeries,
    PoseTrajectory,
    RgbdFrame,
)


@dataclass
class StreamReport:
    """Counts of one stream: ``found == used + sum(dropped.values())`` always."""

    stream: str
    source: str
    found: int
    used: int
    dropped: dict[str, int] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    #: frames used without colour (no colour image close enough in time): kept depth-only
    depth_only: int = 0

    @property
    def balanced(self) -> bool:
        return self.found == self.used + sum(self.dropped.values())

    def to_dict(self) -> dict[str, Any]:
        return {
            "stream": self.stream,
            "source": self.source,
            "found": int(self.found),
            "used": int(self.used),
            "dropped": {k: int(v) for k, v in self.dropped.items() if v},
            "notes": list(self.notes),
            **({"depth_only": int(self.depth_only)} if self.depth_only else {}),
        }


@dataclass
class ConversionReport:
    """What a conversion read, used and dropped, stream by stream."""

    adapter: str
    source: str
    streams: list[StreamReport] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    #: The prosthesis log's clock offset (a ``clock_offset.ClockOffset``) when one was merged.
    clock_offset: Any = None
    #: calibration name → {"source": "bag (topic…)" | "config" | "default", "value": …}
    calibration: dict[str, dict[str, Any]] = field(default_factory=dict)
    #: the recording device (RealSense SDK: product, serial, firmware) when the source says
    device: dict[str, str] = field(default_factory=dict)

    def add(self, stream: StreamReport) -> StreamReport:
        self.streams.append(stream)
        return stream

    def stream(self, name: str) -> StreamReport:
        for s in self.streams:
            if s.stream == name:
                return s
        raise KeyError(
            f"no stream {name!r} in the report (have {[s.stream for s in self.streams]})"
        )

    def to_dict(self) -> dict[str, Any]:
        return {
            "adapter": self.adapter,
            "source": self.source,
            "streams": [s.to_dict() for s in self.streams],
            "notes": list(self.notes),
            **({"clock_offset": self.clock_offset.to_dict()} if self.clock_offset else {}),
            "calibration": {k: dict(v) for k, v in self.calibration.items()},
            **({"device": dict(self.device)} if self.device else {}),
        }


def _no_frames() -> Iterator[RgbdFrame]:
    return iter(())


@dataclass(frozen=True, eq=False)
class Recording:
    """A foreign recording, opened: small streams in memory, frames decoded on demand.

    ``frames()`` yields exactly ``len(frame_times_s)`` frames, in order, with those stamps.
    ``ground_truth`` is ``world_T_camera`` at (a subset of) the frame times;
    ``ground_truth_hf`` the same at the source's own rate.
    """

    name: str
    report: ConversionReport
    resolved: ConvertConfig
    intrinsics: CameraIntrinsics | None = None
    depth_unit_m: float | None = None  #: the unit the session should use (None: no camera)
    frame_times_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    frames: Callable[[], Iterator[RgbdFrame]] = _no_frames
    imu: ImuSeries | None = None
    joints: JointSeries | None = None
    events: GaitEvents | None = None
    ground_truth: PoseTrajectory | None = None
    ground_truth_hf: PoseTrajectory | None = None
    calibration: Calibration = field(default_factory=Calibration)
    camera_profile: str = "unknown"
    imu_profile: str = "unknown"

    @property
    def n_frames(self) -> int:
        return int(np.asarray(self.frame_times_s).size)


class SourceAdapter(Protocol):
    """A kind of source. Adapters are listed explicitly in ``registry.ADAPTERS``."""

    #: registry key, also the value of ``ConvertConfig.format``
    name: str
    #: one line for ``graph-slam convert --help`` and docs
    summary: str

    def detect(self, path: Path) -> bool:
        """Whether ``path`` looks like this kind of source (cheap: names, a header line)."""
        ...

    def open(self, path: Path, config: ConvertConfig) -> Recording:
        """Read metadata and small streams, check them, and return the recording."""
        ...


def resolve_in_folder(root: Path, relative: str, *, what: str) -> Path:
    """``root / relative``, refusing absolute paths and ``..`` escapes (a lexical check, so a
    dataset folder may itself be a symbolic link)."""
    import os

    from graph_slam.errors import ConversionError

    if Path(relative).is_absolute() or relative.startswith(("/", "\\")):
        raise ConversionError(
            f"{what}: path {relative!r} is absolute; it must be relative to {root}"
        )
    normal = os.path.normpath(relative)
    if normal == ".." or normal.startswith(("../", "..\\")):
        raise ConversionError(f"{what}: path {relative!r} escapes the source folder {root}")
    return root / normal

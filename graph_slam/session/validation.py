"""Checking a session completely: :func:`validate_session` and its :class:`ValidationReport`.

Opening a session (:mod:`graph_slam.session.reader`) checks only the manifest and the frame
index; validation also parses every stream, decodes every frame's PNGs, checks the depth scale
on a sample of frames, and then asks :mod:`graph_slam.session.plausibility` what ``compare``
would refuse. It collects every problem; only a broken manifest or frame index stops it, since
nothing else can be read then.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from graph_slam.errors import DepthScaleError, GraphSlamError, SessionError
from graph_slam.session.files import check_depth_scale
from graph_slam.session.reader import Session

__all__ = ["ValidationReport", "validate_session"]


@dataclass
class ValidationReport:
    """What :func:`validate_session` checked and every problem it found."""

    path: Path
    frames_checked: int = 0
    counts: dict[str, int] = field(default_factory=dict)
    problems: list[GraphSlamError] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    """Caveats (graph_slam.session.plausibility) that do not make the session invalid."""

    @property
    def ok(self) -> bool:
        return not self.problems

    def raise_if_failed(self) -> None:
        if self.problems:
            raise self.problems[0]


def validate_session(
    path: str | Path,
    *,
    every_frame: bool = True,
    progress: object | None = None,
    variants: list[str] | None = None,
) -> ValidationReport:
    """Check a session completely: manifest, streams, every frame's PNGs and the depth scale.

    Returns a report listing every problem (a problem in the manifest or frame index stops the
    check, since nothing else can be read). ``progress`` may be a callable ``(done, total)``.
    Then what ``compare`` would refuse (:mod:`graph_slam.session.plausibility`), including the
    streams that ``variants`` need, are problems; caveats are ``warnings``.
    """
    report = ValidationReport(Path(path))
    try:
        session = Session(path)
    except GraphSlamError as err:
        report.problems.append(err)
        return report
    report.counts["frames"] = session.n_frames
    _check_streams(session, report)
    _check_frames(session, report, every_frame=every_frame, progress=progress)
    if not report.problems:
        _check_plausibility(session, report, variants or [])
    return report


#: The session's streams that validation parses (attributes of :class:`Session`).
_STREAMS = (
    "calibration",
    "imu",
    "joints",
    "events",
    "ground_truth",
    "ground_truth_hf",
    "scene",
)


def _check_streams(session: Session, report: ValidationReport) -> None:
    """Parse every stream; count the samples of those that have a length."""
    for stream in _STREAMS:
        try:
            value = getattr(session, stream)
        except GraphSlamError as err:
            report.problems.append(err)
            continue
        if value is not None and hasattr(value, "__len__"):
            report.counts[stream] = len(value)


def _check_frames(
    session: Session, report: ValidationReport, *, every_frame: bool, progress: object | None
) -> None:
    """Decode every frame (or the first, middle and last); check the depth scale on up to 10."""
    n = session.n_frames
    if n == 0:
        indices: list[int] = []
    else:
        indices = list(range(n)) if every_frame else sorted({0, n // 2, n - 1})
    scale_sample = {int(i) for i in np.linspace(0, n - 1, min(n, 10))} if n else set()
    for done, index in enumerate(indices, start=1):
        try:
            frame = session.frame(index)
            if index in scale_sample:
                depth_path = session.path / session.frame_index.depth[index]
                check_depth_scale(depth_path, frame.depth_m, session.depth_unit_m)
            report.frames_checked += 1
        except DepthScaleError as err:
            # One report of a wrong scale is enough (the reader refuses every frame with it).
            if not any(isinstance(p, DepthScaleError) for p in report.problems):
                report.problems.append(err)
        except SessionError as err:
            report.problems.append(err)
        if callable(progress):
            progress(done, len(indices))


def _check_plausibility(session: Session, report: ValidationReport, variants: list[str]) -> None:
    """What compare would refuse (fatal findings) become problems; the rest, warnings."""
    from graph_slam.session.plausibility import safe_findings, variant_findings

    for finding in variant_findings(session, variants) if variants else []:
        report.problems.append(SessionError(str(finding)))
    for finding in safe_findings(session):
        if isinstance(finding, GraphSlamError):
            report.problems.append(finding)
        elif finding.fatal:
            report.problems.append(SessionError(str(finding)))
        else:
            report.warnings.append(str(finding))

"""``convert(src, dst)``: any registered source → a session folder, as a list of steps.

1. check the paths (the source is only read; the destination is never inside it),
2. choose the adapter (``format`` or detection) and open the recording,
3. merge a prosthesis log and apply the calibration overrides,
4. write the session into a temporary sibling folder, frame by frame,
5. write the resolved config (``conversion.yaml``) and the counts (``conversion_report.yaml``)
   into it, then move it into place — an interrupted conversion leaves no session behind.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import yaml

from graph_slam.config import write_config
from graph_slam.errors import ClockOffsetError, ConversionError, RecordError
from graph_slam.session.adapters.base import ConversionReport, Recording
from graph_slam.session.adapters.clock_offset import (
    ClockOffset,
    camera_imu_strikes,
    estimate_clock_offset,
)
from graph_slam.session.adapters.config import ConvertConfig
from graph_slam.session.adapters.log_checks import check_span
from graph_slam.session.adapters.prosthesis_log import read_prosthesis_log
from graph_slam.session.adapters.registry import select_adapter
from graph_slam.session.atomic import atomic_folder, check_output
from graph_slam.session.manifest import MANIFEST_NAME, Provenance
from graph_slam.session.records import Calibration, GaitEvents, JointSeries
from graph_slam.session.writer import SessionWriter

CONFIG_NAME = "conversion.yaml"
REPORT_NAME = "conversion_report.yaml"
#: SessionWriter's unit for a session without a camera (unused: it has no frames).
_NO_CAMERA_UNIT_M = 2e-4


@dataclass(frozen=True)
class ConversionResult:
    """Where the session went, and what the conversion counted and resolved."""

    path: Path
    report: ConversionReport
    config: ConvertConfig
    n_frames: int

    @property
    def clock_offset(self):
        """The prosthesis log's offset to the camera clock (``ClockOffset``), or None."""
        return self.report.clock_offset

    @property
    def config_path(self) -> Path:
        return self.path / CONFIG_NAME

    @property
    def report_path(self) -> Path:
        return self.path / REPORT_NAME


def check_paths(src: Path, dst: Path, overwrite: bool) -> None:
    """The source must exist; the destination must not overlap it; replace only a session."""
    if not src.exists():
        raise ConversionError(f"{src}: no such file or folder")
    src_r, dst_r = src.resolve(), dst.resolve()
    if dst_r == src_r or dst_r.is_relative_to(src_r) or src_r.is_relative_to(dst_r):
        raise ConversionError(
            f"{dst}: the destination overlaps the source {src}; the source is never modified, "
            "choose a destination outside it"
        )
    if dst.exists():
        if not overwrite:
            raise ConversionError(f"{dst}: already exists (pass --overwrite to replace a session)")
        if not dst.is_dir() or (not (dst / MANIFEST_NAME).is_file() and any(dst.iterdir())):
            raise ConversionError(
                f"{dst}: exists, is not empty and is not a session; refusing to overwrite"
            )


def merge_prosthesis_log(recording: Recording, config: ConvertConfig) -> Recording:
    """Add the joints and events of ``prosthesis_log.path`` to a recording that has none, on
    the camera clock: ``prosthesis_log.time_offset_s`` when given, else the offset estimated
    from the foot strikes of the recording's IMU and of the log (:mod:`.clock_offset`). The
    report and the resolved config carry the offset used and where it came from."""
    log = config.prosthesis_log
    if log.path is None or recording.resolved.format == "prosthesis-log":
        return recording
    has_events = log.events is not None or log.load is not None
    if recording.joints is not None or (has_events and recording.events is not None):
        raise ConversionError(
            f"prosthesis_log.path = {log.path!r}: the source already has joints or gait events; "
            "remove its joint/event topics (bag.joint_states_topic, bag.gait_events_topic) or "
            "the log"
        )
    joints, events, reports = read_prosthesis_log(Path(log.path), log)
    for r in reports:
        recording.report.add(r)
    caveat = check_span(Path(log.path), joints.t_s, recording.frame_times_s, log.time.unit)
    if caveat is not None:
        recording.report.notes.append(f"warning: {caveat}")
    if log.time_offset_s is None:
        offset = _estimate_log_offset(recording, config, events)
        joints = JointSeries(joints.t_s + offset.offset_s, joints.knee_rad, joints.ankle_rad)
        if events is not None:
            events = GaitEvents(events.t_s + offset.offset_s, events.kind, events.source)
    else:
        offset = ClockOffset(float(log.time_offset_s), "config")
    recording.report.clock_offset = offset
    recording.report.notes.append(offset.describe())
    recording.report.notes.append(f"joints and events merged from {log.path}")
    resolved = recording.resolved.model_copy(
        update={
            "prosthesis_log": recording.resolved.prosthesis_log.model_copy(
                update={"time_offset_s": offset.offset_s}
            )
        }
    )
    return replace(
        recording,
        joints=joints,
        events=events if has_events else recording.events,
        resolved=resolved,
    )


def _estimate_log_offset(
    recording: Recording, config: ConvertConfig, events: GaitEvents | None
) -> ClockOffset:
    """The log → camera offset from foot strikes (only the recording's IMU and the log's
    strikes are read). The IMU's own offset to the camera clock comes from the calibration
    (the config's value when set, else the source's)."""
    log = config.prosthesis_log
    where = f"prosthesis_log.path = {log.path!r}"
    hint = "set prosthesis_log.time_offset_s to merge it without an estimate"
    if recording.imu is None or not len(recording.imu):
        raise ClockOffsetError(
            f"{where}: the clock offset (prosthesis_log.time_offset_s: null) is estimated from "
            f"the foot strikes in the camera's IMU, but {recording.report.source} has no IMU; "
            f"{hint}"
        )
    if events is None:
        raise ClockOffsetError(
            f"{where}: the clock offset (prosthesis_log.time_offset_s: null) is estimated from "
            f"the log's foot strikes, but the mapping has neither 'events' nor 'load'; {hint}"
        )
    imu_offset_s = config.calibration.imu_time_offset_s
    if imu_offset_s is None:
        imu_offset_s = recording.calibration.imu_time_offset_s
    camera_strikes = camera_imu_strikes(recording.imu, imu_offset_s)
    return estimate_clock_offset(camera_strikes, events.foot_strikes_s, log.clock, where=where)


def apply_calibration(recording: Recording, config: ConvertConfig) -> Recording:
    """Calibration overrides from the config; the resolved config records the values used."""
    c = config.calibration
    base = recording.calibration
    try:
        calibration = Calibration(
            thigh_T_camera=base.thigh_T_camera
            if c.thigh_T_camera is None
            else np.asarray(c.thigh_T_camera),
            camera_T_imu=base.camera_T_imu
            if c.camera_T_imu is None
            else np.asarray(c.camera_T_imu),
            imu_time_offset_s=base.imu_time_offset_s
            if c.imu_time_offset_s is None
            else c.imu_time_offset_s,
            joints_time_offset_s=base.joints_time_offset_s
            if c.joints_time_offset_s is None
            else c.joints_time_offset_s,
        )
    except RecordError as err:
        raise ConversionError(f"config section 'calibration': {err}") from None
    _report_calibration_sources(recording, calibration, c)
    resolved = recording.resolved.model_copy(
        update={
            "calibration": c.model_copy(
                update={
                    "thigh_T_camera": tuple(map(tuple, calibration.thigh_T_camera.tolist())),
                    "camera_T_imu": tuple(map(tuple, calibration.camera_T_imu.tolist())),
                    "imu_time_offset_s": calibration.imu_time_offset_s,
                    "joints_time_offset_s": calibration.joints_time_offset_s,
                }
            )
        }
    )
    return replace(recording, calibration=calibration, resolved=resolved)


def _report_calibration_sources(recording: Recording, calibration: Calibration, c) -> None:
    """Say in the report which source won for each calibration value: the config (it
    overrides), the source recording (e.g. a bag's extrinsics), or the default."""
    entries = recording.report.calibration
    for name in ("thigh_T_camera", "camera_T_imu", "imu_time_offset_s", "joints_time_offset_s"):
        value = getattr(calibration, name)
        value = value.tolist() if isinstance(value, np.ndarray) else value
        if getattr(c, name) is not None:
            overridden = entries.get(name, {}).get("source")
            entries[name] = {"source": "config", "value": value}
            if overridden:
                entries[name]["overrides"] = overridden
        elif name not in entries:
            entries[name] = {"source": "default", "value": value}


def _provenance(recording: Recording, source: str) -> Provenance:
    """The manifest's provenance: the report's notes, then each stream's (named)."""
    report = recording.report
    notes = list(report.notes) + [f"{s.stream}: {n}" for s in report.streams for n in s.notes]
    return Provenance(
        generator=f"graph_slam.session.adapters ({report.adapter})",
        source=source,
        notes="; ".join(notes) or None,
    )


def write_recording(
    recording: Recording,
    path: Path,
    *,
    source: str,
    name: str | None = None,
    camera_profile: str | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> Path:
    """Write a recording as a session folder (SessionWriter: manifest last)."""
    unit = recording.depth_unit_m
    if recording.intrinsics is not None and (unit is None or unit > 0.01):
        raise ConversionError(
            f"{source}: the depth unit {unit} m is beyond the session format's 0.01 m; set "
            "output.depth_unit_m"
        )
    writer = SessionWriter(
        path,
        name=name or recording.name,
        intrinsics=recording.intrinsics,
        depth_unit_m=unit if unit is not None else _NO_CAMERA_UNIT_M,
        camera_profile=camera_profile or recording.camera_profile,
        imu_profile=recording.imu_profile,
        calibration=recording.calibration,
        provenance=_provenance(recording, source),
    )
    with writer:
        n = recording.n_frames
        times = np.asarray(recording.frame_times_s)
        written = 0
        for frame in recording.frames():
            if written >= n or frame.t_s != float(times[written]):
                raise ConversionError(
                    f"{source}: frame {written} does not match the frame index read before "
                    "(the source changed while converting?)"
                )
            writer.add_frame(frame)
            written += 1
            if progress is not None:
                progress(written, n)
        if written != n:
            raise ConversionError(f"{source}: {written} frames read, {n} expected")
        # Again after the frames: reading them adds notes (e.g. a bag's colour-registration
        # counts), and the manifest is written last, on close.
        writer.provenance = _provenance(recording, source)
        if recording.imu is not None and len(recording.imu):
            writer.write_imu(recording.imu)
        if recording.joints is not None and len(recording.joints):
            writer.write_joints(recording.joints)
        if recording.events is not None:
            writer.write_events(recording.events)
        if recording.ground_truth is not None and len(recording.ground_truth):
            writer.write_ground_truth(recording.ground_truth)
        if recording.ground_truth_hf is not None and len(recording.ground_truth_hf):
            writer.write_ground_truth(recording.ground_truth_hf, high_rate=True)
    return writer.path


def convert(
    src: str | Path,
    dst: str | Path,
    config: ConvertConfig | None = None,
    *,
    overwrite: bool = False,
    progress: Callable[[int, int], None] | None = None,
) -> ConversionResult:
    """Convert a supported source into a session at ``dst`` (see the module docstring)."""
    src, dst = Path(src), Path(dst)
    config = config or ConvertConfig()
    check_paths(src, dst, overwrite)
    inputs = [src] + ([config.prosthesis_log.path] if config.prosthesis_log.path else [])
    check_output(dst, overwrite=overwrite, command="convert", inputs=inputs)
    adapter = select_adapter(src, config.format)
    recording = adapter.open(src, config)
    recording = merge_prosthesis_log(recording, config)
    recording = apply_calibration(recording, config)
    with atomic_folder(
        dst, overwrite=overwrite, command="convert", inputs=inputs, create=False
    ) as tmp:
        write_recording(
            recording,
            tmp,
            source=str(src),
            name=config.output.name,
            camera_profile=config.output.camera_profile,
            progress=progress,
        )
        write_config(recording.resolved, tmp / CONFIG_NAME)
        (tmp / REPORT_NAME).write_text(
            yaml.safe_dump(recording.report.to_dict(), sort_keys=False, allow_unicode=True),
            encoding="utf-8",
        )
    return ConversionResult(dst, recording.report, recording.resolved, recording.n_frames)

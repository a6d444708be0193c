"""The project's session format on disk: a lazy reader, a streaming writer, and validation.

A session folder (docs/session_format.md)::

    session.yaml        manifest: schema version, sensors, calibration, files, provenance
    frames.csv          index,t_s,depth,color   (one row per RGB-D frame, paths relative)
    depth/NNNNNN.png    uint16, metres = value × depth_unit_m, 0 = invalid
    color/NNNNNN.png    RGB8, aligned with the depth (optional; per frame)
    imu.csv             t_s,gyro_x_rad_s,gyro_y_rad_s,gyro_z_rad_s,accel_x_m_s2,accel_y_m_s2,accel_z_m_s2
    joints.csv          t_s,knee_rad,ankle_rad
    events.csv          t_s,kind,source
    groundtruth.txt     TUM trajectory of world_T_camera at frame times
    groundtruth_hf.txt  TUM trajectory of world_T_camera at motion-capture rate (optional)
    scene.yaml          scene ground truth (optional)

The reader decodes frames only when asked (memory does not grow with session length); the
writer streams frames to disk and writes the manifest last, so an interrupted write leaves no
manifest and cannot be mistaken for a complete session.
"""

from __future__ import annotations

import csv
import datetime as _dt
import shutil
from collections.abc import Iterator
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from types import TracebackType

import numpy as np
import yaml

from graph_slam.config import yaml_error_text
from graph_slam.errors import (
    DepthScaleError,
    GraphSlamError,
    RecordError,
    SessionError,
    StreamError,
)
from graph_slam.session import io
from graph_slam.session.manifest import (
    MANIFEST_NAME,
    SCHEMA_VERSION,
    CalibrationSpec,
    CameraSpec,
    FilesSpec,
    ImuSpec,
    IntrinsicsSpec,
    JointsSpec,
    Manifest,
    Provenance,
    SensorsSpec,
    check_relative,
    load_manifest,
    resolve_inside,
)
from graph_slam.session.records import (
    Calibration,
    CameraIntrinsics,
    GaitEvents,
    ImuSeries,
    JointSeries,
    PoseTrajectory,
    RgbdFrame,
    SceneObject,
    SceneTruth,
)
from kinematics.imu import IMU_COLUMNS  # the one IMU CSV schema (also graph-slam gait-events)

JOINT_COLUMNS = ("t_s", "knee_rad", "ankle_rad")
FRAME_COLUMNS = ("index", "t_s", "depth", "color")
EVENT_COLUMNS = ("t_s", "kind", "source")

#: A depth scale is implausible when it puts the median valid depth outside this range (m).
PLAUSIBLE_MEDIAN_DEPTH_M = (0.1, 20.0)


def _wrap_record_error(path: Path, err: RecordError) -> SessionError:
    return SessionError(f"{path}: {err}")


# --------------------------------------------------------------------------- reading


@dataclass(frozen=True)
class FrameIndex:
    """The parsed ``frames.csv``: per-frame time and image paths (relative)."""

    t_s: np.ndarray
    depth: tuple[str, ...]
    color: tuple[str | None, ...]


def _read_frame_index(session_dir: Path, rel: str) -> FrameIndex:
    path = resolve_inside(session_dir, rel, what=f"{MANIFEST_NAME} field 'files.frames'")
    with io.text_errors(path):
        return _read_frame_rows(session_dir, rel, path)


def _read_frame_rows(session_dir: Path, rel: str, path: Path) -> FrameIndex:
    io.read_header(path, FRAME_COLUMNS)
    times: list[float] = []
    depth: list[str] = []
    color: list[str | None] = []
    with path.open("r", encoding="utf-8", newline="") as handle:
        reader = csv.reader(handle)
        next(reader)
        for row, fields in enumerate(reader):
            line = row + 2
            if len(fields) != len(FRAME_COLUMNS):
                raise StreamError(
                    f"{path}: data row {row} (line {line}) has {len(fields)} fields, "
                    f"the header has {len(FRAME_COLUMNS)}"
                )
            index_txt, t_txt, depth_rel, color_rel = (f.strip() for f in fields)
            if index_txt != str(row):
                raise StreamError(
                    f"{path}: data row {row} (line {line}), column 'index': expected {row}, "
                    f"found {index_txt!r}; frames must be numbered 0, 1, 2, ... in order"
                )
            try:
                t = float(t_txt)
            except ValueError:
                raise StreamError(
                    f"{path}: data row {row} (line {line}), column 't_s': {t_txt!r} is not a number"
                ) from None
            if not np.isfinite(t):
                raise StreamError(
                    f"{path}: data row {row} (line {line}), column 't_s': {t_txt!r} is not finite"
                )
            for name, value in (("depth", depth_rel), ("color", color_rel)):
                if value:
                    check_relative(session_dir, value, what=f"{rel} row {row} column {name!r}")
            if not depth_rel:
                raise StreamError(f"{path}: data row {row} (line {line}), column 'depth' is empty")
            times.append(t)
            depth.append(depth_rel)
            color.append(color_rel or None)
    t_s = np.asarray(times, dtype=np.float64)
    io.check_times(path, t_s)
    return FrameIndex(t_s, tuple(depth), tuple(color))


def _read_events(path: Path) -> GaitEvents:
    with io.text_errors(path):
        return _read_event_rows(path)


def _read_event_rows(path: Path) -> GaitEvents:
    io.read_header(path, EVENT_COLUMNS)
    times: list[float] = []
    kinds: list[str] = []
    sources: list[str] = []
    with path.open("r", encoding="utf-8", newline="") as handle:
        reader = csv.reader(handle)
        next(reader)
        for row, fields in enumerate(reader):
            if len(fields) != 3:
                raise StreamError(
                    f"{path}: data row {row} (line {row + 2}) has {len(fields)} fields, expected 3"
                )
            try:
                times.append(float(fields[0]))
            except ValueError:
                raise StreamError(
                    f"{path}: data row {row} (line {row + 2}), column 't_s': "
                    f"{fields[0]!r} is not a number"
                ) from None
            kinds.append(fields[1].strip())
            sources.append(fields[2].strip())
    t_s = np.asarray(times, dtype=np.float64)
    io.check_times(path, t_s)
    try:
        return GaitEvents(t_s, tuple(kinds), tuple(sources))
    except RecordError as err:
        raise _wrap_record_error(path, err) from None


def _scene_from_yaml(path: Path) -> SceneTruth:
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise SessionError(f"{path}: scene file is missing") from None
    except (OSError, UnicodeDecodeError) as err:
        raise SessionError(f"{path}: cannot read ({err})") from None
    except yaml.YAMLError as err:
        raise SessionError(f"{path}: {yaml_error_text(err)}") from None
    if not isinstance(data, dict) or not isinstance(data.get("objects", []), list):
        raise SessionError(f"{path}: must be a mapping with a list 'objects'")
    objects = []
    for i, obj in enumerate(data.get("objects", [])):
        try:
            objects.append(
                SceneObject(
                    name=str(obj["name"]),
                    world_T_object=np.asarray(obj["world_T_object"], dtype=float),
                    size_m=np.asarray(obj["size_m"], dtype=float),
                    kind=str(obj.get("kind", "box")),
                )
            )
        except KeyError as err:
            raise SessionError(f"{path}: objects[{i}] lacks field {err.args[0]!r}") from None
        except (RecordError, TypeError, ValueError) as err:
            raise SessionError(f"{path}: objects[{i}]: {err}") from None
    return SceneTruth(name=str(data.get("name", path.stem)), objects=tuple(objects))


def _scene_to_yaml(scene: SceneTruth) -> str:
    return yaml.safe_dump(
        {
            "name": scene.name,
            "objects": [
                {
                    "name": o.name,
                    "kind": o.kind,
                    "size_m": o.size_m.tolist(),
                    "world_T_object": o.world_T_object.tolist(),
                }
                for o in scene.objects
            ],
        },
        sort_keys=False,
    )


class Session:
    """A recorded session on disk, read lazily.

    Small streams (IMU, joints, events, ground truth) are parsed on first access and cached;
    frames are decoded one at a time by :meth:`frame` / :meth:`iter_frames`.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.manifest: Manifest = load_manifest(self.path)
        cam = self.manifest.sensors.camera
        # A session without a camera (sensors.camera: null) has no frames and no intrinsics.
        self.intrinsics: CameraIntrinsics | None = (
            None if cam is None else CameraIntrinsics(**cam.intrinsics.model_dump())
        )
        self.depth_unit_m: float | None = None if cam is None else cam.depth_unit_m
        self._index = _read_frame_index(self.path, self.manifest.files.frames)
        if cam is None and self._index.t_s.size:
            raise SessionError(
                f"{self.path / MANIFEST_NAME}: field 'sensors.camera' is null but "
                f"{self.manifest.files.frames} lists {self._index.t_s.size} frame(s); "
                "a session without a camera has no frames"
            )
        self._depth_scale_checked = False

    # ---------------------------------------------------------------- metadata
    @property
    def name(self) -> str:
        return self.manifest.name

    @cached_property
    def calibration(self) -> Calibration:
        spec = self.manifest.calibration
        try:
            return Calibration(
                thigh_T_camera=np.asarray(spec.thigh_T_camera),
                camera_T_imu=np.asarray(spec.camera_T_imu),
                imu_time_offset_s=spec.imu_time_offset_s,
                joints_time_offset_s=spec.joints_time_offset_s,
            )
        except RecordError as err:
            raise _wrap_record_error(self.path / MANIFEST_NAME, err) from None

    @property
    def frame_times_s(self) -> np.ndarray:
        return self._index.t_s

    @property
    def n_frames(self) -> int:
        return int(self._index.t_s.size)

    @property
    def n_color_frames(self) -> int:
        """Frames with a colour image (the others were recorded depth-only)."""
        return sum(c is not None for c in self._index.color)

    def __len__(self) -> int:
        return self.n_frames

    def _file(self, field_name: str) -> Path | None:
        rel = getattr(self.manifest.files, field_name)
        if rel is None:
            return None
        return resolve_inside(self.path, rel, what=f"{MANIFEST_NAME} field 'files.{field_name}'")

    # ---------------------------------------------------------------- streams
    @cached_property
    def imu(self) -> ImuSeries | None:
        path = self._file("imu")
        if path is None:
            return None
        data = io.read_numeric_csv(path, IMU_COLUMNS)
        io.check_times(path, data[:, 0])
        return ImuSeries(data[:, 0], data[:, 1:4], data[:, 4:7], source=str(path))

    @cached_property
    def joints(self) -> JointSeries | None:
        path = self._file("joints")
        if path is None:
            return None
        data = io.read_numeric_csv(path, JOINT_COLUMNS)
        io.check_times(path, data[:, 0])
        return JointSeries(data[:, 0], data[:, 1], data[:, 2])

    @cached_property
    def events(self) -> GaitEvents | None:
        path = self._file("events")
        return None if path is None else _read_events(path)

    def _trajectory(self, field_name: str) -> PoseTrajectory | None:
        path = self._file(field_name)
        if path is None:
            return None
        t_s, poses = io.read_tum(path)
        try:
            return PoseTrajectory(t_s, poses, parent="world", child="camera")
        except RecordError as err:
            raise _wrap_record_error(path, err) from None

    @cached_property
    def ground_truth(self) -> PoseTrajectory | None:
        """``world_T_camera`` at frame times (when the session has ground truth)."""
        return self._trajectory("ground_truth")

    @cached_property
    def ground_truth_hf(self) -> PoseTrajectory | None:
        """``world_T_camera`` at motion-capture rate (optional)."""
        return self._trajectory("ground_truth_hf")

    @cached_property
    def scene(self) -> SceneTruth | None:
        path = self._file("scene")
        return None if path is None else _scene_from_yaml(path)

    # ---------------------------------------------------------------- frames
    def frame(self, index: int) -> RgbdFrame:
        """Decode frame ``index`` (strict PNG decoding, size checked against the intrinsics)."""
        if not 0 <= index < self.n_frames:
            raise IndexError(f"frame index {index} out of range 0..{self.n_frames - 1}")
        if self.intrinsics is None or self.depth_unit_m is None:  # pragma: no cover - see __init__
            raise SessionError(f"{self.path}: a session without a camera has no frames")
        hw = self.intrinsics.shape_hw
        depth_path = resolve_inside(self.path, self._index.depth[index], what="frames.csv depth")
        raw = io.read_png(depth_path, expect_mode="depth16", expect_hw=hw)
        depth_m = raw.astype(np.float32) * np.float32(self.depth_unit_m)
        if not self._depth_scale_checked and np.any(raw):
            check_depth_scale(depth_path, depth_m, self.depth_unit_m)
            self._depth_scale_checked = True
        color = None
        color_rel = self._index.color[index]
        if color_rel is not None:
            color_path = resolve_inside(self.path, color_rel, what="frames.csv color")
            color = io.read_png(color_path, expect_mode="rgb8", expect_hw=hw)
        return RgbdFrame(
            t_s=float(self._index.t_s[index]), depth_m=depth_m, color_rgb=color, index=index
        )

    def iter_frames(self, start: int = 0, stop: int | None = None) -> Iterator[RgbdFrame]:
        """Yield frames ``start..stop-1`` one at a time (nothing is kept)."""
        stop = self.n_frames if stop is None else min(stop, self.n_frames)
        for index in range(start, stop):
            yield self.frame(index)

    def __iter__(self) -> Iterator[RgbdFrame]:
        return self.iter_frames()


def open_session(path: str | Path) -> Session:
    """Open a session folder (manifest and frame index are checked; frames stay on disk)."""
    return Session(path)


# --------------------------------------------------------------------------- writing


class SessionWriter:
    """Write a session folder, streaming frames to disk.

    Use as a context manager; the manifest is written on a clean exit only::

        with SessionWriter(out, name="walk", intrinsics=K, depth_unit_m=2e-4) as writer:
            for frame in frames:
                writer.add_frame(frame)
            writer.write_imu(imu)

    ``intrinsics=None`` writes a session without a camera (``sensors.camera: null``, zero
    frames), e.g. IMU and ground truth only.
    """

    def __init__(
        self,
        path: str | Path,
        *,
        name: str,
        intrinsics: CameraIntrinsics | None,
        depth_unit_m: float = 2e-4,
        camera_profile: str = "unknown",
        camera_rate_hz: float | None = None,
        imu_profile: str = "unknown",
        imu_rate_hz: float | None = None,
        joints_rate_hz: float | None = None,
        calibration: Calibration | None = None,
        provenance: Provenance | None = None,
        overwrite: bool = False,
    ) -> None:
        self.path = Path(path)
        self._name = name
        if self.path.exists():
            if not overwrite:
                raise SessionError(f"{self.path}: already exists (pass --overwrite to replace it)")
            if not (self.path / MANIFEST_NAME).is_file() and any(self.path.iterdir()):
                raise SessionError(
                    f"{self.path}: exists, is not empty and is not a session; refusing to overwrite"
                )
            shutil.rmtree(self.path)
        self.path.mkdir(parents=True)
        if intrinsics is not None:
            (self.path / "depth").mkdir()
        self.intrinsics = intrinsics
        self.depth_unit_m = float(depth_unit_m)
        self._camera = dict(profile=camera_profile, nominal_rate_hz=camera_rate_hz)
        self._imu_spec = ImuSpec(profile=imu_profile, nominal_rate_hz=imu_rate_hz)
        self._joints_rate_hz = joints_rate_hz
        self.calibration = calibration or Calibration()
        self.provenance = provenance or Provenance(generator="graph_slam")
        self._files: dict[str, str | None] = {}
        self._frames_handle = (self.path / "frames.csv").open("w", encoding="utf-8", newline="\n")
        self._frames_handle.write(",".join(FRAME_COLUMNS) + "\n")
        self._n_frames = 0
        self._has_color: bool | None = None
        self._last_t: float | None = None
        self._closed = False

    # ---------------------------------------------------------------- frames
    def add_frame(self, frame: RgbdFrame) -> None:
        """Quantise the depth to the 16-bit unit and write the frame's PNGs and index row."""
        if self.intrinsics is None:
            raise SessionError(
                f"{self.path}: this session has no camera (intrinsics=None); no frames"
            )
        hw = self.intrinsics.shape_hw
        if frame.depth_m.shape != hw:
            raise SessionError(
                f"{self.path}: frame {self._n_frames} depth is {frame.depth_m.shape} (H×W) but the "
                f"intrinsics say {hw}"
            )
        if self._last_t is not None and frame.t_s <= self._last_t:
            raise SessionError(
                f"{self.path}: frame {self._n_frames} t_s={frame.t_s!r} does not increase "
                f"(previous {self._last_t!r})"
            )
        # Colour may be missing in some frames (a depth frame without a colour image close
        # enough in time is kept depth-only): its row leaves the colour column empty.
        has_color = frame.color_rgb is not None
        if has_color and not self._has_color:
            (self.path / "color").mkdir(exist_ok=True)
            self._has_color = True
        units = np.rint(frame.depth_m / self.depth_unit_m)
        max_units = np.iinfo(np.uint16).max
        if units.max(initial=0) > max_units:
            raise SessionError(
                f"{self.path}: frame {self._n_frames} has depth up to "
                f"{float(frame.depth_m.max()):.3f} m, "
                f"beyond the 16-bit range {max_units * self.depth_unit_m:.3f} m of depth_unit_m="
                f"{self.depth_unit_m}; choose a larger unit"
            )
        name = f"{self._n_frames:06d}.png"
        io.write_png(self.path / "depth" / name, units.astype(np.uint16))
        color_rel = ""
        if has_color:
            io.write_png(self.path / "color" / name, np.asarray(frame.color_rgb))
            color_rel = f"color/{name}"
        self._frames_handle.write(f"{self._n_frames},{frame.t_s:.9f},depth/{name},{color_rel}\n")
        self._n_frames += 1
        self._last_t = frame.t_s

    # ---------------------------------------------------------------- streams
    def write_imu(self, imu: ImuSeries, *, filename: str = "imu.csv") -> None:
        io.write_numeric_csv(
            self.path / filename,
            IMU_COLUMNS,
            np.column_stack([imu.t_s, imu.gyro_rad_s, imu.accel_m_s2]),
        )
        self._files["imu"] = filename

    def write_joints(self, joints: JointSeries, *, filename: str = "joints.csv") -> None:
        io.write_numeric_csv(
            self.path / filename,
            JOINT_COLUMNS,
            np.column_stack([joints.t_s, joints.knee_rad, joints.ankle_rad]),
        )
        self._files["joints"] = filename

    def write_events(self, events: GaitEvents, *, filename: str = "events.csv") -> None:
        with (self.path / filename).open("w", encoding="utf-8", newline="\n") as handle:
            handle.write(",".join(EVENT_COLUMNS) + "\n")
            for t, kind, source in zip(events.t_s, events.kind, events.source, strict=True):
                handle.write(f"{t:.9f},{kind},{source}\n")
        self._files["events"] = filename

    def write_ground_truth(self, trajectory: PoseTrajectory, *, high_rate: bool = False) -> None:
        """``world_T_camera`` in TUM format: at frame times, or at mocap rate (``high_rate``)."""
        if (trajectory.parent, trajectory.child) != ("world", "camera"):
            raise SessionError(f"ground truth must be world_T_camera, got {trajectory.name}")
        filename = "groundtruth_hf.txt" if high_rate else "groundtruth.txt"
        io.write_tum(self.path / filename, trajectory.t_s, trajectory.parent_T_child)
        self._files["ground_truth_hf" if high_rate else "ground_truth"] = filename

    def write_scene(self, scene: SceneTruth) -> None:
        (self.path / "scene.yaml").write_text(_scene_to_yaml(scene), encoding="utf-8")
        self._files["scene"] = "scene.yaml"

    # ---------------------------------------------------------------- finish
    def close(self) -> Path:
        """Write the manifest (last) and return the session path."""
        if self._closed:
            return self.path
        self._frames_handle.close()
        cal = self.calibration
        manifest = Manifest(
            schema_version=SCHEMA_VERSION,
            name=self._name,
            sensors=SensorsSpec(
                camera=None
                if self.intrinsics is None
                else CameraSpec(
                    intrinsics=IntrinsicsSpec(**_intrinsics_dict(self.intrinsics)),
                    depth_unit_m=self.depth_unit_m,
                    has_color=bool(self._has_color),
                    **self._camera,
                ),
                imu=self._imu_spec if "imu" in self._files else None,
                joints=JointsSpec(nominal_rate_hz=self._joints_rate_hz)
                if "joints" in self._files
                else None,
            ),
            calibration=CalibrationSpec(
                thigh_T_camera=cal.thigh_T_camera.tolist(),
                camera_T_imu=cal.camera_T_imu.tolist(),
                imu_time_offset_s=cal.imu_time_offset_s,
                joints_time_offset_s=cal.joints_time_offset_s,
            ),
            files=FilesSpec(frames="frames.csv", **self._files),
            provenance=self.provenance.model_copy(
                update={"created_utc": self.provenance.created_utc or _utc_now()}
            ),
        )
        (self.path / MANIFEST_NAME).write_text(manifest.to_yaml(), encoding="utf-8")
        self._closed = True
        return self.path

    def __enter__(self) -> SessionWriter:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if exc_type is None:
            self.close()
        else:
            self._frames_handle.close()


def _intrinsics_dict(k: CameraIntrinsics) -> dict[str, float | int]:
    return {
        "width_px": int(k.width_px),
        "height_px": int(k.height_px),
        "fx_px": float(k.fx_px),
        "fy_px": float(k.fy_px),
        "cx_px": float(k.cx_px),
        "cy_px": float(k.cy_px),
    }


def _utc_now() -> str:
    return _dt.datetime.now(_dt.UTC).replace(microsecond=0).isoformat()


# --------------------------------------------------------------------------- validation


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


def check_depth_scale(path: Path, depth_m: np.ndarray, depth_unit_m: float) -> None:
    """The median valid depth must be plausible for a body-worn camera (0.1–20 m)."""
    valid = depth_m[depth_m > 0]
    if valid.size == 0:
        return
    median = float(np.median(valid))
    lo, hi = PLAUSIBLE_MEDIAN_DEPTH_M
    if not lo <= median <= hi:
        raise DepthScaleError(
            f"{path}: with depth_unit_m={depth_unit_m} the median valid depth is {median:.4g} m, "
            f"outside the plausible {lo}–{hi} m; the manifest's depth scale is probably wrong"
        )


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
    for stream in (
        "calibration",
        "imu",
        "joints",
        "events",
        "ground_truth",
        "ground_truth_hf",
        "scene",
    ):
        try:
            value = getattr(session, stream)
        except GraphSlamError as err:
            report.problems.append(err)
            continue
        if value is not None and hasattr(value, "__len__"):
            report.counts[stream] = len(value)
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
                depth_path = session.path / session._index.depth[index]
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
    if not report.problems:
        _check_plausibility(session, report, variants or [])
    return report


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

"""Reading a session folder lazily: :class:`Session` and :func:`open_session`.

Opening a session checks its manifest (``session.yaml``) and frame index (``frames.csv``).
Small streams (IMU, joints, events, ground truth, scene) are parsed on first access; frames are
decoded only when asked, one at a time, so memory does not grow with session length. The folder
layout is in :mod:`graph_slam.session.format` and docs/session_format.md.
"""

from __future__ import annotations

from collections.abc import Iterator
from functools import cached_property
from pathlib import Path

import numpy as np

from graph_slam.errors import RecordError, SessionError
from graph_slam.session import io
from graph_slam.session.files import (
    IMU_COLUMNS,
    JOINT_COLUMNS,
    FrameIndex,
    check_depth_scale,
    read_events,
    read_frame_index,
    scene_from_yaml,
    wrap_record_error,
)
from graph_slam.session.manifest import MANIFEST_NAME, Manifest, load_manifest, resolve_inside
from graph_slam.session.records import (
    Calibration,
    CameraIntrinsics,
    GaitEvents,
    ImuSeries,
    JointSeries,
    PoseTrajectory,
    RgbdFrame,
    SceneTruth,
)

__all__ = ["Session", "open_session"]


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
        self._index = read_frame_index(self.path, self.manifest.files.frames)
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
            raise wrap_record_error(self.path / MANIFEST_NAME, err) from None

    @property
    def frame_index(self) -> FrameIndex:
        """The parsed ``frames.csv``: per-frame times and image paths relative to :attr:`path`."""
        return self._index

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
        return None if path is None else read_events(path)

    def _trajectory(self, field_name: str) -> PoseTrajectory | None:
        path = self._file(field_name)
        if path is None:
            return None
        t_s, poses = io.read_tum(path)
        try:
            return PoseTrajectory(t_s, poses, parent="world", child="camera")
        except RecordError as err:
            raise wrap_record_error(path, err) from None

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
        return None if path is None else scene_from_yaml(path)

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

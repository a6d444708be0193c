"""Writing a session folder: :class:`SessionWriter`.

Frames are streamed to disk as they come (depth quantised to the manifest's 16-bit unit);
streams are written whole; the manifest (``session.yaml``) is written last, on a clean close
only, so an interrupted write leaves no manifest and cannot be mistaken for a complete
session. The folder layout is in :mod:`graph_slam.session.format` and docs/session_format.md.
"""

from __future__ import annotations

import datetime as _dt
import shutil
from pathlib import Path
from types import TracebackType

import numpy as np

from graph_slam.errors import SessionError
from graph_slam.session import io
from graph_slam.session.files import (
    EVENT_COLUMNS,
    FRAME_COLUMNS,
    IMU_COLUMNS,
    JOINT_COLUMNS,
    scene_to_yaml,
)
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
)
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

__all__ = ["SessionWriter"]


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
        (self.path / "scene.yaml").write_text(scene_to_yaml(scene), encoding="utf-8")
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

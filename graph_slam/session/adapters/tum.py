"""TUM RGB-D folders (Sturm et al., IROS 2012): ``rgb.txt``, ``depth.txt``, ``groundtruth.txt``
and, when present, ``accelerometer.txt``.

- Depth PNGs are 16-bit, 5000 units per metre (``tum.depth_units_per_m``); 0 = no reading.
- Each depth frame is paired one-to-one with the colour image nearest in time, within
  ``association.max_color_dt_s`` (TUM's ``associate.py`` rule); the frame's time is the depth
  stamp. Unpaired depth frames and colour images are dropped and counted.
- Intrinsics by name (fr1, fr2, fr3 — TUM's published calibration of each Kinect) or given.
  TUM's images are not undistorted; the distortion of fr1/fr2 is not applied here.
- ``groundtruth.txt`` (world_T_camera of the colour camera, motion capture) becomes the
  session's high-rate ground truth, and is interpolated at the frame times (only between two
  samples at most ``association.max_ground_truth_gap_s`` apart).
- ``accelerometer.txt`` (Kinect accelerometer, no gyroscope) is read and counted but not
  converted: the session's IMU stream needs both.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from graph_slam.errors import ConversionError, MissingStreamError
from graph_slam.session import io
from graph_slam.session.adapters.base import (
    ConversionReport,
    Recording,
    StreamReport,
    resolve_in_folder,
)
from graph_slam.session.adapters.config import ConvertConfig, IntrinsicsConfig
from graph_slam.session.adapters.timing import associate, check_depth_units, interpolate_poses
from graph_slam.session.records import CameraIntrinsics, PoseTrajectory, RgbdFrame

#: TUM's published intrinsics of the three Kinects (640×480): fx, fy, cx, cy.
TUM_INTRINSICS: dict[str, tuple[float, float, float, float]] = {
    "fr1": (517.3, 516.5, 318.6, 255.3),
    "fr2": (520.9, 521.0, 325.1, 249.7),
    "fr3": (535.4, 539.2, 320.1, 247.6),
}
TUM_SIZE = (640, 480)
_CAMERA_IN_NAME = re.compile(r"(?:freiburg|fr)([123])(?![0-9])", re.IGNORECASE)
#: Frames sampled (evenly) for the depth-units check.
DEPTH_CHECK_FRAMES = 5


def tum_intrinsics(name: str) -> CameraIntrinsics:
    """Intrinsics of TUM's fr1, fr2 or fr3 Kinect."""
    if name not in TUM_INTRINSICS:
        raise ConversionError(f"unknown TUM camera {name!r}; known: {sorted(TUM_INTRINSICS)}")
    fx, fy, cx, cy = TUM_INTRINSICS[name]
    return CameraIntrinsics(TUM_SIZE[0], TUM_SIZE[1], fx, fy, cx, cy)


def camera_from_folder_name(folder: Path) -> str | None:
    """'fr1' for ``rgbd_dataset_freiburg1_xyz`` or ``tum_fr1_xyz``; None when not named."""
    match = _CAMERA_IN_NAME.search(folder.resolve().name)
    return f"fr{match.group(1)}" if match else None


@dataclass(frozen=True)
class TumList:
    """A parsed ``rgb.txt`` / ``depth.txt``: stamps and file names, as listed."""

    path: Path
    t_s: np.ndarray
    files: tuple[str, ...]


def read_tum_list(path: Path) -> TumList:
    """Read ``timestamp filename`` lines (``#`` comments); stamps must strictly increase."""
    lines = io.read_text(path, MissingStreamError, ConversionError).splitlines()
    times: list[float] = []
    files: list[str] = []
    for line_no, line in enumerate(lines, start=1):
        text = line.strip()
        if not text or text.startswith("#"):
            continue
        fields = text.split()
        if len(fields) != 2:
            raise ConversionError(
                f"{path}: line {line_no}: expected 2 fields 'timestamp filename', found {len(fields)}"
            )
        try:
            t = float(fields[0])
        except ValueError:
            raise ConversionError(
                f"{path}: line {line_no}: timestamp {fields[0]!r} is not a number"
            ) from None
        if not np.isfinite(t):
            raise ConversionError(f"{path}: line {line_no}: timestamp is not finite")
        if times and t <= times[-1]:
            raise ConversionError(
                f"{path}: line {line_no}: timestamps must strictly increase "
                f"({times[-1]!r} then {t!r})"
            )
        times.append(t)
        files.append(fields[1])
    return TumList(path, np.asarray(times, dtype=np.float64), tuple(files))


def read_tum_accelerometer(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """``accelerometer.txt``: ``timestamp ax ay az`` → (t_s, N×3 values as written)."""
    rows: list[list[float]] = []
    for line_no, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
        text = line.strip()
        if not text or text.startswith("#"):
            continue
        fields = text.split()
        if len(fields) != 4:
            raise ConversionError(
                f"{path}: line {line_no}: expected 4 fields 'timestamp ax ay az', found {len(fields)}"
            )
        try:
            rows.append([float(f) for f in fields])
        except ValueError:
            raise ConversionError(f"{path}: line {line_no}: not all fields are numbers") from None
    data = np.asarray(rows, dtype=np.float64).reshape(-1, 4)
    return data[:, 0].copy(), data[:, 1:].copy()


def _intrinsics(folder: Path, config: ConvertConfig) -> tuple[CameraIntrinsics, str, str]:
    """(intrinsics, camera name, how it was chosen)."""
    tum = config.tum
    if tum.intrinsics is not None:
        return CameraIntrinsics(**tum.intrinsics.model_dump()), "given", "tum.intrinsics"
    if tum.camera != "auto":
        return tum_intrinsics(tum.camera), tum.camera, "tum.camera"
    name = camera_from_folder_name(folder)
    if name is None:
        raise ConversionError(
            f"{folder}: cannot tell the TUM camera (fr1, fr2, fr3) from the folder name; "
            "set tum.camera or tum.intrinsics in the conversion config"
        )
    return tum_intrinsics(name), name, f"folder name {folder.resolve().name!r}"


class TumRgbdAdapter:
    """TUM RGB-D benchmark folders."""

    name = "tum"
    summary = "TUM RGB-D folder (rgb.txt, depth.txt, groundtruth.txt, accelerometer.txt)"

    def detect(self, path: Path) -> bool:
        return path.is_dir() and (path / "depth.txt").is_file() and (path / "rgb.txt").is_file()

    def open(self, path: Path, config: ConvertConfig) -> Recording:
        folder = Path(path)
        if not (folder / "depth.txt").is_file():
            found = sorted(p.name for p in folder.iterdir()) if folder.is_dir() else []
            raise MissingStreamError(
                f"{folder}: no depth.txt; a TUM RGB-D folder holds rgb.txt and depth.txt "
                f"(found: {', '.join(found) or 'nothing'})"
            )
        report = ConversionReport(adapter=self.name, source=str(folder))
        depth = read_tum_list(folder / "depth.txt")
        rgb = read_tum_list(folder / "rgb.txt") if (folder / "rgb.txt").is_file() else None
        intrinsics, camera, chosen_by = _intrinsics(folder, config)
        report.notes.append(f"intrinsics {camera} (chosen by {chosen_by})")
        max_dt = config.association.max_color_dt_s

        if rgb is not None:
            i_depth, i_rgb = associate(depth.t_s, rgb.t_s, max_dt)
            report.add(
                StreamReport(
                    "color",
                    "rgb.txt",
                    rgb.t_s.size,
                    i_rgb.size,
                    {f"no depth frame within {max_dt} s": rgb.t_s.size - i_rgb.size},
                )
            )
            dropped = {f"no colour image within {max_dt} s": depth.t_s.size - i_depth.size}
        else:
            i_depth, i_rgb = np.arange(depth.t_s.size), None
            dropped = {}
            report.notes.append("no rgb.txt: frames without colour")
        report.add(StreamReport("frames", "depth.txt", depth.t_s.size, i_depth.size, dropped))

        # Every listed path must stay inside the folder (checked for all, used or not).
        all_depth = [
            resolve_in_folder(folder, name, what=f"{depth.path} entry {i}")
            for i, name in enumerate(depth.files)
        ]
        all_rgb = (
            []
            if rgb is None
            else [
                resolve_in_folder(folder, name, what=f"{rgb.path} entry {j}")
                for j, name in enumerate(rgb.files)
            ]
        )
        depth_paths = [all_depth[i] for i in i_depth]
        rgb_paths = None if i_rgb is None else [all_rgb[j] for j in i_rgb]
        unit_m = 1.0 / config.tum.depth_units_per_m
        hw = intrinsics.shape_hw
        if depth_paths:
            picks = np.unique(np.linspace(0, len(depth_paths) - 1, DEPTH_CHECK_FRAMES).astype(int))
            samples = [
                io.read_png(depth_paths[k], expect_mode="depth16", expect_hw=hw) for k in picks
            ]
            check_depth_units(
                samples,
                unit_m,
                where=str(folder / "depth.txt"),
                unit_source=f"tum.depth_units_per_m = {config.tum.depth_units_per_m:g}",
                fix="set tum.depth_units_per_m",
            )
        frame_t = depth.t_s[i_depth]

        ground_truth = ground_truth_hf = None
        gt_path = folder / "groundtruth.txt"
        if gt_path.is_file():
            t_gt, poses = io.read_tum(gt_path)
            ground_truth_hf = PoseTrajectory(t_gt, poses)
            report.add(StreamReport("ground_truth_hf", gt_path.name, t_gt.size, t_gt.size))
            max_gap = config.association.max_ground_truth_gap_s
            mask, at_frames = interpolate_poses(t_gt, poses, frame_t, max_gap)
            inside = (frame_t >= t_gt[0]) & (frame_t <= t_gt[-1]) if t_gt.size else mask
            report.add(
                StreamReport(
                    "ground_truth",
                    f"{gt_path.name} at frame times",
                    frame_t.size,
                    int(mask.sum()),
                    {
                        "frame outside the ground-truth span": int((~inside).sum()),
                        f"ground-truth samples around the frame > {max_gap} s apart": int(
                            (inside & ~mask).sum()
                        ),
                    },
                )
            )
            if mask.any():
                ground_truth = PoseTrajectory(frame_t[mask], at_frames)
        else:
            report.notes.append("no groundtruth.txt")

        acc_path = folder / "accelerometer.txt"
        if acc_path.is_file():
            t_acc, _ = read_tum_accelerometer(acc_path)
            report.add(
                StreamReport(
                    "accelerometer",
                    acc_path.name,
                    t_acc.size,
                    0,
                    {"not converted: the session's IMU stream needs a gyroscope": t_acc.size},
                )
            )

        output_unit = config.output.depth_unit_m or unit_m
        resolved = config.model_copy(
            update={
                "format": self.name,
                "tum": config.tum.model_copy(
                    update={
                        "camera": camera if camera in TUM_INTRINSICS else config.tum.camera,
                        "intrinsics": IntrinsicsConfig(
                            width_px=intrinsics.width_px,
                            height_px=intrinsics.height_px,
                            fx_px=intrinsics.fx_px,
                            fy_px=intrinsics.fy_px,
                            cx_px=intrinsics.cx_px,
                            cy_px=intrinsics.cy_px,
                        ),
                    }
                ),
            }
        )

        def frames() -> Iterator[RgbdFrame]:
            scale = np.float32(unit_m)
            for k, (t, dpath) in enumerate(zip(frame_t, depth_paths, strict=True)):
                raw = io.read_png(dpath, expect_mode="depth16", expect_hw=hw)
                color = (
                    None
                    if rgb_paths is None
                    else io.read_png(rgb_paths[k], expect_mode="rgb8", expect_hw=hw)
                )
                yield RgbdFrame(
                    t_s=float(t), depth_m=raw.astype(np.float32) * scale, color_rgb=color, index=k
                )

        return Recording(
            name=folder.resolve().name,
            report=report,
            resolved=resolved,
            intrinsics=intrinsics,
            depth_unit_m=output_unit,
            frame_times_s=frame_t,
            frames=frames,
            ground_truth=ground_truth,
            ground_truth_hf=ground_truth_hf,
            camera_profile=f"tum-{camera}",
        )

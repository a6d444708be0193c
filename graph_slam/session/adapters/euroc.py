"""EuRoC MAV / ASL folders (Burri et al., IJRR 2016): IMU CSV and ground truth.

- IMU: ``timestamp [ns], w_RS_S_x/y/z [rad/s], a_RS_S_x/y/z [m/s²]`` (``imu0/data.csv``).
- Ground truth: the ASL CSV (``timestamp [ns], p_RS_R_x/y/z [m], q_RS_w/x/y/z, ...``, e.g.
  ``state_groundtruth_estimate0/data.csv`` or ``vicon0/data.csv``) or a TUM file
  (``t tx ty tz qx qy qz qw``, seconds, e.g. ``V101_gt.txt``). It is the pose of the body frame,
  which for EuRoC's ``imu0`` is the IMU frame (its ``T_BS`` is the identity).

The images of EuRoC (grayscale stereo, no depth) are not converted: the session has no camera
(``sensors.camera: null``, zero frames). By the convention of camera-less sessions,
``camera_T_imu`` is the identity, so the ground truth stored as ``world_T_camera`` is the pose
of the IMU; it is written at its own rate (``groundtruth_hf.txt``), since there are no frames.
"""

from __future__ import annotations

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
from graph_slam.session.adapters.config import ConvertConfig
from graph_slam.session.adapters.timing import order_stamps
from graph_slam.session.records import ImuSeries, PoseTrajectory

IMU_CANDIDATES = ("mav0/imu0/data.csv", "imu0/data.csv", "imu0_data.csv")
GT_CANDIDATES = (
    "mav0/state_groundtruth_estimate0/data.csv",
    "state_groundtruth_estimate0/data.csv",
    "mav0/vicon0/data.csv",
    "vicon0/data.csv",
    "groundtruth.txt",
)


def _rows(path: Path, n_fields: int, what: str) -> tuple[np.ndarray, np.ndarray]:
    """Comma-separated rows after a ``#`` header: (int64 ns stamps, N×(n_fields-1) floats).

    At least ``n_fields`` fields per row (extra ones are ignored).
    """
    lines = io.read_text(path, MissingStreamError, ConversionError).splitlines()
    if not lines or not lines[0].startswith("#"):
        raise ConversionError(f"{path}: the first line must be the '#timestamp [ns],...' header")
    stamps: list[int] = []
    values: list[list[float]] = []
    for line_no, line in enumerate(lines[1:], start=2):
        text = line.strip()
        if not text:
            continue
        fields = text.split(",")
        if len(fields) < n_fields:
            raise ConversionError(
                f"{path}: line {line_no}: {what} rows have at least {n_fields} fields, "
                f"found {len(fields)}"
            )
        try:
            stamps.append(int(fields[0]))
        except ValueError:
            raise ConversionError(
                f"{path}: line {line_no}: timestamp {fields[0]!r} is not an integer (nanoseconds)"
            ) from None
        try:
            values.append([float(f) for f in fields[1:n_fields]])
        except ValueError:
            raise ConversionError(f"{path}: line {line_no}: not all fields are numbers") from None
    return np.asarray(stamps, dtype=np.int64), np.asarray(values, dtype=np.float64).reshape(
        -1, n_fields - 1
    )


def read_euroc_imu(path: Path) -> tuple[ImuSeries, StreamReport]:
    """Read an ASL IMU CSV; samples are put in time order, duplicate stamps and rows with NaN
    or inf are dropped, all counted in the returned report."""
    stamps_ns, values = _rows(path, 7, "IMU")
    finite = np.isfinite(values).all(axis=1)
    order = order_stamps(stamps_ns[finite])
    kept = np.flatnonzero(finite)[order.keep]
    t_s = stamps_ns[kept] * 1e-9
    report = StreamReport(
        "imu",
        path.name,
        int(stamps_ns.size),
        int(kept.size),
        {"NaN or inf": int((~finite).sum()), "duplicate stamp": order.duplicates},
    )
    if order.reordered:
        report.notes.append(f"{order.reordered} sample(s) out of time order, sorted")
    return ImuSeries(t_s, values[kept, 0:3], values[kept, 3:6]), report


def read_asl_ground_truth(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """ASL ground-truth CSV → (t_s, N×4×4 world_T_body); quaternion w first, norm within 1e-3."""
    from scipy.spatial.transform import Rotation

    stamps_ns, values = _rows(path, 8, "ground-truth")
    if not np.isfinite(values).all():
        raise ConversionError(f"{path}: ground truth holds NaN or inf")
    quat_wxyz = values[:, 3:7]
    norm = np.linalg.norm(quat_wxyz, axis=1)
    bad = np.flatnonzero(np.abs(norm - 1.0) > 1e-3)
    if bad.size:
        raise ConversionError(
            f"{path}: line {int(bad[0]) + 2}: quaternion norm {norm[bad[0]]:.6f} is not 1 "
            f"(tolerance 1e-3; {bad.size} row(s))"
        )
    poses = np.tile(np.eye(4), (stamps_ns.size, 1, 1))
    if stamps_ns.size:
        poses[:, :3, :3] = Rotation.from_quat(quat_wxyz[:, [1, 2, 3, 0]]).as_matrix()
        poses[:, :3, 3] = values[:, 0:3]
    t_s = stamps_ns * 1e-9
    if t_s.size > 1 and np.any(np.diff(stamps_ns) <= 0):
        row = int(np.flatnonzero(np.diff(stamps_ns) <= 0)[0]) + 1
        raise ConversionError(
            f"{path}: line {row + 2}: timestamps must strictly increase in ground truth"
        )
    return t_s, poses


def _find(folder: Path, given: str | None, candidates: tuple[str, ...], what: str) -> Path | None:
    if given is not None:
        path = resolve_in_folder(folder, given, what=f"euroc.{what}")
        if not path.is_file():
            raise MissingStreamError(f"{path}: euroc.{what} names a file that does not exist")
        return path
    for rel in candidates:
        if (folder / rel).is_file():
            return folder / rel
    return None


class EurocAdapter:
    """EuRoC / ASL folders: IMU and ground truth (no camera)."""

    name = "euroc"
    summary = "EuRoC / ASL folder (imu0/data.csv, ground-truth CSV or TUM file); no camera"

    def detect(self, path: Path) -> bool:
        return path.is_dir() and any((path / rel).is_file() for rel in IMU_CANDIDATES)

    def open(self, path: Path, config: ConvertConfig) -> Recording:
        folder = Path(path)
        imu_path = _find(folder, config.euroc.imu_csv, IMU_CANDIDATES, "imu_csv")
        if imu_path is None:
            found = sorted(p.name for p in folder.iterdir()) if folder.is_dir() else []
            raise MissingStreamError(
                f"{folder}: no EuRoC IMU file (looked for {', '.join(IMU_CANDIDATES)}; "
                f"found: {', '.join(found) or 'nothing'}); set euroc.imu_csv"
            )
        report = ConversionReport(adapter=self.name, source=str(folder))
        imu, imu_report = read_euroc_imu(imu_path)
        imu_report.source = imu_path.relative_to(folder).as_posix()
        report.add(imu_report)

        gt_path = _find(folder, config.euroc.ground_truth, GT_CANDIDATES, "ground_truth")
        if gt_path is None and config.euroc.ground_truth is None:
            tum_files = sorted(folder.glob("*_gt.txt"))
            if len(tum_files) > 1:
                raise ConversionError(
                    f"{folder}: several ground-truth files {[p.name for p in tum_files]}; "
                    "choose one with euroc.ground_truth"
                )
            gt_path = tum_files[0] if tum_files else None
        ground_truth_hf = None
        if gt_path is not None:
            if gt_path.suffix == ".csv":
                t_gt, poses = read_asl_ground_truth(gt_path)
            else:
                t_gt, poses = io.read_tum(gt_path)
            # Camera-less session: camera_T_imu = I, so world_T_camera is world_T_imu (= body).
            ground_truth_hf = PoseTrajectory(t_gt, poses, parent="world", child="camera")
            report.add(
                StreamReport(
                    "ground_truth_hf", gt_path.relative_to(folder).as_posix(), t_gt.size, t_gt.size
                )
            )
            report.notes.append(
                "no camera: ground truth is the pose of the IMU (body) frame, stored as "
                "world_T_camera with camera_T_imu = identity"
            )
        else:
            report.notes.append("no ground-truth file found")
        if (folder / "mav0" / "cam0").is_dir() or (folder / "cam0").is_dir():
            report.notes.append("cam0/cam1 images (grayscale, no depth) are not converted")
        resolved = config.model_copy(
            update={
                "format": self.name,
                "euroc": config.euroc.model_copy(
                    update={
                        "imu_csv": imu_path.relative_to(folder).as_posix(),
                        "ground_truth": None
                        if gt_path is None
                        else gt_path.relative_to(folder).as_posix(),
                    }
                ),
            }
        )
        return Recording(
            name=folder.resolve().name,
            report=report,
            resolved=resolved,
            imu=imu,
            ground_truth_hf=ground_truth_hf,
            imu_profile="euroc-imu0",
        )

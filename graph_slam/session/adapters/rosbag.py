"""ROS 1 (``.bag``) and ROS 2 (``.db3``, ``.mcap``, or their folder with ``metadata.yaml``) bags,
read with the ``rosbags`` library (no ROS installation; the optional extra ``bags``).

Topics are chosen by a preset (RealSense SDK recordings, the RealSense ROS wrapper) or given
explicitly in ``bag:`` of the conversion config; see docs/adapters.md. The bag is read twice:
once for stamps, metadata and the small streams (IMU, joints, events), then frame by frame
while the session is written. Stamps are ``header.stamp`` (or the bag's receive time with
``bag.stamps: bag``); messages are put in stamp order and exact duplicate stamps are dropped,
all counted in the report.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from graph_slam.errors import ConversionError, MissingStreamError
from graph_slam.session.adapters.align import CameraModel
from graph_slam.session.adapters.bag_calibration import (
    BagCalibration,
    camera_model_from_info,
    extrinsic_entry,
    imu_intrinsics_entries,
    intrinsics_of,
    resolve_bag_calibration,
    sdk_imu_intrinsic_topics,
    sdk_tf_topics,
)
from graph_slam.session.adapters.bag_frames import (
    FrameSource,
    color_plan,
    frame_reader,
    pair_frames,
)
from graph_slam.session.adapters.bag_images import image_array
from graph_slam.session.adapters.bag_reader import Bag, bag_path
from graph_slam.session.adapters.bag_scan import (
    Collected,
    first_pass,
    sdk_metadata_topics,
    use_metadata_stamps,
)
from graph_slam.session.adapters.bag_sdk import device_info
from graph_slam.session.adapters.bag_streams import imu_series, joints_events, zero_stamps
from graph_slam.session.adapters.bag_topics import TopicChoice, listing, resolve_topics
from graph_slam.session.adapters.base import ConversionReport, Recording
from graph_slam.session.adapters.config import ConvertConfig
from graph_slam.session.adapters.timing import check_depth_units
from graph_slam.session.records import Calibration

__all__ = ["RosbagAdapter", "bag_path", "image_array", "resolve_topics"]

#: REP 118: 16UC1 depth images are in millimetres.
DEFAULT_DEPTH_UNIT_M = 1e-3
#: Float depth is written to the session with this unit unless output.depth_unit_m says otherwise
#: (0.1 mm quantisation, 13.1 m range).
FLOAT_DEPTH_SESSION_UNIT_M = 2e-4


@dataclass(frozen=True)
class _Scan:
    """The first pass: topics in the bag, the topics chosen, what was gathered."""

    topics: dict[str, str | None]
    choice: TopicChoice
    got: Collected
    is_ros2: bool


class RosbagAdapter:
    """ROS 1 and ROS 2 bags via rosbags."""

    name = "rosbag"
    summary = "ROS 1 .bag or ROS 2 bag (.db3, .mcap, folder); presets realsense-sdk/realsense-ros"

    def detect(self, path: Path) -> bool:
        if path.is_file():
            return path.suffix in (".bag", ".db3", ".mcap") or path.name.endswith(".bag.active")
        # A folder of .db3/.mcap files without metadata.yaml is claimed too, to say how to fix it.
        return path.is_dir() and (
            (path / "metadata.yaml").is_file()
            or any(p.suffix in (".db3", ".mcap") for p in path.iterdir())
        )

    def open(self, path: Path, config: ConvertConfig) -> Recording:
        path = Path(path)
        cfg = config.bag
        report = ConversionReport(adapter=self.name, source=str(path))
        scan = _scan(path, config, report)
        choice, got = scan.choice, scan.got
        depth_model, unit_m, session_unit, encoding = _camera(
            path, choice, got, cfg, config, report, scan.is_ros2
        )
        calib = _calibration(scan, config, report)
        plan = color_plan(path, choice, got, cfg, calib, depth_model, report)
        depth_kept, color_pos, frames_report = pair_frames(choice, got, config, plan, report)
        frame_t = np.asarray(got.depth_ns, dtype=np.int64)[depth_kept] * 1e-9
        imu = imu_series(got, choice, cfg, report, calib.gyro_R_accel)
        joints, events = joints_events(got, choice, cfg, report)
        calibration = Calibration()
        if calib.camera_T_imu is not None:
            calibration = Calibration(camera_T_imu=calib.camera_T_imu.pose)
            report.calibration["camera_T_imu"] = extrinsic_entry(calib.camera_T_imu)
        elif imu is not None:
            report.notes.append(
                "no depth→IMU extrinsics in the bag (librealsense 2.5x records none for its "
                "motion streams): camera_T_imu is identity unless calibration.camera_T_imu "
                "is set in the conversion config"
            )
        source = FrameSource(
            path, choice, scan.topics, depth_kept, color_pos, frame_t, unit_m,
            got.depth_format, got.color_format, plan,
        )  # fmt: skip
        profile = choice.preset if choice.preset != "none" else "rosbag"
        return Recording(
            name=path.stem if path.is_file() else path.name,
            report=report,
            resolved=_resolved_config(config, self.name, choice, encoding, unit_m),
            intrinsics=intrinsics_of(depth_model),
            depth_unit_m=session_unit,
            frame_times_s=frame_t,
            frames=frame_reader(source, frames_report),
            imu=imu,
            joints=joints,
            events=events,
            calibration=calibration,
            camera_profile=profile,
            imu_profile=profile,
        )


def _scan(path: Path, config: ConvertConfig, report: ConversionReport) -> _Scan:
    """Choose the topics and read the bag once (bag_scan.first_pass); zero stamps refused."""
    cfg = config.bag
    with Bag(path) as bag:
        topics, counts, is_ros2 = bag.topics(), bag.counts(), bag.is_ros2
        try:
            choice = resolve_topics(topics, cfg)
        except ConversionError as err:  # the topic errors name the file too
            hint = ""
            if not any("/image/data" in t for t in topics) and "/file_version" in topics:
                hint = (
                    " (an SDK recording without frames: empty, or interrupted — librealsense "
                    "writes a .db3's messages in batches and when the recording is closed)"
                )
            raise type(err)(f"{path}: {err}{hint}") from None
        if choice.camera_info is None and cfg.intrinsics is None:
            raise MissingStreamError(
                f"{path}: no camera_info topic for {choice.depth}; set bag.camera_info_topic "
                f"or bag.intrinsics. Topics found: {listing(topics)}"
            )
        imu_topics = sdk_imu_intrinsic_topics(topics, {"accel": choice.accel, "gyro": choice.gyro})
        extra = sdk_tf_topics(topics) + tuple(imu_topics.values())
        metadata = sdk_metadata_topics(choice, topics) if cfg.stamps == "header" else {}
        device = _device_topic(choice.depth, topics)
        got = first_pass(bag, choice, cfg, counts, topics, extra, metadata, device)
    report.notes.append(
        f"ROS {'2' if is_ros2 else '1'} bag; topics chosen by preset {choice.preset}"
    )
    report.notes.extend(choice.notes)
    report.notes.extend(use_metadata_stamps(got, choice, path))
    report.device.update(device_info(got.device))
    for role, values in (("depth", got.depth_ns), ("color", got.color_ns)):
        topic = getattr(choice, role)
        if topic is not None:
            zero_stamps(values, topic, cfg)
    return _Scan(dict(topics), choice, got, is_ros2)


def _device_topic(depth: str, topics: dict[str, str | None]) -> str | None:
    """The RealSense SDK's device info topic (``/device_<d>/info``) of the depth stream."""
    device = depth.split("/sensor_", 1)[0] + "/info" if depth.startswith("/device_") else None
    return device if device in topics else None


def _calibration(scan: _Scan, config: ConvertConfig, report: ConversionReport) -> BagCalibration:
    """The bag's cameras and extrinsics (config's bag.color_T_depth wins), into the report."""
    got = scan.got
    calib = resolve_bag_calibration(
        scan.choice, got.frame_ids, got.extra, got.tf_static, got.color_info, scan.is_ros2,
        config.bag.color_T_depth,
    )  # fmt: skip
    report.calibration.update(calib.entries)
    report.calibration.update(imu_intrinsics_entries(got.extra, scan.choice))
    report.notes.extend(calib.notes)
    if any(k.endswith("_intrinsics") for k in report.calibration):
        report.notes.append("IMU intrinsics recorded in the bag are reported, not applied")
    return calib


def _camera(path, choice, got, cfg, config, report, is_ros2):
    """The depth camera and the depth unit: (model, unit_m, session unit, encoding)."""
    if not got.depth_ns or got.depth_format is None:
        raise MissingStreamError(f"{path}: depth topic {choice.depth} holds no message")
    encoding, width, height = got.depth_format
    if cfg.intrinsics is not None:
        depth_model = CameraModel(**cfg.intrinsics.model_dump())
        report.notes.append("intrinsics from bag.intrinsics")
    else:
        if got.camera_info is None:
            raise MissingStreamError(f"{path}: camera_info topic {choice.camera_info} is empty")
        depth_model = camera_model_from_info(got.camera_info, is_ros2, str(choice.camera_info))
        report.notes.append(
            f"intrinsics from {choice.camera_info} (first of {got.camera_info_count} message(s))"
        )
        if depth_model.kind != "none":
            report.notes.append(
                f"depth camera_info distortion ({depth_model.distortion_model}, "
                f"{len(depth_model.coeffs)} coefficients) is used to register colour but not "
                "stored: the session assumes a rectified pinhole depth camera"
            )
    if (depth_model.width_px, depth_model.height_px) != (width, height):
        raise ConversionError(
            f"{path}: depth images on {choice.depth} are {width}×{height} but the intrinsics "
            f"say {depth_model.width_px}×{depth_model.height_px}"
        )
    if encoding == "32FC1":
        unit_m = cfg.float_depth_unit_m
        unit_source = (
            "32FC1 depth is in metres (REP 118)" if unit_m == 1.0 else "bag.float_depth_unit_m"
        )
        session_unit = config.output.depth_unit_m or FLOAT_DEPTH_SESSION_UNIT_M
        fix = "set bag.float_depth_unit_m"
    else:
        if cfg.depth_unit_m is not None:
            unit_m, unit_source = cfg.depth_unit_m, "bag.depth_unit_m"
        elif got.depth_units is not None:
            unit_m, unit_source = got.depth_units, f"bag option {choice.depth_units}"
        else:
            unit_m, unit_source = DEFAULT_DEPTH_UNIT_M, "default for 16-bit depth (REP 118: mm)"
        session_unit = config.output.depth_unit_m or unit_m
        fix = "set bag.depth_unit_m"
    check_depth_units(
        got.depth_samples,
        unit_m,
        where=f"{path} topic {choice.depth}",
        unit_source=unit_source,
        fix=fix,
    )
    report.notes.append(f"depth {encoding}, {unit_m:g} m per value ({unit_source})")
    return depth_model, unit_m, session_unit, encoding


def _resolved_config(
    config: ConvertConfig, name: str, choice: TopicChoice, encoding: str, unit_m: float
) -> ConvertConfig:
    """The config as used: topics chosen and depth unit (repeats the conversion). Intrinsics
    from camera_info are not written (the topic is): a pinhole ``bag.intrinsics`` would drop
    the depth camera's distortion and register colour differently on a re-run."""
    cfg = config.bag
    return config.model_copy(
        update={
            "format": name,
            "bag": cfg.model_copy(
                update={
                    "preset": choice.preset,
                    "depth_topic": choice.depth,
                    "color_topic": choice.color,
                    "camera_info_topic": choice.camera_info,
                    "color_info_topic": choice.color_info,
                    "imu_topic": choice.imu,
                    "accel_topic": choice.accel,
                    "gyro_topic": choice.gyro,
                    "joint_states_topic": choice.joint_states,
                    "gait_events_topic": choice.gait_events,
                    "depth_unit_m": None if encoding == "32FC1" else unit_m,
                    "color_registered_to_depth": choice.color_registered,
                    # Intrinsics stay as given: from camera_info they are read again with
                    # the distortion, which bag.intrinsics (pinhole) cannot hold.
                    "intrinsics": cfg.intrinsics,
                }
            ),
        }
    )

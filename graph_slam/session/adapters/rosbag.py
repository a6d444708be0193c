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

from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from graph_slam.errors import BagError, ConversionError, MissingStreamError
from graph_slam.session.adapters.align import CameraModel, align_color_to_depth, pixel_rays
from graph_slam.session.adapters.bag_calibration import (
    Extrinsic,
    camera_model_from_info,
    imu_intrinsics_entries,
    intrinsics_of,
    resolve_bag_calibration,
    sdk_imu_intrinsic_topics,
    sdk_tf_topics,
)
from graph_slam.session.adapters.bag_images import decode_image, image_array
from graph_slam.session.adapters.bag_reader import Bag, bag_path
from graph_slam.session.adapters.bag_scan import first_pass
from graph_slam.session.adapters.bag_topics import TopicChoice, listing, resolve_topics
from graph_slam.session.adapters.base import ConversionReport, Recording, StreamReport
from graph_slam.session.adapters.config import BagConfig, ConvertConfig, IntrinsicsConfig
from graph_slam.session.adapters.timing import (
    associate,
    check_depth_units,
    merge_accel_gyro,
    order_stamps,
)
from graph_slam.session.records import (
    Calibration,
    GaitEvents,
    ImuSeries,
    JointSeries,
    RgbdFrame,
)

__all__ = ["RosbagAdapter", "bag_path", "image_array", "resolve_topics"]

#: REP 118: 16UC1 depth images are in millimetres.
DEFAULT_DEPTH_UNIT_M = 1e-3
#: Float depth is written to the session with this unit unless output.depth_unit_m says otherwise
#: (0.1 mm quantisation, 13.1 m range).
FLOAT_DEPTH_SESSION_UNIT_M = 2e-4


def _zero_stamps(values: list[int] | np.ndarray, topic: str, cfg: BagConfig) -> None:
    zeros = int(np.count_nonzero(np.asarray(values, dtype=np.int64) == 0))
    if zeros and cfg.stamps == "header":
        raise ConversionError(
            f"topic {topic}: {zeros} message(s) have header.stamp = 0; set bag.stamps: bag to "
            "use the recording time instead"
        )


def _ordered(
    items: list[tuple], width: int, stream: str, source: str
) -> tuple[np.ndarray, np.ndarray, StreamReport]:
    """``items`` = (stamp ns, ``width`` values) tuples → (int64 stamps, N×width values) with
    finite values, in stamp order, duplicate stamps dropped; the report counts both."""
    stamps = np.asarray([it[0] for it in items], dtype=np.int64)
    values = np.asarray([it[1:] for it in items], dtype=np.float64).reshape(-1, width)
    finite = np.isfinite(values).all(axis=1)
    order = order_stamps(stamps[finite])
    kept = np.flatnonzero(finite)[order.keep]
    report = StreamReport(
        stream,
        source,
        int(stamps.size),
        int(kept.size),
        {"NaN or inf": int((~finite).sum()), "duplicate stamp": order.duplicates},
    )
    if order.reordered:
        report.notes.append(f"{order.reordered} message(s) out of stamp order, sorted")
    return stamps[kept], values[kept], report


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
        with Bag(path) as bag:
            topics, counts, is_ros2 = bag.topics(), bag.counts(), bag.is_ros2
            choice = resolve_topics(topics, cfg)
            if choice.camera_info is None and cfg.intrinsics is None:
                raise MissingStreamError(
                    f"{path}: no camera_info topic for {choice.depth}; set bag.camera_info_topic "
                    f"or bag.intrinsics. Topics found: {listing(topics)}"
                )
            extra = sdk_tf_topics(topics) + tuple(
                sdk_imu_intrinsic_topics(
                    topics, {"accel": choice.accel, "gyro": choice.gyro}
                ).values()
            )
            got = first_pass(bag, choice, cfg, counts, topics, extra)
        report.notes.append(
            f"ROS {'2' if is_ros2 else '1'} bag; topics chosen by preset {choice.preset}"
        )
        report.notes.extend(choice.notes)
        for role, values in (("depth", got.depth_ns), ("color", got.color_ns)):
            topic = getattr(choice, role)
            if topic is not None:
                _zero_stamps(values, topic, cfg)
        depth_model, unit_m, session_unit, encoding = _camera(
            path, choice, got, cfg, config, report, is_ros2
        )
        intrinsics = intrinsics_of(depth_model)
        calib = resolve_bag_calibration(
            choice, got.frame_ids, got.extra, got.tf_static, got.color_info, is_ros2,
            cfg.color_T_depth,
        )  # fmt: skip
        report.calibration.update(calib.entries)
        report.calibration.update(imu_intrinsics_entries(got.extra, choice))
        report.notes.extend(calib.notes)
        if any(k.endswith("_intrinsics") for k in report.calibration):
            report.notes.append("IMU intrinsics recorded in the bag are reported, not applied")
        align = _color_plan(path, choice, got, cfg, calib, depth_model, report)
        depth_kept, color_pos, frames_report = _pair_frames(choice, got, config, align, report)
        frame_t = np.asarray(got.depth_ns, dtype=np.int64)[depth_kept] * 1e-9
        imu = _imu_series(got, choice, cfg, report, calib.gyro_R_accel)
        joints, events = _joints_events(got, choice, cfg, report)
        calibration = Calibration()
        if calib.camera_T_imu is not None:
            calibration = Calibration(camera_T_imu=calib.camera_T_imu.pose)
            report.calibration["camera_T_imu"] = _extrinsic_entry(calib.camera_T_imu)
        resolved = _resolved_config(config, self.name, choice, encoding, unit_m, intrinsics)
        frames = _frame_reader(
            path,
            choice,
            topics,
            depth_kept,
            color_pos,
            frame_t,
            unit_m,
            frames_report,
            align,
        )
        return Recording(
            name=path.stem if path.is_file() else path.name,
            report=report,
            resolved=resolved,
            intrinsics=intrinsics,
            depth_unit_m=session_unit,
            frame_times_s=frame_t,
            frames=frames,
            imu=imu,
            joints=joints,
            events=events,
            calibration=calibration,
            camera_profile=choice.preset if choice.preset != "none" else "rosbag",
            imu_profile=choice.preset if choice.preset != "none" else "rosbag",
        )


def _extrinsic_entry(ext: Extrinsic) -> dict[str, Any]:
    return {"source": ext.source, "value": np.round(ext.pose, 12).tolist()}


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


@dataclass(frozen=True)
class ColorPlan:
    """How colour is written: as recorded (registered) or registered to depth here."""

    use: bool
    depth_model: CameraModel | None = None
    color_model: CameraModel | None = None
    color_T_depth: np.ndarray | None = None

    @property
    def align(self) -> bool:
        return self.use and self.color_T_depth is not None


def _color_plan(path, choice, got, cfg, calib, depth_model, report) -> ColorPlan:
    """Use colour as recorded when it is registered to depth; else register it when the bag
    (or the config) has the colour camera and the depth→colour extrinsics; else drop it."""
    if choice.color is None:
        return ColorPlan(False)
    width, height = got.depth_format[1:]
    if choice.color_registered:
        if got.color_format is not None and got.color_format[1:] != (width, height):
            raise ConversionError(
                f"{path}: colour on {choice.color} is {got.color_format[1]}×"
                f"{got.color_format[2]}, depth is {width}×{height}; registered colour "
                "must have the depth's size"
            )
        return ColorPlan(True)
    missing = []
    if not cfg.align_color:
        missing.append("bag.align_color is false")
    if calib.color_model is None:
        missing.append("no colour camera_info (bag.color_info_topic)")
    if calib.color_T_depth is None:
        missing.append("no depth→colour extrinsics in the bag (bag.color_T_depth)")
    if missing:
        reason = "not registered to depth: " + "; ".join(missing)
        report.add(
            StreamReport("color", choice.color, len(got.color_ns), 0, {reason: len(got.color_ns)})
        )
        return ColorPlan(False)
    if got.color_format is not None and got.color_format[1:] != (
        calib.color_model.width_px,
        calib.color_model.height_px,
    ):
        raise ConversionError(
            f"{path}: colour on {choice.color} is {got.color_format[1]}×{got.color_format[2]} "
            f"but {choice.color_info} says {calib.color_model.width_px}×"
            f"{calib.color_model.height_px}"
        )
    report.notes.append(
        f"colour registered to depth here ({calib.color_model.distortion_model} colour camera, "
        f"color_T_depth from {calib.color_T_depth.source})"
    )
    return ColorPlan(True, depth_model, calib.color_model, calib.color_T_depth.pose)


def _pair_frames(choice, got, config, plan: ColorPlan, report):
    """Depth frames in stamp order, each paired with a colour image when colour is used."""
    depth_ns = np.asarray(got.depth_ns, dtype=np.int64)
    d_order = order_stamps(depth_ns)
    depth_kept = d_order.keep  # message positions, in stamp order
    frames_dropped = {"duplicate stamp": d_order.duplicates}
    color_pos = None
    if plan.use:
        color_ns = np.asarray(got.color_ns, dtype=np.int64)
        c_order = order_stamps(color_ns)
        max_dt = config.association.max_color_dt_s
        ns0 = int(depth_ns.min())
        i_d, i_c = associate(
            (depth_ns[depth_kept] - ns0) * 1e-9,
            (color_ns[c_order.keep] - ns0) * 1e-9,
            max_dt,
        )
        frames_dropped[f"no colour image within {max_dt} s"] = depth_kept.size - i_d.size
        depth_kept = depth_kept[i_d]
        color_pos = c_order.keep[i_c]
        report.add(
            StreamReport(
                "color",
                choice.color,
                color_ns.size,
                color_pos.size,
                {
                    "duplicate stamp": c_order.duplicates,
                    f"no depth frame within {max_dt} s": c_order.keep.size - color_pos.size,
                },
            )
        )
    frames_report = report.add(
        StreamReport("frames", choice.depth, depth_ns.size, depth_kept.size, frames_dropped)
    )
    return depth_kept, color_pos, frames_report


def _imu_series(got, choice, cfg, report, gyro_R_accel) -> ImuSeries | None:
    """The IMU: a combined topic, or accel interpolated at the gyro stamps (or the reverse)."""
    imu = None
    if choice.imu is not None:
        ns, values, imu_report = _ordered(got.imu, 6, "imu", choice.imu)
        report.add(imu_report)
        _zero_stamps(ns, choice.imu, cfg)
        imu = ImuSeries(ns * 1e-9, values[:, 0:3], values[:, 3:6]) if ns.size else None
    elif choice.accel is not None and choice.gyro is not None:
        g_ns, gyro, g_report = _ordered(got.gyro, 3, "gyro", choice.gyro)
        a_ns, accel, a_report = _ordered(got.accel, 3, "accel", choice.accel)
        if gyro_R_accel is not None:  # accel samples into the gyro (IMU) frame
            accel = accel @ gyro_R_accel.T
        _zero_stamps(g_ns, choice.gyro, cfg)
        _zero_stamps(a_ns, choice.accel, cfg)
        # Interpolate on times relative to the first stamp: exact weights (absolute float
        # seconds near 1.7e9 s resolve only 0.24 µs).
        ns0 = int(min(g_ns[0] if g_ns.size else 0, a_ns[0] if a_ns.size else 0))
        imu_rel, merge = merge_accel_gyro(
            (g_ns - ns0) * 1e-9,
            gyro,
            (a_ns - ns0) * 1e-9,
            accel,
            time_base=cfg.imu.time_base,
            max_gap_s=cfg.imu.max_gap_s,
        )
        imu = ImuSeries(imu_rel.t_s + ns0 * 1e-9, imu_rel.gyro_rad_s, imu_rel.accel_m_s2)
        base, other = (g_report, a_report) if cfg.imu.time_base == "gyro" else (a_report, g_report)
        base.used = merge.base_used
        base.dropped.update(
            {
                "before the other stream starts": merge.base_dropped_start,
                "after the other stream ends": merge.base_dropped_end,
                f"other stream gap > {cfg.imu.max_gap_s} s": merge.base_dropped_gap,
            }
        )
        other.used = merge.other_used
        other.dropped.update(
            {
                "before the first kept base sample": merge.other_unused_start,
                "after the last kept base sample": merge.other_unused_end,
            }
        )
        other.notes.append(f"interpolated linearly at the {cfg.imu.time_base} stamps")
        report.add(g_report)
        report.add(a_report)
        report.notes.append(
            f"IMU: {len(imu)} samples on the {cfg.imu.time_base} time base "
            f"({choice.gyro} + {choice.accel})"
        )
        if imu is not None and len(imu) == 0:
            imu = None
    return imu


def _joints_events(got, choice, cfg, report):
    joints = None
    if choice.joint_states is not None:
        ns, values, j_report = _ordered(got.joints, 2, "joints", choice.joint_states)
        report.add(j_report)
        _zero_stamps(ns, choice.joint_states, cfg)
        if ns.size:
            joints = JointSeries(ns * 1e-9, values[:, 0], values[:, 1])
    events = None
    if choice.gait_events is not None:
        events, e_report = _map_events(got.events, cfg, choice.gait_events)
        report.add(e_report)
    return joints, events


def _resolved_config(config, name, choice, encoding, unit_m, intrinsics) -> ConvertConfig:
    """The config as used: topics chosen, unit and intrinsics (repeats the conversion)."""
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


def _map_events(
    items: list[tuple[int, str]], cfg: BagConfig, topic: str
) -> tuple[GaitEvents, StreamReport]:
    dropped: dict[str, int] = {}
    times: list[int] = []
    kinds: list[str] = []
    for bag_ns, value in items:
        if value in cfg.gait_event_values:
            times.append(bag_ns)
            kinds.append(cfg.gait_event_values[value])
        else:
            key = f"unmapped value {value!r}"
            dropped[key] = dropped.get(key, 0) + 1
    order = order_stamps(np.asarray(times, dtype=np.int64))
    dropped["duplicate stamp"] = order.duplicates
    report = StreamReport("events", topic, len(items), order.keep.size, dropped)
    report.notes.append("stamped with the bag's receive time (std_msgs carry no header)")
    t_s = np.asarray(times, dtype=np.int64)[order.keep] * 1e-9
    events = GaitEvents(
        t_s, tuple(kinds[i] for i in order.keep), (cfg.gait_events_source,) * order.keep.size
    )
    return events, report


def _frame_reader(
    path: Path,
    choice: TopicChoice,
    msgtypes: Mapping[str, str | None],
    depth_pos: np.ndarray,
    color_pos: np.ndarray | None,
    frame_t: np.ndarray,
    unit_m: float,
    frames_report: StreamReport,
    plan: ColorPlan,
):
    """A callable yielding the frames in stamp order (second pass over the bag)."""
    frame_of_depth = {int(p): k for k, p in enumerate(depth_pos)}
    frame_of_color = {} if color_pos is None else {int(p): k for k, p in enumerate(color_pos)}
    n_frames = int(depth_pos.size)
    rays = pixel_rays(plan.depth_model) if plan.align else None

    def frames() -> Iterator[RgbdFrame]:
        depth_ready: dict[int, np.ndarray] = {}
        color_ready: dict[int, np.ndarray] = {}
        next_frame = 0
        topics = {choice.depth}
        if color_pos is not None and choice.color is not None:
            topics.add(choice.color)
        position = dict.fromkeys(topics, -1)
        counts = {"non_finite": 0, "no_depth": 0, "outside": 0}
        with Bag(path) as bag:
            for topic, _, msg in bag.messages(topics):
                position[topic] += 1
                pos = position[topic]
                if topic == choice.depth and pos in frame_of_depth:
                    raw = decode_image(msg, msgtypes.get(topic), topic, pos, "depth")
                    depth_ready[frame_of_depth[pos]] = _depth_m(raw, unit_m, counts)
                if topic == choice.color and pos in frame_of_color:
                    color_ready[frame_of_color[pos]] = decode_image(
                        msg, msgtypes.get(topic), topic, pos, "color"
                    )
                while (
                    next_frame < n_frames
                    and next_frame in depth_ready
                    and (color_pos is None or next_frame in color_ready)
                ):
                    depth_m = depth_ready.pop(next_frame)
                    color = color_ready.pop(next_frame, None)
                    if plan.align and color is not None:
                        aligned = align_color_to_depth(
                            depth_m, color, plan.depth_model, plan.color_model,
                            plan.color_T_depth, rays,
                        )  # fmt: skip
                        counts["no_depth"] += aligned.no_depth
                        counts["outside"] += aligned.outside
                        color = aligned.color_rgb
                    yield RgbdFrame(
                        t_s=float(frame_t[next_frame]),
                        depth_m=depth_m,
                        color_rgb=color,
                        index=next_frame,
                    )
                    next_frame += 1
        _frame_notes(frames_report, counts, plan)
        if next_frame != n_frames:
            raise BagError(
                f"{path}: the second pass found {next_frame} of {n_frames} frames; the bag "
                "changed or is damaged while converting"
            )

    return frames


def _depth_m(raw: np.ndarray, unit_m: float, counts: dict[str, int]) -> np.ndarray:
    scale = np.float32(unit_m)
    if raw.dtype == np.float32:
        bad = ~np.isfinite(raw) | (raw < 0)
        counts["non_finite"] += int(bad.sum())
        return np.where(bad, 0.0, raw).astype(np.float32) * scale
    return raw.astype(np.float32) * scale


def _frame_notes(frames_report: StreamReport, counts: dict[str, int], plan: ColorPlan) -> None:
    if counts["non_finite"]:
        frames_report.notes.append(
            f"{counts['non_finite']} depth pixel(s) NaN, inf or negative written as 0 "
            "(no reading, REP 118)"
        )
    if plan.align:
        frames_report.notes.append(
            f"colour registered to depth: {counts['outside']} depth pixel(s) with a reading "
            f"project outside the colour image (written black); {counts['no_depth']} without "
            "a reading get no colour (black)"
        )

"""The bag's small streams (IMU, joints, gait events) from the first pass: in stamp order,
non-finite samples and duplicate stamps dropped, accel and gyro merged on one time base; every
sample counted in the conversion report."""

from __future__ import annotations

import numpy as np

from graph_slam.errors import ConversionError
from graph_slam.session.adapters.bag_scan import Collected
from graph_slam.session.adapters.bag_topics import TopicChoice
from graph_slam.session.adapters.base import ConversionReport, StreamReport
from graph_slam.session.adapters.config import BagConfig
from graph_slam.session.adapters.timing import merge_accel_gyro, order_stamps
from graph_slam.session.records import GaitEvents, ImuSeries, JointSeries


def zero_stamps(values: list[int] | np.ndarray, topic: str, cfg: BagConfig) -> None:
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


def imu_series(
    got: Collected,
    choice: TopicChoice,
    cfg: BagConfig,
    report: ConversionReport,
    gyro_R_accel: np.ndarray | None,
) -> ImuSeries | None:
    """The IMU: a combined topic, or accel interpolated at the gyro stamps (or the reverse)."""
    imu = None
    if choice.imu is not None:
        ns, values, imu_report = _ordered(got.imu, 6, "imu", choice.imu)
        report.add(imu_report)
        zero_stamps(ns, choice.imu, cfg)
        imu = ImuSeries(ns * 1e-9, values[:, 0:3], values[:, 3:6]) if ns.size else None
    elif choice.accel is not None and choice.gyro is not None:
        g_ns, gyro, g_report = _ordered(got.gyro, 3, "gyro", choice.gyro)
        a_ns, accel, a_report = _ordered(got.accel, 3, "accel", choice.accel)
        if gyro_R_accel is not None:  # accel samples into the gyro (IMU) frame
            accel = accel @ gyro_R_accel.T
        zero_stamps(g_ns, choice.gyro, cfg)
        zero_stamps(a_ns, choice.accel, cfg)
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


def joints_events(
    got: Collected, choice: TopicChoice, cfg: BagConfig, report: ConversionReport
) -> tuple[JointSeries | None, GaitEvents | None]:
    """Knee and ankle angles, and the gait events mapped to their kinds (bag receive time)."""
    joints = None
    if choice.joint_states is not None:
        ns, values, j_report = _ordered(got.joints, 2, "joints", choice.joint_states)
        report.add(j_report)
        zero_stamps(ns, choice.joint_states, cfg)
        if ns.size:
            joints = JointSeries(ns * 1e-9, values[:, 0], values[:, 1])
    events = None
    if choice.gait_events is not None:
        events, e_report = _map_events(got.events, cfg, choice.gait_events)
        report.add(e_report)
    return joints, events


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

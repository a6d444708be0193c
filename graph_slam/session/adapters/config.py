"""The typed conversion config: one sub-model per source kind, all loadable from one YAML.

``graph-slam convert --config overrides.yaml`` reads a partial YAML of this tree (unknown keys
are errors); the fully *resolved* config (topics found, units chosen, intrinsics used) is
written as ``conversion.yaml`` in the converted session, so the run can be repeated exactly.
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from graph_slam.config import ConfigModel
from graph_slam.session.manifest import IntrinsicsSpec, Matrix4

GaitKind = Literal["foot_strike", "toe_off"]
#: The names of the registered sources (graph_slam.session.adapters.registry.ADAPTERS).
SourceFormat = Literal["auto", "rosbag", "tum", "euroc", "prosthesis-log", "session", "synthetic"]
BagPreset = Literal["auto", "realsense-sdk", "realsense-ros", "none"]

# The manifest's intrinsics schema and 4×4 type, under the names this config has always used.
IntrinsicsConfig = IntrinsicsSpec


class AssociationConfig(ConfigModel):
    """How streams at different times are paired."""

    max_color_dt_s: float = Field(
        0.02,
        gt=0,
        le=1.0,
        description="a depth frame and a colour image pair only if their stamps differ by at "
        "most this (TUM's associate.py uses 0.02 s)",
    )
    share_color: bool = Field(
        False,
        description="bags: a colour image may be registered to every depth frame within "
        "max_color_dt_s (colour slower than depth: each depth frame gets the nearest colour "
        "image, as librealsense's frame syncer does); false: one depth frame per colour image, "
        "the other depth frames kept depth-only",
    )
    max_ground_truth_gap_s: float = Field(
        0.05,
        gt=0,
        le=1.0,
        description="ground truth is interpolated at a frame only between two samples at most "
        "this far apart",
    )


class ImuMergeConfig(ConfigModel):
    """Separate accelerometer and gyroscope streams → one IMU series."""

    time_base: Literal["gyro", "accel"] = Field(
        "gyro", description="the stream whose stamps are kept; the other is interpolated"
    )
    max_gap_s: float = Field(
        0.05,
        gt=0,
        le=1.0,
        description="a sample is dropped when the other stream's bracketing samples are "
        "further apart than this",
    )


DEFAULT_EVENT_VALUES: dict[str, GaitKind] = {
    "foot_strike": "foot_strike",
    "heel_strike": "foot_strike",
    "toe_off": "toe_off",
}


class BagConfig(ConfigModel):
    """ROS 1 / ROS 2 bags. A topic set here overrides the preset's choice."""

    preset: BagPreset = "auto"
    depth_topic: str | None = None
    color_topic: str | None = None
    camera_info_topic: str | None = None
    color_info_topic: str | None = Field(
        None, description="the colour camera's CameraInfo (to register unaligned colour)"
    )
    imu_topic: str | None = Field(None, description="combined sensor_msgs/Imu (gyro + accel)")
    accel_topic: str | None = None
    gyro_topic: str | None = None
    joint_states_topic: str | None = None
    gait_events_topic: str | None = None
    depth_unit_m: float | None = Field(
        None,
        gt=0,
        le=0.01,
        description="metres per 16-bit depth unit; None: the bag's 'Depth Units' option "
        "(RealSense SDK), else 0.001 (REP 118: 16UC1 depth is in millimetres)",
    )
    float_depth_unit_m: float = Field(
        1.0, gt=0, description="metres per 32FC1 depth value (REP 118: metres, 1.0)"
    )
    color_registered_to_depth: bool | None = Field(
        None,
        description="colour pixels align with depth pixels; None: the preset decides "
        "(true for aligned_depth_to_color, false for SDK recordings)",
    )
    intrinsics: IntrinsicsConfig | None = Field(
        None, description="use these instead of the camera_info topic"
    )
    align_color: bool = Field(
        True,
        description="register unaligned colour to the depth image (needs the colour camera_info "
        "and the depth→colour extrinsics); false: drop it, counted",
    )
    color_T_depth: Matrix4 | None = Field(
        None,
        description="depth camera → colour camera extrinsics (maps depth-frame points to the "
        "colour frame); None: from the bag (SDK tf topics, /tf_static)",
    )
    stamps: Literal["header", "bag"] = Field(
        "header", description="message time: header.stamp, or the bag's receive time"
    )
    knee_joint: str = "knee"
    ankle_joint: str = "ankle"
    gait_event_values: dict[str, GaitKind] = Field(
        default_factory=lambda: dict(DEFAULT_EVENT_VALUES)
    )
    gait_events_source: str = "bag"
    imu: ImuMergeConfig = ImuMergeConfig()

    @model_validator(mode="after")
    def _imu_topics(self) -> BagConfig:
        if self.imu_topic and (self.accel_topic or self.gyro_topic):
            raise ValueError(
                "set either imu_topic (combined) or accel_topic + gyro_topic, not both"
            )
        if bool(self.accel_topic) != bool(self.gyro_topic):
            raise ValueError("accel_topic and gyro_topic must be set together")
        return self


class TumConfig(ConfigModel):
    """TUM RGB-D folders (rgb.txt, depth.txt, groundtruth.txt, accelerometer.txt)."""

    camera: Literal["auto", "fr1", "fr2", "fr3"] = Field(
        "auto", description="intrinsics by name; auto: from 'freiburgN' / 'frN' in the folder name"
    )
    intrinsics: IntrinsicsConfig | None = None
    depth_units_per_m: float = Field(5000.0, gt=0, description="TUM depth PNGs: 5000 units = 1 m")


class EurocConfig(ConfigModel):
    """EuRoC / ASL folders. Paths are relative to the source folder; None: look in the usual
    places (mav0/imu0/data.csv, imu0/data.csv, imu0_data.csv; state_groundtruth_estimate0/
    data.csv, vicon0/data.csv, *_gt.txt, groundtruth.txt)."""

    imu_csv: str | None = None
    ground_truth: str | None = None


class TimeColumn(ConfigModel):
    column: str = "t_s"
    unit: Literal["s", "ms", "us", "ns"] = "s"


class AngleColumn(ConfigModel):
    """radians = to_rad(value × scale + offset, unit)."""

    column: str
    unit: Literal["rad", "deg"] = "rad"
    scale: float = 1.0
    offset: float = 0.0


class EventColumn(ConfigModel):
    """Rows with a non-empty value in ``column`` are events; ``values`` maps them to kinds."""

    column: str
    values: dict[str, GaitKind]
    ignore: tuple[str, ...] = Field((), description="values that are not gait events")


class LoadColumn(ConfigModel):
    """Gait events from a load cell by hysteresis: a foot strike when the load rises through
    ``foot_strike_above_n``, a toe-off when it falls through ``toe_off_below_n``."""

    column: str
    scale: float = Field(1.0, description="newtons per log unit")
    foot_strike_above_n: float
    toe_off_below_n: float

    @model_validator(mode="after")
    def _hysteresis(self) -> LoadColumn:
        if self.toe_off_below_n > self.foot_strike_above_n:
            raise ValueError("toe_off_below_n must not exceed foot_strike_above_n")
        return self


class ClockOffsetConfig(ConfigModel):
    """How the clock offset between a prosthesis log and the camera is estimated when
    ``prosthesis_log.time_offset_s`` is None (graph_slam.session.adapters.clock_offset).

    The foot strikes the offline detector finds in the camera's own IMU (on the thigh) are
    matched to the log's foot strikes (load cell or event column); the offset is the median of
    the matched differences and σ their spread (1.4826 × MAD). The expected difference between
    an IMU-detected strike and the log's strike of the same step, on one clock, is
    ``imu_strike_bias_s − log_strike_lag_s``; it is removed before the median is taken.
    """

    tolerance_s: float = Field(
        0.04,
        gt=0,
        le=0.3,
        description="a camera strike and a log strike match when, after the offset, they are "
        "at most this far apart (the detector's worst error on real walking is ~50 ms)",
    )
    min_matched_strikes: int = Field(
        5, ge=2, description="fewer matched foot strikes than this is an error"
    )
    max_spread_s: float = Field(
        0.02,
        gt=0,
        le=0.2,
        description="a spread (1.4826 × MAD of the matched differences) above this is an error",
    )
    imu_strike_bias_s: float = Field(
        -0.0002,
        ge=-0.2,
        le=0.2,
        description="the thigh-IMU detector's bias, detected − true foot strike: median "
        "−0.2 ms over 630 simulated strikes at 0.8/1.1/1.4 m/s (−1.8/0.0/+0.1 ms each; "
        "docs/adapters.md)",
    )
    log_strike_lag_s: float = Field(
        0.0,
        ge=-0.2,
        le=0.2,
        description="how late the log's strike is after the true contact (a load cell's "
        "threshold crossing lags the contact by its rise time to the threshold); 0 = unknown",
    )


class ProsthesisLogConfig(ConfigModel):
    """The column mapping of a prosthesis controller's CSV log.

    ``time_offset_s`` (camera time = log time + offset): None (the default) estimates it from
    the foot strikes of the camera's IMU and of the log (``clock``) when the log is merged into
    a recording; a number is used as given. A log converted on its own has no other clock:
    None means 0 there.
    """

    path: str | None = Field(
        None,
        description="a log to merge into a bag / TUM conversion (relative to the current "
        "folder); not needed when the log itself is the source",
    )
    delimiter: str = Field(",", min_length=1, max_length=1)
    time: TimeColumn = TimeColumn()
    time_offset_s: float | None = Field(
        None,
        description="added to the log's times (to the camera clock); None: estimated from "
        "foot strikes when merged into a recording with an IMU (see 'clock'), 0 for a log on "
        "its own",
    )
    clock: ClockOffsetConfig = ClockOffsetConfig()
    knee: AngleColumn = AngleColumn(column="knee_rad")
    ankle: AngleColumn = AngleColumn(column="ankle_rad")
    events: EventColumn | None = None
    load: LoadColumn | None = None
    events_source: str | None = Field(
        None, description="GaitEvents.source; None: 'log' (event column) or 'load_cell'"
    )

    @model_validator(mode="after")
    def _one_event_source(self) -> ProsthesisLogConfig:
        if self.events is not None and self.load is not None:
            raise ValueError("give gait events either by 'events' or by 'load', not both")
        return self


class CalibrationConfig(ConfigModel):
    """Calibration written into the session (None: the source's own, else identity / 0)."""

    thigh_T_camera: Matrix4 | None = None
    camera_T_imu: Matrix4 | None = None
    imu_time_offset_s: float | None = None
    joints_time_offset_s: float | None = None


class OutputConfig(ConfigModel):
    name: str | None = Field(None, description="session name; None: from the source")
    depth_unit_m: float | None = Field(
        None,
        gt=0,
        le=0.01,
        description="metres per PNG unit; None: the source's own unit (lossless), or 2e-4 "
        "for float depth",
    )
    camera_profile: str | None = None


class ConvertConfig(ConfigModel):
    """Everything ``graph-slam convert`` needs; every field has a default."""

    format: SourceFormat = "auto"
    association: AssociationConfig = AssociationConfig()
    bag: BagConfig = BagConfig()
    tum: TumConfig = TumConfig()
    euroc: EurocConfig = EurocConfig()
    prosthesis_log: ProsthesisLogConfig = ProsthesisLogConfig()
    calibration: CalibrationConfig = CalibrationConfig()
    output: OutputConfig = OutputConfig()

"""Sessions: records, the on-disk format (reader, writer, validation) and sources."""

from graph_slam.session.info import SessionInfo, session_info
from graph_slam.session.reader import Session, open_session
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
from graph_slam.session.validation import ValidationReport, validate_session
from graph_slam.session.writer import SessionWriter

__all__ = [
    "Calibration",
    "CameraIntrinsics",
    "GaitEvents",
    "ImuSeries",
    "JointSeries",
    "PoseTrajectory",
    "RgbdFrame",
    "SceneObject",
    "SceneTruth",
    "Session",
    "SessionInfo",
    "SessionWriter",
    "ValidationReport",
    "open_session",
    "session_info",
    "validate_session",
]

"""Sessions: records, the on-disk format (reader, writer, validation) and sources."""

from graph_slam.session.format import (
    Session,
    SessionWriter,
    ValidationReport,
    open_session,
    validate_session,
)
from graph_slam.session.info import SessionInfo, session_info
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

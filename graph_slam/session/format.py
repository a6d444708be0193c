"""The project's session format on disk: the folder layout and where each part of it lives.

A session folder (docs/session_format.md)::

    session.yaml        manifest: schema version, sensors, calibration, files, provenance
    frames.csv          index,t_s,depth,color   (one row per RGB-D frame, paths relative)
    depth/NNNNNN.png    uint16, metres = value × depth_unit_m, 0 = invalid
    color/NNNNNN.png    RGB8, aligned with the depth (optional; per frame)
    imu.csv             t_s,gyro_x_rad_s,gyro_y_rad_s,gyro_z_rad_s,accel_x_m_s2,accel_y_m_s2,accel_z_m_s2
    joints.csv          t_s,knee_rad,ankle_rad
    events.csv          t_s,kind,source
    groundtruth.txt     TUM trajectory of world_T_camera at frame times
    groundtruth_hf.txt  TUM trajectory of world_T_camera at motion-capture rate (optional)
    scene.yaml          scene ground truth (optional)

The format's parts, in the order data flows through them:

- :mod:`graph_slam.session.manifest` - ``session.yaml`` (typed, versioned) and path checks;
- :mod:`graph_slam.session.files` - the column schemas, ``frames.csv``, ``events.csv``,
  ``scene.yaml`` and the depth scale's plausibility rule;
- :mod:`graph_slam.session.io` - strict PNG, numeric CSV streams, TUM poses;
- :mod:`graph_slam.session.reader` - :class:`Session`, the lazy reader (memory does not grow
  with session length);
- :mod:`graph_slam.session.writer` - :class:`SessionWriter`, which streams frames to disk and
  writes the manifest last, so an interrupted write leaves no manifest and cannot be mistaken
  for a complete session;
- :mod:`graph_slam.session.validation` - :func:`validate_session`, the complete check.

This module gathers their public names in one place (``graph_slam.session`` re-exports the
main ones).
"""

from graph_slam.session.files import (
    EVENT_COLUMNS,
    FRAME_COLUMNS,
    IMU_COLUMNS,
    JOINT_COLUMNS,
    PLAUSIBLE_MEDIAN_DEPTH_M,
    FrameIndex,
    check_depth_scale,
)
from graph_slam.session.reader import Session, open_session
from graph_slam.session.validation import ValidationReport, validate_session
from graph_slam.session.writer import SessionWriter

__all__ = [
    "EVENT_COLUMNS",
    "FRAME_COLUMNS",
    "IMU_COLUMNS",
    "JOINT_COLUMNS",
    "PLAUSIBLE_MEDIAN_DEPTH_M",
    "FrameIndex",
    "Session",
    "SessionWriter",
    "ValidationReport",
    "check_depth_scale",
    "open_session",
    "validate_session",
]

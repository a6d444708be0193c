"""Prosthetic-leg kinematics, gait events and gait reference curves (numpy in, numpy out).

This package never imports ``graph_slam``. Modules (import what you need; pinocchio and gtsam
are only imported by the modules that use them):

- :mod:`kinematics.gait_curves` - hip/knee/ankle reference curves vs phase and speed
- :mod:`kinematics.leg_params` - the typed leg parameters and the URDF they generate
- :mod:`kinematics.leg_model` - :class:`~kinematics.leg_model.LegModel` (Pinocchio FK,
  Jacobians, camera-pose covariance)
- :mod:`kinematics.stride_frame` - ``stride_T_camera`` at foot strike
- :mod:`kinematics.encoders` - joint-encoder validation (limits, NaN, jumps)
- :mod:`kinematics.imu` - the IMU series and the IMU CSV schema (shared with the session format)
- :mod:`kinematics.gait_events` - foot strike / toe-off from a load cell or a thigh IMU
  (:class:`~kinematics.gait_events.DetectedEvents`), gait phase (:mod:`kinematics.gait_templates`,
  :mod:`kinematics.gait_load_cell`, :mod:`kinematics.gait_event_times`, :mod:`kinematics.gait_io`)
- :mod:`kinematics.gait_phase` - the online (causal) gait estimator: phase EKF, cadence, events
  as they happen (:mod:`kinematics.gait_phase_filter`, :mod:`kinematics.gait_phase_events`,
  :mod:`kinematics.gait_phase_mounting` its stages,
  :mod:`kinematics.thigh_attitude` thigh angle, :mod:`kinematics.phase_model`
  measurement model, :mod:`kinematics.gait_phase_config` parameters and records,
  :mod:`kinematics.gait_online` batch helper and CSV,
  :mod:`kinematics.gait_phase_metrics` scores, :mod:`kinematics.gait_phase_portrait` the
  thigh's phase-portrait phase as a yardstick, :mod:`kinematics.gait_scenarios` synthetic walks)
- :mod:`kinematics.conversions` - pin.SE3 <-> gtsam.Pose3 <-> 4x4 arrays
"""

import logging

from kinematics.errors import (
    EncoderError,
    GaitCurveError,
    GaitDetectionError,
    GaitInputError,
    KinematicsError,
    LegModelError,
)

logging.getLogger(__name__).addHandler(logging.NullHandler())

__all__ = [
    "EncoderError",
    "GaitCurveError",
    "GaitDetectionError",
    "GaitInputError",
    "KinematicsError",
    "LegModelError",
]

"""The IMU series and its CSV schema: one definition for the whole project.

:class:`ImuSeries` is plain data (numpy in, numpy out). ``graph_slam.session.records.ImuSeries``
is the same class with validation on construction (shapes, finite, strictly increasing time);
:func:`kinematics.gait_io.validate_imu` adds the rules of a gait recording (rate, gaps,
ranges). :data:`IMU_COLUMNS` is the header of every IMU CSV: the session format's ``imu.csv``
and the input of ``graph-slam gait-events``. :data:`LEGACY_IMU_COLUMNS` (the gait-event
reader's former header, without units) is still read.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

IMU_COLUMNS: tuple[str, ...] = (
    "t_s",
    "gyro_x_rad_s",
    "gyro_y_rad_s",
    "gyro_z_rad_s",
    "accel_x_m_s2",
    "accel_y_m_s2",
    "accel_z_m_s2",
)
"""Time (s), angular rate (rad/s) and specific force (m/s²) in the IMU frame."""

LEGACY_IMU_COLUMNS: tuple[str, ...] = (
    "t_s",
    "gyro_x",
    "gyro_y",
    "gyro_z",
    "accel_x",
    "accel_y",
    "accel_z",
)
"""The same columns without units in their names; read, never written."""


@dataclass(frozen=True, slots=True, eq=False)
class ImuSeries:
    """IMU samples in the IMU frame: angular rate (rad/s) and specific force (m/s²).

    ``t_s`` (N,), ``gyro_rad_s`` (N, 3), ``accel_m_s2`` (N, 3); ``source`` names where the
    samples came from (a file), for messages.
    """

    t_s: np.ndarray
    gyro_rad_s: np.ndarray
    accel_m_s2: np.ndarray
    source: str = "<memory>"

    def __len__(self) -> int:
        return int(np.asarray(self.t_s).size)

"""Exceptions of the kinematics package (which never imports graph_slam).

Every message names the input (file, row, column, field or joint) and the rule it broke.
``graph_slam.errors.library_errors()`` includes :class:`KinematicsError`, so the CLI maps all
of these to one line and exit code 2.
"""

from __future__ import annotations


class KinematicsError(Exception):
    """Base class of every error the kinematics package raises on purpose."""


class LegModelError(KinematicsError):
    """The leg model (URDF, parameters) is invalid or does not match the encoder channels."""


class EncoderError(KinematicsError):
    """Joint-encoder samples cannot be used (wrong shape, no valid sample left, ...)."""


class GaitCurveError(KinematicsError):
    """A gait reference curve was asked for outside its validity (speed range, bad phase)."""


class GaitInputError(KinematicsError):
    """A gait-event input (IMU or load-cell series, CSV file) breaks a rule."""


class GaitDetectionError(KinematicsError):
    """Gait events cannot be detected from this signal (no periodic walking found, ...)."""

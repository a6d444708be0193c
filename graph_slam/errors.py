"""Typed exceptions of graph_slam.

Every error the library raises on purpose is a :class:`GraphSlamError`. Messages name the
file, the row or field, and the rule that was broken, so that a user can fix the input
without reading code. The CLI turns these into a one-line message and exit code 2.

The ``kinematics`` package never imports ``graph_slam``; its errors derive from
``kinematics.KinematicsError``. Catch :data:`LIBRARY_ERRORS` to catch both.
"""

from __future__ import annotations

from enum import StrEnum


class GraphSlamError(Exception):
    """Base class of every error graph_slam raises on purpose."""


class ConfigError(GraphSlamError):
    """A configuration value or combination is invalid (names the field)."""


class MountPitchError(ConfigError):
    """The camera's mount pitch on the thigh cannot be estimated from the recording (too few
    foot-flat samples, too large a spread, or outside the leg model's range): set it."""


class RecordError(GraphSlamError):
    """An in-memory record (frame, IMU series, ...) has a wrong shape, dtype or value."""


class SessionError(GraphSlamError):
    """A recorded session on disk is missing, malformed or inconsistent."""


class ManifestError(SessionError):
    """The session manifest is missing, unreadable or has a bad field."""


class SchemaVersionError(ManifestError):
    """The manifest's schema version is not one this reader understands."""


class PathEscapeError(SessionError):
    """A path in a manifest or index points outside the session folder."""


class StreamError(SessionError):
    """A CSV stream (frames, imu, joints, events, ground truth) breaks a rule."""


class TimestampError(StreamError):
    """Timestamps are non-monotonic, duplicated or not finite."""


class NonFiniteError(StreamError):
    """A numeric sample is NaN or infinite."""


class ImageError(SessionError):
    """An image file is missing, corrupt, truncated or has the wrong size or type."""


class DepthScaleError(SessionError):
    """The stated depth scale makes the depth values implausible."""


class ConversionError(GraphSlamError):
    """A foreign recording (bag, TUM folder, EuRoC, log) cannot be converted."""


class PlanarError(GraphSlamError):
    """The 2D study (graph_slam.planar) got input it cannot use."""


class MissingStreamError(ConversionError):
    """A topic, file or column the conversion needs is absent (the message lists those found)."""


class BagError(ConversionError):
    """A bag cannot be read (truncated, unindexed, damaged); the message carries a hint."""


class ClockOffsetError(ConversionError):
    """The clock offset between a prosthesis log and the camera cannot be estimated (too few
    matched foot strikes, too large a spread, or two offsets that fit equally well)."""


class CompressedImageError(BagError):
    """A CompressedImage / compressedDepth message in a bag is corrupt or of an unsupported kind
    (the message names the topic and the message index)."""


class DepthUnitsError(ConversionError):
    """The depth values are implausible in the stated units (detected from the data)."""


class SimulationError(GraphSlamError):
    """The simulator (graph_slam.sim) got a scene, profile or setting it cannot use."""


class RealsenseError(GraphSlamError):
    """A RealSense camera or SDK recording could not be opened, recorded or read live."""


class MissingExtraError(RealsenseError):
    """An optional extra (e.g. ``realsense``: pyrealsense2) is not installed."""


class RegistrationFailure(StrEnum):
    """Why a registration failed (see :class:`RegistrationError`)."""

    EMPTY_SOURCE = "empty_source"
    EMPTY_TARGET = "empty_target"
    NO_OVERLAP = "no_overlap"
    TOO_FEW_CORRESPONDENCES = "too_few_correspondences"
    LOW_FITNESS = "low_fitness"
    NOT_CONVERGED = "not_converged"
    NUMERICAL = "numerical"
    DEGENERATE = "degenerate"


class RegistrationError(GraphSlamError):
    """A registration failed: never read as zero motion.

    ``reason`` is a :class:`RegistrationFailure`; ``fitness`` and ``correspondences`` are the
    last values seen (``None`` when the failure came before any ICP iteration).
    """

    def __init__(
        self,
        reason: RegistrationFailure,
        message: str,
        *,
        fitness: float | None = None,
        correspondences: int | None = None,
    ) -> None:
        super().__init__(f"registration failed ({reason.value}): {message}")
        self.reason = reason
        self.detail = message
        self.fitness = fitness
        self.correspondences = correspondences


class EstimationError(GraphSlamError):
    """The estimator cannot go on (an input it cannot use, not a numerical hiccup)."""


class MappingError(GraphSlamError):
    """Map building (fusion, elevation grid, obstacles) got input it cannot use."""


class EvaluationError(GraphSlamError):
    """Evaluation got inputs it cannot compare, or a needed optional extra is missing."""


def library_errors() -> tuple[type[Exception], ...]:
    """The exception types a caller should treat as 'bad input', not as a bug."""
    from kinematics import KinematicsError

    return (GraphSlamError, KinematicsError)


class OutputError(GraphSlamError):
    """An output folder cannot be written or replaced (a file, a user's folder, no permission)."""


class BatchError(GraphSlamError):
    """A batch study (``graph-slam batch``) cannot start: its optional extra is missing, the
    scheduler cannot be reached, or its output folder is not one it wrote."""

"""Leg kinematics for the estimator: encoders -> camera pose in the stride frame, contact points.

:class:`LegKinematics` (a :class:`kinematics.leg_model.LegModel`, a :class:`~graph_slam.
strides.joints.JointBuffer` and the session's ``camera_T_imu``) answers, for a time ``t_s``:

* :meth:`LegKinematics.anchor` — the stride's anchor at its first frame:
  :func:`kinematics.stride_frame.stride_T_camera` with the IMU's up vector carried into the
  model's IMU frame (:func:`imu_up_in_model`); with an up σ its covariance is
  :func:`anchor_covariance`. It remembers the struck foot's ``stride_T_foot``;
* :meth:`LegKinematics.foot_pose` — the ``foot_pose`` stance measurement: that foot held,
  ``stride_T_foot · foot_T_camera(q)``;
* :meth:`LegKinematics.contact_geometry` — ``imu_T_foot`` and ``foot_p_toe`` for the
  ``contact_points`` stance model.

Each returns None (logged) when no measurement exists: no model, ``t_s`` outside the buffered
encoder samples, or a ``KinematicsError`` (e.g. a joint outside its limits).

Also here: :func:`leg_model_for` (the leg model matching a calibration) and
:func:`session_leg_model` (the leg model for a session: its camera mount from the config, the
calibration, or estimated from the session by :mod:`graph_slam.strides.mount`).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from graph_slam.errors import ConfigError, MountPitchError
from graph_slam.strides.joints import JointBuffer
from graph_slam.strides.measurements import KinematicMeasurement
from graph_slam.strides.mount import MountEstimateConfig, MountPitchEstimate
from kinematics.conversions import adjoint_rot_first

log = logging.getLogger(__name__)


def leg_model_for(thigh_T_camera: np.ndarray, mount_pitch_deg: float | None = None):
    """The ``LegModel`` whose camera mount matches the calibration's ``thigh_T_camera``.

    With ``mount_pitch_deg`` None the pitch is fitted (30-45°); the fitted mount must reproduce
    the calibration within 1 mm / 1 mrad, else :class:`ConfigError`.
    """
    from scipy.optimize import minimize_scalar

    from kinematics.leg_model import LegModel
    from kinematics.leg_params import LegParams

    def model(pitch_rad: float) -> LegModel:
        return LegModel(LegParams(mount_pitch_down_rad=pitch_rad))

    def mismatch(m) -> float:
        d = np.linalg.inv(m.thigh_T_frame("camera_optical")) @ thigh_T_camera
        return float(np.linalg.norm(d[:3, 3]) + np.linalg.norm(d[:3, :3] - np.eye(3)))

    if mount_pitch_deg is not None:
        return model(math.radians(mount_pitch_deg))
    fit = minimize_scalar(
        lambda p: mismatch(model(p)),
        bounds=(math.radians(30), math.radians(45)),
        method="bounded",
        options={"xatol": 1e-9},
    )
    best = model(float(fit.x))
    if mismatch(best) > 1e-3:
        raise ConfigError(
            "calibration.thigh_T_camera: no leg-model camera mount (pitch 30-45°, default "
            f"geometry) reproduces it (mismatch {mismatch(best):.3g}); say how the camera sits "
            "on the thigh: pipeline.mount_pitch_deg in the run config (a converted recording's "
            "calibration is identity unless calibration.thigh_T_camera was set)"
        )
    return best


MountSource = Literal["config", "calibration", "estimated"]


@dataclass(frozen=True)
class MountPitch:
    """Which source set the leg model's mount pitch, and its value."""

    source: MountSource
    pitch_deg: float
    estimate: MountPitchEstimate | None = None

    def to_dict(self) -> dict:
        out: dict = {"source": self.source, "pitch_deg": round(self.pitch_deg, 4)}
        if self.estimate is not None:
            out["spread_deg"] = round(self.estimate.spread_deg, 4)
            out["n_samples"] = self.estimate.n_samples
            out["counts"] = dict(self.estimate.counts)
        return out

    def describe(self) -> str:
        """One line for logs and reports."""
        text = f"mount pitch {self.pitch_deg:.2f}° ({self.source}"
        if self.estimate is not None:
            e = self.estimate
            text += f" from {e.n_samples} foot-flat IMU samples, spread {e.spread_deg:.2f}°"
        return text + ")"


def is_identity(a_T_b: np.ndarray, atol: float = 1e-9) -> bool:
    return bool(np.allclose(np.asarray(a_T_b, float), np.eye(4), atol=atol))


def session_leg_model(
    session,
    mount_pitch_deg: float | None = None,
    config: MountEstimateConfig | None = None,
    *,
    streams=None,
    event_source: str | None = "load_cell",
):
    """``(LegModel, MountPitch)`` for a session: the mount pitch from, in this order,
    ``mount_pitch_deg`` (``pipeline.mount_pitch_deg``), the session's ``thigh_T_camera`` when
    it is not the identity (:func:`~graph_slam.strides.kinematics.leg_model_for`'s fit), or
    :func:`estimate_mount_pitch` on the session's streams (``streams``: those of
    :func:`~graph_slam.strides.streams.session_streams`, read with ``event_source`` when
    None). The winner is logged."""
    from kinematics.leg_model import LegModel
    from kinematics.leg_params import LegParams

    thigh_T_camera = session.calibration.thigh_T_camera
    if mount_pitch_deg is not None:
        model = leg_model_for(thigh_T_camera, mount_pitch_deg)
        chosen = MountPitch("config", float(mount_pitch_deg))
    elif not is_identity(thigh_T_camera):
        model = leg_model_for(thigh_T_camera, None)
        chosen = MountPitch("calibration", math.degrees(model.params.mount_pitch_down_rad))
    else:
        if streams is None:
            from graph_slam.strides.streams import session_streams

            streams = session_streams(session, event_source)
        estimate = estimate_from_streams(
            streams, session.calibration.camera_T_imu, config, where=str(session.path)
        )
        model = LegModel(LegParams(mount_pitch_down_rad=math.radians(estimate.pitch_deg)))
        chosen = MountPitch("estimated", estimate.pitch_deg, estimate)
    log.info("%s: %s", session.path, chosen.describe())
    return model, chosen


def estimate_from_streams(
    streams, camera_T_imu: np.ndarray, config: MountEstimateConfig | None = None, where="session"
) -> MountPitchEstimate:
    """:func:`estimate_mount_pitch` on a :class:`~graph_slam.strides.streams.Streams`."""
    if streams.imu_t_s is None or streams.joints_t_s is None:
        missing = "imu.csv" if streams.imu_t_s is None else "joints.csv"
        raise MountPitchError(
            f"{where}: the session's thigh_T_camera is the identity and it has no {missing} to "
            "estimate the camera's mount pitch from; set pipeline.mount_pitch_deg"
        )
    from graph_slam.strides.mount import estimate_mount_pitch

    return estimate_mount_pitch(
        streams.imu_t_s,
        streams.gyro_rad_s,
        streams.accel_m_s2,
        streams.joints_t_s,
        np.column_stack([streams.knee_rad, streams.ankle_rad]),
        streams.events.foot_strikes_s,
        streams.events.toe_offs_s,
        camera_T_imu,
        config,
        where=where,
    )


def imu_up_in_model(model, camera_T_imu: np.ndarray, up_in_imu: np.ndarray) -> np.ndarray:
    """The session IMU's up vector expressed in the leg model's ``imu`` frame (via the camera)."""
    model_camera_R_imu = (
        np.linalg.inv(model.thigh_T_frame("camera_optical")) @ model.thigh_T_frame("imu")
    )[:3, :3]
    return model_camera_R_imu.T @ camera_T_imu[:3, :3] @ up_in_imu


def tilt_covariance(stride_T_camera: np.ndarray, cov: np.ndarray, sigma_rad: float) -> np.ndarray:
    """``cov`` (camera local, rotation first) with its tilt about the stride frame's x and y axes
    (through the stride origin) replaced by an independent σ ``sigma_rad``: with the stride
    frame's z from the IMU's up vector the camera's tilt error is that vector's error."""
    ad = adjoint_rot_first(stride_T_camera)  # right (camera) -> left (stride) coordinates
    left = ad @ cov @ ad.T
    left[:2, :] = 0.0
    left[:, :2] = 0.0
    left[0, 0] = left[1, 1] = sigma_rad**2
    inv = np.linalg.inv(ad)
    return inv @ left @ inv.T


def anchor_covariance(
    stride_T_camera: np.ndarray,
    encoder_cov: np.ndarray,
    up_sigma_rad: float,
    yaw_sigma_rad: float,
    position_sigma_m: float,
) -> np.ndarray:
    """The anchor's covariance (camera local, rotation first) when the up vector is known.

    The stride frame *is* the foot at the strike (origin at the heel, x along the foot) with z
    up: relative to it the camera is uncertain only by the encoders' FK error
    (``encoder_cov``), the up vector's tilt error (``up_sigma_rad``, about the stride x/y axes
    through the heel) and a small floor on yaw and position (``yaw_sigma_rad``,
    ``position_sigma_m``) that keeps the prior well conditioned. Where the foot landed in the
    world (the contact noise of the kinematics module) does not move the camera in this frame.
    Measured without this (the contact noise's 2° yaw and 1 cm in the anchor): the smoother
    turned whole strides by up to 1° of yaw to fit a carried-over velocity (24 mm at the stride's
    end, full-resolution normal-speed session).
    """
    ad = adjoint_rot_first(stride_T_camera)
    floor = np.diag(np.r_[0.0, 0.0, yaw_sigma_rad**2, np.full(3, position_sigma_m**2)])
    inv = np.linalg.inv(ad)
    cov = np.asarray(encoder_cov, float) + inv @ floor @ inv.T
    return tilt_covariance(stride_T_camera, cov, up_sigma_rad)


@dataclass(frozen=True, eq=False)
class ContactGeometry:
    """The foot in the IMU frame at one time: ``imu_T_foot`` (foot = heel frame, x along the
    sole) and the toe in the foot frame ``foot_p_toe`` (m)."""

    imu_T_foot: np.ndarray
    foot_p_toe: np.ndarray


class LegKinematics:
    """Encoders + leg model -> the estimator's kinematic measurements (module docstring)."""

    def __init__(
        self,
        model,
        camera_T_imu: np.ndarray,
        joints: JointBuffer,
        anchor_yaw_sigma_rad: float = 1e-3,
        anchor_position_sigma_m: float = 1e-3,
    ):
        self.model = model
        self.camera_T_imu = np.asarray(camera_T_imu, float)
        self.joints = joints
        self.anchor_yaw_sigma_rad = anchor_yaw_sigma_rad
        self.anchor_position_sigma_m = anchor_position_sigma_m
        self.stride_T_foot: np.ndarray | None = None
        """The struck foot (rotation only) of the last anchor computed from the encoders."""

    def add_joints(self, t_s, knee_rad, ankle_rad) -> int:
        """Buffer encoder samples (rad); returns how many were accepted."""
        return self.joints.add(t_s, knee_rad, ankle_rad)

    def q_at(self, t_s: float) -> np.ndarray | None:
        """``[knee, ankle]`` at ``t_s`` when a model exists and ``t_s`` is inside the samples."""
        return None if self.model is None else self.joints.q_at(t_s)

    def anchor(
        self, t_s: float, up_in_imu: np.ndarray | None, up_sigma_rad: float | None = None
    ) -> KinematicMeasurement | None:
        """The camera in the new stride's frame at ``t_s`` (``up_in_imu``: session IMU frame,
        None: the model's nominal heel-strike pitch). ``up_sigma_rad`` given: the covariance
        is :func:`anchor_covariance` (no contact noise), else the kinematics' heel-strike one."""
        from kinematics.errors import KinematicsError
        from kinematics.stride_frame import DEFAULT_ENCODER_VAR_RAD2, stride_T_camera

        q = self.q_at(t_s)
        if q is None:
            return None
        try:
            up = (
                None
                if up_in_imu is None
                else imu_up_in_model(self.model, self.camera_T_imu, up_in_imu)
            )
            a = stride_T_camera(self.model, q, up_in_imu=up)
            self.stride_T_foot = a.stride_T_foot
            cov = a.covariance
            if up_sigma_rad is not None:
                cov = anchor_covariance(
                    a.stride_T_camera,
                    self.model.camera_covariance(q, DEFAULT_ENCODER_VAR_RAD2),
                    up_sigma_rad,
                    self.anchor_yaw_sigma_rad,
                    self.anchor_position_sigma_m,
                )
            return KinematicMeasurement(a.stride_T_camera, cov)
        except KinematicsError as err:
            log.warning("t=%.3f s: no kinematic measurement (%s)", t_s, err)
            return None

    def foot_pose(self, t_s: float) -> KinematicMeasurement | None:
        """``foot_pose`` stance: the struck foot held, the camera from the encoders at ``t_s``."""
        from kinematics.errors import KinematicsError
        from kinematics.stride_frame import DEFAULT_ENCODER_VAR_RAD2

        q = self.q_at(t_s)
        if q is None or self.stride_T_foot is None:
            return None
        try:
            cov = self.model.camera_covariance(q, DEFAULT_ENCODER_VAR_RAD2, contact="foot_flat")
            return KinematicMeasurement(self.stride_T_foot @ self.model.foot_T_camera(q), cov)
        except KinematicsError as err:
            log.warning("t=%.3f s: no kinematic measurement (%s)", t_s, err)
            return None

    def heel_strike_up(self, t_s: float) -> np.ndarray | None:
        """Up in the session's IMU frame at ``t_s`` from the encoders alone: the camera's
        attitude with the foot at the model's nominal heel-strike pitch and the leg's sagittal
        plane vertical (:func:`kinematics.stride_frame.stride_T_camera` without an up
        vector). None without a model, an encoder sample there, or when the model refuses
        the angles."""
        from kinematics.errors import KinematicsError
        from kinematics.stride_frame import stride_T_camera

        q = self.q_at(t_s)
        if q is None:
            return None
        try:
            stride_R_camera = stride_T_camera(self.model, q).stride_T_camera[:3, :3]
        except KinematicsError as err:
            log.warning("t=%.3f s: no heel-strike up vector (%s)", t_s, err)
            return None
        up = self.camera_T_imu[:3, :3].T @ (stride_R_camera.T @ np.array([0.0, 0.0, 1.0]))
        return up / np.linalg.norm(up)

    def contact_geometry(self, t_s: float) -> ContactGeometry | None:
        """Heel frame and toe point from the encoders at ``t_s`` (``contact_points`` stance)."""
        from kinematics.errors import KinematicsError

        q = self.q_at(t_s)
        if q is None:
            return None
        try:
            imu_T_foot = np.linalg.inv(self.model.foot_T_imu(q))
            foot_p_toe = self.model.frame_T_frame("heel", "toe", q)[:3, 3]
        except KinematicsError as err:
            log.warning("t=%.3f s: no kinematic measurement (%s)", t_s, err)
            return None
        return ContactGeometry(imu_T_foot, foot_p_toe)


def make_leg_kinematics(
    leg_model,
    camera_T_imu: np.ndarray,
    anchor_yaw_sigma_rad: float = 1e-3,
    anchor_position_sigma_m: float = 1e-3,
) -> LegKinematics:
    """A :class:`LegKinematics` whose joint buffer validates against ``leg_model`` (None: no
    model; :meth:`LegKinematics.add_joints` still buffers, every measurement is None)."""
    return LegKinematics(
        leg_model,
        camera_T_imu,
        JointBuffer(leg_model),
        anchor_yaw_sigma_rad,
        anchor_position_sigma_m,
    )

"""The camera's mount pitch on the thigh, estimated from the recording itself.

A converted recording knows the camera's IMU (``camera_T_imu`` from the bag) but not how the
camera sits on the thigh (its ``thigh_T_camera`` is the identity unless set by hand). The leg
model needs one number for it: the optical axis's pitch below horizontal with the leg straight
(``LegParams.mount_pitch_down_rad``). It follows from the data where the foot lies flat on level
ground during stance:

* the camera's IMU gives the direction of the specific force in the camera frame, hence the
  camera's pitch against it (:func:`camera_pitch_rad`);
* the encoders give the chain foot → shank → thigh (knee and ankle angles), hence the thigh's
  pitch against gravity with the foot flat, and — differentiating the IMU's position in the
  foot frame twice — the IMU's own acceleration, so the same specific force is predicted in
  the thigh frame (:func:`thigh_pitch_rad`). Without that compensation the estimate was off by
  up to 20° in mid-stance on the simulator: the thigh turns at ~1.5 rad/s over the foot there,
  so "low gyro rate" moments do not exist while the foot is flat;
* mount pitch = camera pitch − thigh pitch (both in the sagittal plane, about the thigh's y
  axis), per IMU sample.

Foot-flat samples: inside ``[strike + start·stance, strike + end·stance]`` of every stance (a
foot strike to its toe-off), where the gyro's rate about the thigh's y axis agrees with the rate
the encoders give for a flat foot (a rolling foot — heel or toe rocker — breaks the agreement)
and the accelerometer's magnitude agrees with the predicted specific force's (a foot slap or a
slipping foot breaks it). The estimate is the median of the samples, its spread 1.4826·MAD;
:func:`estimate_mount_pitch` refuses (:class:`MountPitchError`) with too few samples, too large
a spread, or a result outside the leg model's 30-45°. The lever arm of the IMU in the thigh
frame depends on the pitch a little: the estimate is made twice, the second time with the
first's lever arm.

:func:`graph_slam.strides.kinematics.session_leg_model` picks the source:
``pipeline.mount_pitch_deg`` when set, else the session's ``thigh_T_camera`` when it is not the
identity (the fit of :func:`~graph_slam.strides.kinematics.leg_model_for`), else this
estimate.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field

import numpy as np
from pydantic import Field, model_validator

from graph_slam.config import ConfigModel
from graph_slam.errors import MountPitchError

log = logging.getLogger(__name__)

GRAVITY_M_S2 = 9.81
MAD_TO_SIGMA = 1.4826
PITCH_RANGE_DEG = (30.0, 45.0)
"""The leg model's valid mount pitch (``LegParams``)."""


class MountEstimateConfig(ConfigModel):
    """How the mount pitch is estimated from foot-flat stance samples (docs/kinematics.md)."""

    stance_start: float = Field(
        0.15,
        ge=0,
        lt=1,
        description="foot-flat window start, as a fraction of the stance after the foot strike "
        "(past the heel rocker and the foot slap)",
    )
    stance_end: float = Field(
        0.5,
        gt=0,
        le=1,
        description="foot-flat window end, as a fraction of the stance (before heel-off)",
    )
    rate_tolerance_rad_s: float = Field(
        0.15,
        gt=0,
        description="gyro rate about the thigh's y axis vs the encoders' flat-foot rate",
    )
    accel_tolerance_m_s2: float = Field(
        1.0,
        gt=0,
        description="accelerometer magnitude vs the predicted specific force's magnitude",
    )
    smoothing_s: float = Field(
        0.08,
        gt=0,
        le=0.5,
        description="Savitzky-Golay window for the encoders' derivatives (cubic)",
    )
    min_samples: int = Field(50, ge=1, description="fewest foot-flat IMU samples accepted")
    max_spread_deg: float = Field(
        3.0, gt=0, description="largest accepted spread (1.4826·MAD) of the samples"
    )

    @model_validator(mode="after")
    def _window(self) -> MountEstimateConfig:
        if self.stance_end <= self.stance_start:
            raise ValueError("stance_end must be after stance_start")
        return self


@dataclass(frozen=True)
class MountPitchEstimate:
    """The mount pitch from foot-flat samples: median, spread (1.4826·MAD), how many."""

    pitch_deg: float
    spread_deg: float
    n_samples: int
    counts: dict[str, int] = field(default_factory=dict)
    """IMU samples in the stance windows, and rejected by reason (rate, accel, no encoders)."""


# --------------------------------------------------------------------------- geometry


def sagittal_axes(model) -> tuple[np.ndarray, np.ndarray]:
    """The thigh's y axis in the camera frame and the camera's in-plane "up" (⟂ optical axis):
    neither depends on the mount pitch (a rotation about that y axis)."""
    camera_R_thigh = model.thigh_T_frame("camera_optical")[:3, :3].T
    y_thigh = camera_R_thigh @ np.array([0.0, 1.0, 0.0])
    return y_thigh, np.cross([0.0, 0.0, 1.0], y_thigh)


def camera_pitch_rad(f_camera: np.ndarray, up_in_plane: np.ndarray) -> np.ndarray:
    """Optical axis below the direction normal to ``f`` (N×3, camera frame), in the sagittal
    plane: the camera's pitch down against gravity when ``f`` is the specific force at rest."""
    return np.arctan2(-f_camera[:, 2], f_camera @ up_in_plane)


def thigh_pitch_rad(f_thigh: np.ndarray) -> np.ndarray:
    """The thigh's x axis below the direction normal to ``f`` (N×3, thigh frame)."""
    return np.arctan2(-f_thigh[:, 0], f_thigh[:, 2])


def _foot_chain(model, q_rad: np.ndarray) -> np.ndarray:
    """(n, 4, 4) ``heel_T_thigh`` at each joint vector (limits not checked: flagged samples
    were removed by the caller's encoder checks)."""
    return np.array([model.frame_T_frame("heel", "thigh", q, check_limits=False) for q in q_rad])


# --------------------------------------------------------------------------- the estimator


@dataclass(frozen=True)
class _Stance:
    """One stance's foot-flat candidates: per IMU sample the camera-frame specific force and
    gyro, and from the encoders (foot flat) thigh_R_heel, the thigh's pitch rate and the
    chain's ``heel_T_thigh`` with its second derivative (for any IMU lever arm)."""

    f_camera: np.ndarray
    rate_gyro: np.ndarray
    thigh_R_heel: np.ndarray
    rate_chain: np.ndarray
    heel_T_thigh: np.ndarray
    heel_T_thigh_dd: np.ndarray


def _stance_samples(
    t0: float, t1: float, lo: float, hi: float, imu, joints, model, camera_R_imu, y_thigh, cfg
) -> tuple[_Stance | None, int, int]:
    """Candidates of the stance ``[t0, t1]`` in its window ``[lo, hi]``: (stance, n in window,
    n without encoder cover)."""
    from scipy.signal import savgol_filter

    imu_t, gyro, accel = imu
    joints_t, q = joints
    in_window = (imu_t >= lo) & (imu_t <= hi)
    n_window = int(in_window.sum())
    covered = in_window & (imu_t >= joints_t[0]) & (imu_t <= joints_t[-1])
    n_uncovered = n_window - int(covered.sum())
    if not covered.any():
        return None, n_window, n_uncovered
    dt = float(np.median(np.diff(joints_t)))
    grid = np.arange(max(t0, joints_t[0]), min(t1, joints_t[-1]) + 0.5 * dt, dt)
    width = max(5, round(cfg.smoothing_s / dt) | 1)
    if grid.size < width:  # too short a stance to differentiate: counted as uncovered
        return None, n_window, n_window
    q_grid = np.column_stack([np.interp(grid, joints_t, q[:, j]) for j in range(2)])
    chain = _foot_chain(model, q_grid)
    chain_dd = savgol_filter(chain, width, 3, deriv=2, delta=dt, axis=0)
    up_thigh = np.einsum("nji,j->ni", chain[:, :3, :3], [0.0, 0.0, 1.0])  # thigh_R_heel e_z
    theta = savgol_filter(np.unwrap(thigh_pitch_rad(up_thigh)), width, 3, axis=0)
    theta_dot = savgol_filter(theta, width, 3, deriv=1, delta=dt, axis=0)
    t = imu_t[covered]

    def at(values: np.ndarray) -> np.ndarray:
        flat = values.reshape(values.shape[0], -1)
        cols = [np.interp(t, grid, flat[:, k]) for k in range(flat.shape[1])]
        return np.stack(cols, axis=-1).reshape((t.size, *values.shape[1:]))

    heel_T_thigh = at(chain)
    return (
        _Stance(
            f_camera=accel[covered] @ camera_R_imu.T,
            rate_gyro=(gyro[covered] @ camera_R_imu.T) @ y_thigh,
            thigh_R_heel=np.transpose(heel_T_thigh[:, :3, :3], (0, 2, 1)),
            rate_chain=at(theta_dot),
            heel_T_thigh=heel_T_thigh,
            heel_T_thigh_dd=at(chain_dd),
        ),
        n_window,
        n_uncovered,
    )


def _pitch_samples(stance: _Stance, thigh_p_imu: np.ndarray, up_in_plane: np.ndarray, cfg):
    """Per-sample mount pitch (rad) and the rate/accel agreement masks for one lever arm."""
    p = np.r_[thigh_p_imu, 1.0]
    a_heel = stance.heel_T_thigh_dd @ p  # the IMU's acceleration, foot (= level ground) frame
    f_heel = a_heel[:, :3] + [0.0, 0.0, GRAVITY_M_S2]
    f_thigh = np.einsum("nij,nj->ni", stance.thigh_R_heel, f_heel)
    pitch = camera_pitch_rad(stance.f_camera, up_in_plane) - thigh_pitch_rad(f_thigh)
    pitch = (pitch + math.pi) % (2 * math.pi) - math.pi
    rate_ok = np.abs(stance.rate_gyro - stance.rate_chain) <= cfg.rate_tolerance_rad_s
    accel_ok = (
        np.abs(np.linalg.norm(stance.f_camera, axis=1) - np.linalg.norm(f_heel, axis=1))
        <= cfg.accel_tolerance_m_s2
    )
    return pitch, rate_ok, accel_ok


def estimate_mount_pitch(
    imu_t_s: np.ndarray,
    gyro_rad_s: np.ndarray,
    accel_m_s2: np.ndarray,
    joints_t_s: np.ndarray,
    q_rad: np.ndarray,
    foot_strikes_s: np.ndarray,
    toe_offs_s: np.ndarray,
    camera_T_imu: np.ndarray,
    config: MountEstimateConfig | None = None,
    *,
    leg=None,
    where: str = "session",
) -> MountPitchEstimate:
    """The camera's mount pitch (deg below horizontal, leg straight) from foot-flat stance.

    ``imu_*``: the camera's IMU (IMU frame; rad/s, m/s²); ``joints_t_s``, ``q_rad`` (N×2,
    knee and ankle) and the events on the same clock; ``camera_T_imu`` the IMU's pose in the
    camera frame; ``leg``: the leg's :class:`~kinematics.leg_params.LegParams` (its pitch is
    ignored; defaults otherwise). Raises :class:`MountPitchError` naming ``where`` and the
    rule when too few foot-flat samples remain, their spread is too large, or the result is
    outside 30-45°.
    """
    from kinematics.leg_model import LegModel
    from kinematics.leg_params import LegParams

    cfg = config or MountEstimateConfig()
    params = leg or LegParams()
    model = LegModel(params)
    _, up_in_plane = sagittal_axes(model)
    camera_R_imu = np.asarray(camera_T_imu, float)[:3, :3]
    imu = (np.asarray(imu_t_s, float), np.asarray(gyro_rad_s, float), np.asarray(accel_m_s2, float))
    joints, n_dropped = _usable_joints(joints_t_s, q_rad, model, where)
    if joints[0].size < 2 or imu[0].size == 0:
        raise MountPitchError(
            f"{where}: estimating the camera's mount pitch needs the IMU and the joint "
            "encoders; set pipeline.mount_pitch_deg"
        )
    counts = {"encoder_rows_dropped": n_dropped, "stances": 0, "in_window": 0}
    counts |= {"no_encoders": 0, "rate": 0, "accel": 0, "used": 0}
    stances = _stances(foot_strikes_s, toe_offs_s, imu, joints, model, camera_R_imu, cfg, counts)
    pitch_rad = params.mount_pitch_down_rad
    for _ in range(2):  # the lever arm of the IMU in the thigh frame depends on the pitch
        leg_now = LegParams(**{**params.to_dict(), "mount_pitch_down_rad": _clamp(pitch_rad)})
        thigh_T_camera = LegModel(leg_now).thigh_T_frame("camera_optical")
        thigh_p_imu = (thigh_T_camera @ np.asarray(camera_T_imu, float))[:3, 3]
        samples, rate_bad, accel_bad = [], 0, 0
        for stance in stances:
            pitch, rate_ok, accel_ok = _pitch_samples(stance, thigh_p_imu, up_in_plane, cfg)
            rate_bad += int((~rate_ok).sum())
            accel_bad += int((rate_ok & ~accel_ok).sum())
            samples.append(pitch[rate_ok & accel_ok])
        values = np.degrees(np.concatenate(samples)) if samples else np.zeros(0)
        if values.size < cfg.min_samples:
            break
        pitch_rad = math.radians(float(np.median(values)))
    counts.update(rate=rate_bad, accel=accel_bad, used=int(values.size))
    return _checked(values, counts, cfg, where)


def _stances(strikes_s, offs_s, imu, joints, model, camera_R_imu, cfg, counts) -> list[_Stance]:
    """Every stance's foot-flat candidates (a foot strike to the first toe-off before the next
    strike; a strike without one is no stance); ``counts`` updated."""
    y_thigh, _ = sagittal_axes(model)
    strikes, offs = np.sort(strikes_s), np.sort(offs_s)
    stances: list[_Stance] = []
    for k, t0 in enumerate(strikes):
        t_next = strikes[k + 1] if k + 1 < strikes.size else np.inf
        after = offs[(offs > t0) & (offs < t_next)]
        if after.size == 0:
            continue
        t1 = float(after[0])
        lo, hi = t0 + cfg.stance_start * (t1 - t0), t0 + cfg.stance_end * (t1 - t0)
        stance, n_window, n_uncovered = _stance_samples(
            t0, t1, lo, hi, imu, joints, model, camera_R_imu, y_thigh, cfg
        )
        counts["stances"] += 1
        counts["in_window"] += n_window
        counts["no_encoders"] += n_uncovered
        if stance is not None:
            stances.append(stance)
    return stances


def _usable_joints(joints_t_s, q_rad, model, where: str):
    """The encoder rows :func:`kinematics.encoders.check_encoders` passes (NaN, limits,
    impossible jumps flagged), and how many were dropped."""
    from kinematics.encoders import check_encoders

    t, q = np.asarray(joints_t_s, float), np.asarray(q_rad, float)
    if t.size == 0:
        return (t, q.reshape(0, 2)), 0
    check = check_encoders(t, q, model.joint_names, model, source=f"{where} (joints)")
    usable = check.usable
    return (t[usable], q[usable]), int((~usable).sum())


def _clamp(pitch_rad: float) -> float:
    lo, hi = (math.radians(v) for v in PITCH_RANGE_DEG)
    return min(max(pitch_rad, lo), hi)


def _checked(values: np.ndarray, counts: dict, cfg: MountEstimateConfig, where: str):
    """The estimate, or :class:`MountPitchError` stating which rule failed."""
    fix = "set pipeline.mount_pitch_deg (or calibration.thigh_T_camera) by hand"
    if values.size < cfg.min_samples:
        raise MountPitchError(
            f"{where}: {values.size} foot-flat IMU samples for the camera's mount pitch, need "
            f">= {cfg.min_samples} (pipeline.mount_estimate.min_samples; {counts['stances']} "
            f"stances, {counts['in_window']} samples in their windows, rejected: "
            f"{counts['rate']} gyro rate, {counts['accel']} accel, {counts['no_encoders']} "
            f"without encoders); {fix}"
        )
    median = float(np.median(values))
    spread = MAD_TO_SIGMA * float(np.median(np.abs(values - median)))
    if spread > cfg.max_spread_deg:
        raise MountPitchError(
            f"{where}: the camera's mount pitch from {values.size} foot-flat samples spreads "
            f"{spread:.2f}° (1.4826·MAD), more than pipeline.mount_estimate.max_spread_deg="
            f"{cfg.max_spread_deg}; median {median:.2f}°; {fix}"
        )
    lo, hi = PITCH_RANGE_DEG
    if not lo <= median <= hi:
        raise MountPitchError(
            f"{where}: the camera's mount pitch estimated at {median:.2f}° (spread "
            f"{spread:.2f}°, {values.size} foot-flat samples) is outside the leg model's "
            f"valid {lo:g}-{hi:g}° below horizontal; {fix}"
        )
    return MountPitchEstimate(median, spread, int(values.size), dict(counts))

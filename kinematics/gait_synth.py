"""Thigh-IMU signals synthesised from gait kinematics, and "true" gait events to score against.

Two sources of thigh motion:

* :func:`read_opensim_mot` + :func:`thigh_imu_from_opensim`: a real OpenSim inverse-kinematics
  trial (Gait2392 coordinates). The thigh's orientation is the full pelvis (tilt, list,
  rotation) times hip (flexion, adduction, rotation) chain, so its sagittal angle is pelvis
  tilt + hip flexion and the out-of-plane motion of the real trial is kept. Positions come
  from the pelvis translation and the model's hip offset.
* :func:`thigh_imu_from_reference`: walking at a given speed from the reference curves
  (:mod:`kinematics.gait_curves`), with standing still before and after.

Both add a mounting rotation (any), white noise and a constant bias to gyro and accelerometer
(:class:`ImuNoise`).

True events of the OpenSim trial (:func:`opensim_true_events`) come from its kinematics by the
coordinate-based method of Zeni, Richards & Higginson (Gait & Posture 27:710, 2008): foot
strike at the most anterior position of the heel relative to the pelvis, toe-off at the most
posterior position of the toe. Zeni et al. validated it against force plates (foot strike
within about one 60 Hz frame for most steps). The heel and toe come from a sagittal-plane
chain with the Gait2392 default segment geometry (hip offset, femur 0.40 m, tibia 0.43 m,
talus-calcaneus and toe offsets); only the timing of the extremes is used, which the exact
lengths barely change.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.signal import find_peaks
from scipy.spatial.transform import Rotation

from kinematics.errors import GaitInputError
from kinematics.imu import ImuSeries

GRAVITY_M_S2 = 9.81

# Gait2392 default geometry (metres, OpenSim axes: x forward, y up, z right).
_HIP_IN_PELVIS = np.array([-0.0707, -0.0661, 0.0835])
_FEMUR_M = 0.40
_TIBIA_M = 0.43
_HEEL_IN_TALUS = np.array([-0.04877, -0.04195])  # calcaneus origin ~ heel
_TOE_IN_TALUS = np.array([-0.04877 + 0.1788, -0.04195 - 0.002])
_IMU_IN_FEMUR = np.array([0.0, -0.25, 0.07])  # lateral on the thigh (z mirrored for left)


@dataclass(frozen=True)
class ImuNoise:
    """White noise (per-sample sigma) and bias (drawn uniformly in ±max per axis)."""

    gyro_sigma_rad_s: float = 0.03
    gyro_bias_max_rad_s: float = 0.05
    accel_sigma_m_s2: float = 0.1
    accel_bias_max_m_s2: float = 0.3


@dataclass(frozen=True)
class OpenSimMotion:
    """An OpenSim .mot coordinates file: time and columns (angles converted to radians)."""

    t_s: np.ndarray
    columns: dict[str, np.ndarray]
    source: str

    def angle(self, name: str) -> np.ndarray:
        if name not in self.columns:
            raise GaitInputError(f"{self.source}: no column {name!r}")
        return self.columns[name]


def read_opensim_mot(path: str | Path) -> OpenSimMotion:
    """Read an OpenSim .mot (header up to ``endheader``, then a tab/space table)."""
    path = Path(path)
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except OSError as err:
        raise GaitInputError(f"{path}: cannot read ({err.strerror})") from None
    try:
        end = next(i for i, line in enumerate(lines) if line.strip() == "endheader")
    except StopIteration:
        raise GaitInputError(f"{path}: no 'endheader' line (not an OpenSim .mot)") from None
    header = {k.strip(): v.strip() for k, _, v in (ln.partition("=") for ln in lines[:end])}
    in_degrees = header.get("inDegrees", "no").lower() == "yes"
    names = lines[end + 1].split()
    rows = []
    for i, line in enumerate(lines[end + 2 :], start=end + 3):
        if not line.strip():
            continue
        parts = line.split()
        if len(parts) != len(names):
            raise GaitInputError(f"{path}: line {i} has {len(parts)} values, expected {len(names)}")
        try:
            rows.append([float(x) for x in parts])
        except ValueError:
            raise GaitInputError(f"{path}: line {i} has a non-numeric value") from None
    data = np.asarray(rows)
    if data.shape[0] < 10 or "time" not in names:
        raise GaitInputError(f"{path}: need a 'time' column and at least 10 rows")
    cols: dict[str, np.ndarray] = {}
    for j, name in enumerate(names):
        col = data[:, j]
        is_translation = name.endswith(("_tx", "_ty", "_tz")) or name == "time"
        cols[name] = np.radians(col) if in_degrees and not is_translation else col
    t = cols.pop("time")
    if np.any(np.diff(t) <= 0):
        raise GaitInputError(f"{path}: time must increase strictly")
    return OpenSimMotion(t_s=t, columns=cols, source=str(path))


def _sagittal_chain(motion: OpenSimMotion, side: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pelvis, heel and toe positions (N, 2) in the sagittal plane (x forward, y up)."""
    tilt = motion.angle("pelvis_tilt")
    thigh = tilt + motion.angle(f"hip_flexion_{side}")
    shank = thigh + motion.angle(f"knee_angle_{side}")  # knee flexion is negative in Gait2392
    foot = shank + motion.angle(f"ankle_angle_{side}")

    def rot(a: np.ndarray, v: np.ndarray) -> np.ndarray:
        c, s = np.cos(a), np.sin(a)
        return np.stack([c * v[0] - s * v[1], s * v[0] + c * v[1]], axis=-1)

    pelvis = np.stack([motion.angle("pelvis_tx"), motion.angle("pelvis_ty")], axis=-1)
    hip = pelvis + rot(tilt, _HIP_IN_PELVIS[:2])
    knee = hip + rot(thigh, np.array([0.0, -_FEMUR_M]))
    ankle = knee + rot(shank, np.array([0.0, -_TIBIA_M]))
    return pelvis, ankle + rot(foot, _HEEL_IN_TALUS), ankle + rot(foot, _TOE_IN_TALUS)


def _extremes(t: np.ndarray, y: np.ndarray, maximum: bool, min_separation_s: float) -> np.ndarray:
    """Times of interior extremes of y (parabolic sub-sample refinement)."""
    sig = y if maximum else -y
    dt = float(np.median(np.diff(t)))
    height = float(np.mean(sig) + 0.25 * np.ptp(sig))
    peaks, _ = find_peaks(sig, distance=max(1, int(min_separation_s / dt)), height=height)
    out = []
    for k in peaks:
        if 0 < k < len(t) - 1:
            a, b, c = sig[k - 1], sig[k], sig[k + 1]
            den = a - 2 * b + c
            off = 0.5 * (a - c) / den if den != 0 else 0.0
            out.append(t[k] + off * dt)
    return np.asarray(out)


def opensim_true_events(motion: OpenSimMotion, side: str = "r") -> dict[str, np.ndarray]:
    """Foot strikes and toe-offs of one leg by Zeni's method (see the module docstring).

    Extremes at the very first or last sample are not events (the trial may start or end
    there), so an event within one frame of either end is not returned.
    """
    if side not in ("r", "l"):
        raise GaitInputError(f"side={side!r}: must be 'r' or 'l'")
    pelvis, heel, toe = _sagittal_chain(motion, side)
    t = motion.t_s
    strikes = _extremes(t, heel[:, 0] - pelvis[:, 0], maximum=True, min_separation_s=0.6)
    toe_offs = _extremes(t, toe[:, 0] - pelvis[:, 0], maximum=False, min_separation_s=0.6)
    return {
        "foot_strike": strikes,
        "toe_off": toe_offs,
        "heel_height_m": heel[:, 1] - heel[:, 1].min(),
    }


def _rz(a: np.ndarray) -> Rotation:
    return Rotation.from_rotvec(np.outer(a, [0.0, 0.0, 1.0]))


def _rx(a: np.ndarray) -> Rotation:
    return Rotation.from_rotvec(np.outer(a, [1.0, 0.0, 0.0]))


def _ry(a: np.ndarray) -> Rotation:
    return Rotation.from_rotvec(np.outer(a, [0.0, 1.0, 0.0]))


def _imu_from_pose_functions(
    t: np.ndarray,
    world_R_thigh: Callable[[np.ndarray], Rotation],
    world_p_imu: Callable[[np.ndarray], np.ndarray],
    *,
    up_axis: np.ndarray,
    thigh_R_sensor: np.ndarray,
    noise: ImuNoise,
    rng: np.random.Generator,
    source: str,
) -> ImuSeries:
    """Gyro/accel in the sensor frame from thigh orientation and IMU position functions."""
    h = 1e-4
    r_minus, r_0, r_plus = world_R_thigh(t - h), world_R_thigh(t), world_R_thigh(t + h)
    omega_thigh = (r_0.inv() * r_plus).as_rotvec() / (2 * h) - (r_0.inv() * r_minus).as_rotvec() / (
        2 * h
    )
    hp = 1e-3
    acc_world = (world_p_imu(t + hp) - 2 * world_p_imu(t) + world_p_imu(t - hp)) / hp**2
    f_world = acc_world + GRAVITY_M_S2 * up_axis  # specific force = a - g, g = -9.81 up
    f_thigh = r_0.inv().apply(f_world)
    gyro = omega_thigh @ thigh_R_sensor  # R^T w for each row
    accel = f_thigh @ thigh_R_sensor
    gyro_bias = rng.uniform(-noise.gyro_bias_max_rad_s, noise.gyro_bias_max_rad_s, 3)
    accel_bias = rng.uniform(-noise.accel_bias_max_m_s2, noise.accel_bias_max_m_s2, 3)
    gyro = gyro + gyro_bias + rng.normal(0.0, noise.gyro_sigma_rad_s, gyro.shape)
    accel = accel + accel_bias + rng.normal(0.0, noise.accel_sigma_m_s2, accel.shape)
    return ImuSeries(t_s=t, gyro_rad_s=gyro, accel_m_s2=accel, source=source)


def thigh_imu_from_opensim(
    motion: OpenSimMotion,
    side: str = "r",
    *,
    rate_hz: float = 200.0,
    thigh_R_sensor: np.ndarray | None = None,
    noise: ImuNoise | None = None,
    seed: int = 0,
) -> ImuSeries:
    """Thigh-IMU signals over the trial, sampled at ``rate_hz`` (cubic-spline interpolation).

    ``thigh_R_sensor`` is the mounting rotation (identity when None); the thigh frame is the
    Gait2392 femur frame (x forward, y up along the thigh, z to the right).
    """
    if side not in ("r", "l"):
        raise GaitInputError(f"side={side!r}: must be 'r' or 'l'")
    mirror = 1.0 if side == "r" else -1.0
    rng = np.random.default_rng(seed)
    t_src = motion.t_s
    splines = {
        name: CubicSpline(t_src, motion.angle(name))
        for name in (
            "pelvis_tilt",
            "pelvis_list",
            "pelvis_rotation",
            "pelvis_tx",
            "pelvis_ty",
            "pelvis_tz",
            f"hip_flexion_{side}",
            f"hip_adduction_{side}",
            f"hip_rotation_{side}",
        )
    }

    def pelvis_r(t: np.ndarray) -> Rotation:
        return (
            _rz(splines["pelvis_tilt"](t))
            * _rx(splines["pelvis_list"](t))
            * _ry(splines["pelvis_rotation"](t))
        )

    def world_r_thigh(t: np.ndarray) -> Rotation:
        hip = (
            _rz(splines[f"hip_flexion_{side}"](t))
            * _rx(mirror * splines[f"hip_adduction_{side}"](t))
            * _ry(mirror * splines[f"hip_rotation_{side}"](t))
        )
        return pelvis_r(t) * hip

    hip_off = _HIP_IN_PELVIS * np.array([1.0, 1.0, mirror])
    imu_off = _IMU_IN_FEMUR * np.array([1.0, 1.0, mirror])

    def world_p_imu(t: np.ndarray) -> np.ndarray:
        p = np.stack([splines[f"pelvis_t{a}"](t) for a in "xyz"], axis=-1)
        return p + pelvis_r(t).apply(hip_off) + world_r_thigh(t).apply(imu_off)

    dt = 1.0 / rate_hz
    t = np.arange(t_src[0] + 2e-3, t_src[-1] - 2e-3, dt)
    mount = np.eye(3) if thigh_R_sensor is None else np.asarray(thigh_R_sensor, dtype=float)
    return _imu_from_pose_functions(
        t,
        world_r_thigh,
        world_p_imu,
        up_axis=np.array([0.0, 1.0, 0.0]),
        thigh_R_sensor=mount,
        noise=noise or ImuNoise(),
        rng=rng,
        source=f"{motion.source} ({side} thigh, synthetic IMU)",
    )


@dataclass(frozen=True)
class SimulatedWalk:
    """A synthetic thigh-IMU recording with its true events."""

    imu: ImuSeries
    foot_strikes_s: np.ndarray
    toe_offs_s: np.ndarray
    speed_m_s: float


def _smoothstep(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3 - 2 * x)


def thigh_imu_from_reference(
    speed_m_s: float,
    *,
    n_strides: int = 8,
    standing_s: float = 3.0,
    rate_hz: float = 200.0,
    thigh_R_sensor: np.ndarray | None = None,
    noise: ImuNoise | None = None,
    seed: int = 0,
    stride_time_jitter: float = 0.02,
) -> SimulatedWalk:
    """Stand, walk ``n_strides`` at ``speed_m_s`` from the reference curves, stand again.

    The walk starts at mid-stance (phase 0.3) from standing, blending from the standing posture
    into the curves before the first swing, and stops after the last foot strike: the stance
    goes on normally to mid-stance (phase N + 0.3), then blends back to standing by N + 0.5,
    before toe-off. So the true foot strikes are
    the ``n_strides`` times the phase reaches an integer, and the true toe-offs the
    ``n_strides`` times it reaches k + stance fraction (k = 0 .. n_strides - 1).
    Stride times vary by ``stride_time_jitter`` (relative sigma, seeded). Out-of-plane thigh
    motion (3 deg ab/adduction, 5 deg rotation) and a standing sway of about 1 deg are added.
    """
    from kinematics.gait_curves import stance_fraction, stride_time_s, thigh_angle

    rng = np.random.default_rng(seed)
    t_stride = stride_time_s(speed_m_s)
    durations = t_stride * (1 + stride_time_jitter * rng.standard_normal(n_strides + 1))
    phase_start, phase_end = 0.3, n_strides + 0.5
    # phase knots: phase 0.3 at standing_s, integer phases at cumulative stride durations
    knots_phase = np.concatenate([[phase_start], np.arange(1, n_strides + 1), [phase_end]])
    seg = np.diff(knots_phase) * durations[: len(knots_phase) - 1]
    knots_t = standing_s + np.concatenate([[0.0], np.cumsum(seg)])
    t_end_walk = knots_t[-1]
    total = t_end_walk + standing_s
    dt = 1.0 / rate_hz
    fine_t = np.arange(0.0, total, dt / 4)
    phase_fn = CubicSpline(knots_t, knots_phase, bc_type="natural")
    sway_f = rng.uniform(0.15, 0.5, 3)
    sway_p = rng.uniform(0, 2 * np.pi, 3)

    def fields(t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        t = np.asarray(t, dtype=float)
        ph = phase_fn(np.clip(t, knots_t[0], knots_t[-1]))
        w_on = _smoothstep((ph - phase_start) / 0.25)  # blend in over phase 0.3-0.55
        w_off = 1.0 - _smoothstep((ph - (phase_end - 0.2)) / 0.2)  # out over N+0.3-N+0.5
        walking = (t > knots_t[0]) & (t < knots_t[-1])
        w = np.where(walking, np.minimum(w_on, w_off), 0.0)
        stand = math.radians(2.0) + sum(
            math.radians(0.4) * np.sin(2 * np.pi * f * t + p)
            for f, p in zip(sway_f, sway_p, strict=True)
        )
        sag = stand + w * (thigh_angle(ph % 1.0, speed_m_s) - stand)
        cyc = 2 * np.pi * ph
        add = w * math.radians(3.0) * np.sin(cyc + 0.5)
        rot = w * math.radians(5.0) * np.sin(cyc - 0.8)
        return sag, add, rot, w

    def world_r_thigh(t: np.ndarray) -> Rotation:
        sag, add, rot, _ = fields(t)
        # world: x forward, y left, z up; flexion = knee forward = rotation about -y
        return _ry(-sag) * _rx(add) * _rz(rot)

    pos_fine = np.zeros((fine_t.size, 3))
    ph_fine = phase_fn(np.clip(fine_t, knots_t[0], knots_t[-1]))
    _, _, _, w_fine = fields(fine_t)
    vel = np.where((fine_t > knots_t[0]) & (fine_t < knots_t[-1]), speed_m_s * w_fine, 0.0)
    pos_fine[:, 0] = np.cumsum(vel) * (dt / 4)
    pos_fine[:, 2] = 0.9 + w_fine * 0.02 * np.cos(4 * np.pi * ph_fine)
    pos_splines = [CubicSpline(fine_t, pos_fine[:, i]) for i in range(3)]

    def world_p_imu(t: np.ndarray) -> np.ndarray:
        hip = np.stack([s(np.clip(t, fine_t[0], fine_t[-1])) for s in pos_splines], axis=-1)
        return hip + world_r_thigh(t).apply(np.array([0.0, -0.07, -0.25]))

    t = np.arange(0.0, total - dt, dt) + 1e-3
    mount = np.eye(3) if thigh_R_sensor is None else np.asarray(thigh_R_sensor, dtype=float)
    imu = _imu_from_pose_functions(
        t,
        world_r_thigh,
        world_p_imu,
        up_axis=np.array([0.0, 0.0, 1.0]),
        thigh_R_sensor=mount,
        noise=noise or ImuNoise(),
        rng=rng,
        source=f"reference curves {speed_m_s} m/s (synthetic IMU)",
    )
    strikes = knots_t[1:-1]
    sf = stance_fraction(speed_m_s)
    toe_offs = np.array([float(_invert(phase_fn, k + sf, knots_t)) for k in range(n_strides)])
    return SimulatedWalk(imu=imu, foot_strikes_s=strikes, toe_offs_s=toe_offs, speed_m_s=speed_m_s)


def _invert(fn: CubicSpline, value: float, knots_t: np.ndarray) -> float:
    """Time at which the monotonic spline ``fn`` reaches ``value`` (bisection)."""
    lo, hi = float(knots_t[0]), float(knots_t[-1])
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if fn(mid) < value:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def random_mounting(seed: int) -> np.ndarray:
    """A seeded uniformly random rotation (thigh_R_sensor)."""
    return Rotation.random(random_state=np.random.default_rng(seed)).as_matrix()

"""Sensor models: depth noise and dropouts, frame drops, IMU, joint encoders, load cell.

Every function takes an explicit ``numpy.random.Generator`` (seeded by the caller) and a
``noise_scale`` that multiplies every noise σ (0 = noise-free, for known-answer tests).
"""

from __future__ import annotations

import math

import numpy as np

from graph_slam.session.records import GaitEvents, ImuSeries, JointSeries
from graph_slam.sim.config import DepthNoise, DropModel, ImuProfile, ProsthesisProfile
from graph_slam.sim.motion import GaitMotion

# --------------------------------------------------------------------------- depth


def depth_sigma_m(z_m: np.ndarray, noise: DepthNoise, noise_scale: float = 1.0) -> np.ndarray:
    """Depth noise σ at depth z: ``sigma_at_1m · z^exponent + floor``, times ``noise_scale``."""
    return noise_scale * (noise.sigma_at_1m_m * np.power(z_m, noise.exponent) + noise.sigma_floor_m)


def apply_depth_noise(
    depth_m: np.ndarray,
    cos_incidence: np.ndarray,
    noise: DepthNoise,
    rng: np.random.Generator,
    *,
    noise_scale: float = 1.0,
    min_range_m: float = 0.0,
    max_range_m: float = np.inf,
) -> np.ndarray:
    """Noisy float32 depth (0 = invalid) from exact depth (0 or inf = no hit).

    Order: grazing-angle dropout, edge dropout and flying pixels (an edge is a 4-neighbour
    depth jump > ``edge_threshold_m``), random dropout, Gaussian noise σ(z), range limits.
    With ``noise_scale = 0`` only the range limits and the grazing-angle rule apply.
    """
    z = np.where(np.isfinite(depth_m), depth_m, 0.0).astype(np.float32)
    valid = z > 0
    valid &= cos_incidence >= noise.grazing_cos_min
    h, w = z.shape
    if noise_scale > 0:
        # Edges: largest absolute jump to a 4-neighbour (invalid neighbours count as far).
        far = np.where(valid, z, np.float32(1e3))
        pad = np.pad(far, 1, mode="edge")
        jump = np.zeros_like(z)
        neighbour = far.copy()
        for dy, dx in ((0, 1), (0, -1), (1, 0), (-1, 0)):
            nb = pad[1 + dy : 1 + dy + h, 1 + dx : 1 + dx + w]
            d = np.abs(nb - far)
            bigger = d > jump
            jump = np.where(bigger, d, jump)
            neighbour = np.where(bigger, nb, neighbour)
        edge = valid & (jump > noise.edge_threshold_m)
        n_edge = int(edge.sum())
        if n_edge:
            u = rng.random(n_edge)
            idx = np.flatnonzero(edge)
            drop = u < noise.edge_dropout_prob
            p_fly = (
                noise.edge_dropout_prob + (1 - noise.edge_dropout_prob) * noise.flying_pixel_prob
            )
            fly = (~drop) & (u < p_fly)
            flat = z.reshape(-1)
            valid.reshape(-1)[idx[drop]] = False
            fly_idx = idx[fly]
            nb = neighbour.reshape(-1)[fly_idx]
            nb_ok = nb < 1e3
            mix = rng.random(fly_idx.size).astype(np.float32)
            mixed = flat[fly_idx] + mix * (nb - flat[fly_idx])
            flat[fly_idx] = np.where(nb_ok, mixed, flat[fly_idx])
        if noise.random_dropout_prob > 0:
            valid &= rng.random((h, w), dtype=np.float32) >= noise.random_dropout_prob
        sigma = depth_sigma_m(z, noise, noise_scale).astype(np.float32)
        z = z + sigma * rng.standard_normal((h, w), dtype=np.float32)
    valid &= (z >= min_range_m) & (z <= max_range_m)
    return np.where(valid, z, np.float32(0.0)).astype(np.float32)


# --------------------------------------------------------------------------- frame drops


def frame_schedule(
    duration_s: float, rate_hz: float, drops: DropModel, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """Capture times of the frames that survive, and their index in the nominal 90 Hz grid.

    Capture times are the nominal grid plus Gaussian jitter (kept strictly increasing).
    ``none`` keeps every frame; ``random`` keeps each with ``keep_prob``; ``bursty`` runs a
    two-state (Gilbert-Elliott) chain that starts in the good state.
    """
    n = math.floor(duration_s * rate_hz) + 1
    nominal = np.arange(n) / rate_hz
    jitter = drops.jitter_s * rng.standard_normal(n)
    jitter = np.clip(jitter, -0.4 / rate_hz, 0.4 / rate_hz)
    t = np.clip(nominal + jitter, 0.0, duration_s)
    u = rng.random(n)
    if drops.model == "none":
        keep = np.ones(n, dtype=bool)
    elif drops.model == "random":
        keep = u < drops.keep_prob
    else:
        switch = rng.random(n)
        keep = np.zeros(n, dtype=bool)
        bad = False
        for i in range(n):
            keep[i] = u[i] < (drops.bad_keep_prob if bad else drops.good_keep_prob)
            bad = (switch[i] >= drops.p_bad_to_good) if bad else (switch[i] < drops.p_good_to_bad)
    idx = np.flatnonzero(keep)
    times = t[idx]
    ok = np.concatenate([[True], np.diff(times) > 0])
    return times[ok], idx[ok]


# --------------------------------------------------------------------------- IMU


def simulate_imu(
    motion: GaitMotion,
    thigh_T_imu: np.ndarray,
    profile: ImuProfile,
    rng: np.random.Generator,
    *,
    rate_hz: float | None = None,
    noise_scale: float = 1.0,
    accel_range_g: float | None = None,
    time_offset_s: float = 0.0,
    gravity_m_s2: float = 9.81,
) -> tuple[ImuSeries, ImuSeries]:
    """(measured, ideal) IMU series stamped on the IMU clock.

    A sample stamped ``t`` happened at session (camera) time ``t + time_offset_s`` (the
    :class:`~graph_slam.session.records.Calibration` convention). Discrete white noise
    σ_d = density·√rate; bias random walk b_{k+1} = b_k + σ_rw·√dt·N(0, 1) from a turn-on bias;
    saturation clips at ±range.
    """
    rate = float(rate_hz or profile.rate_hz)
    n = math.floor(motion.duration_s * rate) + 1
    t_stamp = np.arange(n) / rate
    t_true = t_stamp + time_offset_s
    keep = (t_true >= 0.0) & (t_true <= motion.duration_s)
    t_stamp, t_true = t_stamp[keep], t_true[keep]
    gyro, accel = motion.imu_ideal(t_true, thigh_T_imu)
    ideal = ImuSeries(t_stamp, gyro, accel)
    dt = 1.0 / rate
    s = noise_scale
    m = t_stamp.size

    def biased(signal, density, walk, turn_on):
        bias0 = s * turn_on * rng.standard_normal(3)
        steps = s * walk * math.sqrt(dt) * rng.standard_normal((m, 3))
        bias = bias0 + np.cumsum(steps, axis=0)
        white = s * density * math.sqrt(rate) * rng.standard_normal((m, 3))
        return signal + bias + white

    gyro_m = biased(
        gyro,
        profile.gyro_noise_density_rad_s_sqrt_hz,
        profile.gyro_random_walk_rad_s2_sqrt_hz,
        profile.gyro_bias_sigma_rad_s,
    )
    accel_m = biased(
        accel,
        profile.accel_noise_density_m_s2_sqrt_hz,
        profile.accel_random_walk_m_s3_sqrt_hz,
        profile.accel_bias_sigma_m_s2,
    )
    a_range = accel_range_g if accel_range_g is not None else profile.accel_range_g
    if a_range is not None:
        limit = a_range * gravity_m_s2
        accel_m = np.clip(accel_m, -limit, limit)
    if profile.gyro_range_rad_s is not None:
        gyro_m = np.clip(gyro_m, -profile.gyro_range_rad_s, profile.gyro_range_rad_s)
    return ImuSeries(t_stamp, gyro_m, accel_m), ideal


# --------------------------------------------------------------------------- prosthesis


def simulate_encoders(
    motion: GaitMotion,
    profile: ProsthesisProfile,
    rng: np.random.Generator,
    *,
    noise_scale: float = 1.0,
) -> tuple[JointSeries, JointSeries]:
    """(measured, true) knee and ankle angles: noise, then quantisation to 2π / 2^bits."""
    n = math.floor(motion.duration_s * profile.encoder_rate_hz) + 1
    t = np.arange(n) / profile.encoder_rate_hz
    knee, ankle = motion.joint_angles(t)
    true = JointSeries(t, knee, ankle)
    step = 2.0 * math.pi / 2**profile.encoder_bits
    sigma = noise_scale * profile.encoder_noise_rad

    def measure(x: np.ndarray) -> np.ndarray:
        noisy = x + sigma * rng.standard_normal(x.size)
        return np.round(noisy / step) * step if noise_scale > 0 else noisy

    return JointSeries(t, measure(knee), measure(ankle)), true


def true_events(motion: GaitMotion) -> GaitEvents:
    """Foot strikes and toe-offs of the prosthetic leg from the motion (source ``truth``)."""
    return _events(motion.foot_strikes_s, motion.toe_offs_s, "truth", motion.duration_s)


def load_cell_events(
    motion: GaitMotion,
    profile: ProsthesisProfile,
    rng: np.random.Generator,
    *,
    noise_scale: float = 1.0,
) -> GaitEvents:
    """What the load cell reports: each true event delayed by latency + jitter (≥ 0)."""

    def delay(n: int) -> np.ndarray:
        jitter = noise_scale * profile.load_cell_jitter_s * rng.standard_normal(n)
        return np.maximum(profile.load_cell_latency_s + jitter, 0.0)

    strikes = motion.foot_strikes_s + delay(motion.foot_strikes_s.size)
    toe_offs = motion.toe_offs_s + delay(motion.toe_offs_s.size)
    return _events(strikes, toe_offs, "load_cell", motion.duration_s)


def _events(strikes: np.ndarray, toe_offs: np.ndarray, source: str, end_s: float) -> GaitEvents:
    t = np.concatenate([strikes, toe_offs])
    kind = np.array(["foot_strike"] * strikes.size + ["toe_off"] * toe_offs.size)
    keep = (t >= 0) & (t <= end_s)
    t, kind = t[keep], kind[keep]
    order = np.argsort(t, kind="stable")
    return GaitEvents(t[order], tuple(kind[order]), (source,) * int(order.size))

"""Foot strikes of the ``imu-online`` event source on simulated sessions, against the truth.

For each speed and seed, the simulator's session IMU (:func:`graph_slam.sim.recording.prepare`
and :func:`graph_slam.sim.sensors.simulate_imu`, as ``graph-slam simulate`` writes it; no
rendering) goes through :func:`graph_slam.strides.online_events.online_stride_events`; prints
the strikes matched to the true ones (within 0.25 s), their error (estimated − true: median,
worst |·|), the latency (known − true: p95 over all, and over the strikes after the first emission: a
session that starts mid-walk, 0.25 s before a strike, has no standing start, so its strikes up
to then come out when the axis is learned), and how many were placed on the heel-contact
shock (``impact_strikes`` of the estimator).

    python examples/sim_imu_online_timing.py [--seeds 3] [--strides 6] [--heel-shock 15]

``--heel-shock 0``: the simulator without the heel-contact burst (``motion.heel_shock_m_s2``).
"""

from __future__ import annotations

import argparse
import logging

import numpy as np

from graph_slam.sim.config import MotionConfig, SimConfig
from graph_slam.sim.recording import prepare
from graph_slam.sim.sensors import simulate_imu
from kinematics.gait_events import match_events
from kinematics.gait_online import estimate_online


def one(speed: float, seed: int, strides: int, shock: float):
    """(errors, latencies, missed, extra, strikes on the shock) of one simulated session."""
    motion = MotionConfig(heel_shock_m_s2=shock)
    cfg = SimConfig(speed_m_s=speed, strides=strides, seed=seed, motion=motion)
    sim = prepare(cfg)
    imu, _ = simulate_imu(sim.motion, sim.thigh_T_imu, sim.imu, np.random.default_rng([seed, 3]))
    res = estimate_online(imu)
    est, known = res.times("foot_strike"), res.times("foot_strike", detected=True)
    truth = sim.motion.foot_strikes_s
    err, missed, extra = match_events(est, truth)
    lat = [float(known[np.argmin(np.abs(est - t))] - t) for t in truth if est.size]
    found = [t for t in truth if est.size and np.min(np.abs(est - t)) < 0.25]
    lat = [x for x, t in zip(lat, truth, strict=True) if t in found]
    first_out = float(known.min()) if known.size else np.inf
    later = [x for x, t in zip(lat, found, strict=True) if t > first_out]
    return list(err), (lat, later), missed, extra, res.counts["impact_strikes"]


def _p95_ms(values: list[float]) -> str:
    return f"{np.percentile(np.asarray(values) * 1e3, 95):.0f}" if values else "–"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--strides", type=int, default=6)
    parser.add_argument("--heel-shock", type=float, default=MotionConfig().heel_shock_m_s2)
    args = parser.parse_args()
    logging.basicConfig(level=logging.ERROR)
    print("| speed m/s | true strikes | missed | extra | error median ms | worst abs ms | "
          "latency p95 ms, all / after the first emission | on the shock |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|")
    for speed in (0.8, 1.1, 1.4):
        errs, lats, rest, missed, extra, impacts, true = [], [], [], 0, 0, 0, 0
        for seed in range(1, args.seeds + 1):
            e, lat, m, x, n = one(speed, seed, args.strides, args.heel_shock)
            errs += e
            lats += lat[0]
            rest += lat[1]
            missed, extra, impacts = missed + m, extra + x, impacts + n
            true += len(e) + m
        e = np.asarray(errs) * 1e3
        print(
            f"| {speed} | {true} | {missed} | {extra} | {np.median(e):+.0f} | "
            f"{np.abs(e).max():.0f} | {_p95_ms(lats)} / {_p95_ms(rest)} | "
            f"{impacts} |"
        )


if __name__ == "__main__":
    main()

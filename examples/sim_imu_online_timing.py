"""Foot strikes of the ``imu-online`` event source on simulated sessions, against the truth.

For each speed and seed, the simulator's session IMU (:func:`graph_slam.sim.recording.prepare`
and :func:`graph_slam.sim.sensors.simulate_imu`, as ``graph-slam simulate`` writes it; no
rendering) goes through :func:`graph_slam.strides.online_events.online_stride_events`; prints
the strikes matched to the true ones (within 0.25 s), their error (estimated − true: median,
worst |·|), the latency (known − true: p95), and how many were placed on the heel-contact
shock (``impact_strikes`` of the estimator).

    python examples/sim_imu_online_timing.py [--seeds 3] [--strides 6]
"""

from __future__ import annotations

import argparse
import logging

import numpy as np

from graph_slam.sim.config import SimConfig
from graph_slam.sim.recording import prepare
from graph_slam.sim.sensors import simulate_imu
from kinematics.gait_events import match_events
from kinematics.gait_online import estimate_online


def one(speed: float, seed: int, strides: int) -> tuple[list[float], list[float], int, int, int]:
    cfg = SimConfig(speed_m_s=speed, strides=strides, seed=seed)
    sim = prepare(cfg)
    imu, _ = simulate_imu(sim.motion, sim.thigh_T_imu, sim.imu, np.random.default_rng([seed, 3]))
    res = estimate_online(imu)
    est, known = res.times("foot_strike"), res.times("foot_strike", detected=True)
    truth = sim.motion.foot_strikes_s
    err, missed, extra = match_events(est, truth)
    lat = [float(known[np.argmin(np.abs(est - t))] - t) for t in truth if est.size]
    lat = [x for x, t in zip(lat, truth, strict=True) if np.min(np.abs(est - t)) < 0.25]
    return list(err), lat, missed, extra, res.counts["impact_strikes"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--strides", type=int, default=6)
    args = parser.parse_args()
    logging.basicConfig(level=logging.ERROR)
    print("| speed m/s | true strikes | missed | extra | error median ms | worst abs ms | "
          "latency p95 ms | on the shock |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|")
    for speed in (0.8, 1.1, 1.4):
        errs, lats, missed, extra, impacts, true = [], [], 0, 0, 0, 0
        for seed in range(1, args.seeds + 1):
            e, lat, m, x, n = one(speed, seed, args.strides)
            errs += e
            lats += lat
            missed, extra, impacts = missed + m, extra + x, impacts + n
            true += len(e) + m
        e = np.asarray(errs) * 1e3
        print(
            f"| {speed} | {true} | {missed} | {extra} | {np.median(e):+.0f} | "
            f"{np.abs(e).max():.0f} | {np.percentile(np.asarray(lats) * 1e3, 95):.0f} | "
            f"{impacts} |"
        )


if __name__ == "__main__":
    main()

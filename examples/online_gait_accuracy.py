"""Online (causal) gait phase and events from a thigh IMU: accuracy, latency and cost.

Prints, per data set: foot strikes (true, missed, extra), strike error (estimated − true:
mean, p95 |·|, max |·|), strike latency (detection − true: p95 over all strikes, and p95 without
the first strike of each recording, which is emitted when the sagittal axis is fixed), toe-off
error (p95 |·|, max |·|, missed, extra), phase RMSE against the phase linear between true
strikes; then standing and stop-and-go event counts and the cost per sample on one core.

Data: simulated walking from the reference curves at 0.6-1.8 m/s (random mounting, noise, bias,
stride-time jitter 3 %), a slow → fast speed change within 3 strides, the real OpenSim trial
(``--mot``; thigh IMU synthesised as in ``examples/gait_event_accuracy.py``) with the axis
learned online from the trial itself and with the mounting given by a calibration (the offline
detector's sagittal axis of the trial: a prosthesis keeps its mounting between sessions).

    python examples/online_gait_accuracy.py [--seeds 5] [--mot PATH.mot] [--plot phase.png]
"""

from __future__ import annotations

import argparse
import logging
import time
from pathlib import Path

import numpy as np

from kinematics.gait_events import detect_from_thigh_imu
from kinematics.gait_online import estimate_online
from kinematics.gait_phase import OnlineGaitEstimator
from kinematics.gait_phase_metrics import OnlineScore, score_online
from kinematics.gait_scenarios import simulate_walks, speed_change
from kinematics.gait_synth import (
    ImuNoise,
    opensim_true_events,
    random_mounting,
    read_opensim_mot,
    thigh_imu_from_opensim,
    thigh_imu_from_reference,
)
from kinematics.thigh_attitude import SagittalAxis

REPO = Path(__file__).resolve().parents[1]
DEFAULT_MOT = Path("/work/shared/data/gait/opensim_subject01_walk1_ik.mot")


class Tally:
    def __init__(self) -> None:
        self.fs, self.lat, self.lat_rest, self.to = [], [], [], []
        self.true = self.missed = self.extra = self.to_missed = self.to_extra = 0
        self.rmse: list[float] = []

    def add(self, s: OnlineScore) -> None:
        self.fs += list(s.foot_strike.errors_s)
        self.lat += list(s.foot_strike.latencies_s)
        self.lat_rest += list(s.foot_strike.latencies_s[1:])
        self.to += list(s.toe_off.errors_s)
        self.true += s.foot_strike.true
        self.missed += s.foot_strike.missed
        self.extra += s.foot_strike.extra
        self.to_missed += s.toe_off.missed
        self.to_extra += s.toe_off.extra
        self.rmse.append(s.phase_rmse_cyc)

    def row(self, name: str) -> str:
        def p95(x):
            return np.percentile(np.abs(x), 95) * 1e3 if len(x) else float("nan")

        fs = np.asarray(self.fs)
        lat, rest, to = (np.asarray(x) for x in (self.lat, self.lat_rest, self.to))
        return (
            f"| {name} | {self.true} | {self.missed} | {self.extra} | "
            f"{fs.mean() * 1e3 if fs.size else float('nan'):+.1f} | {p95(fs):.1f} | "
            f"{np.abs(fs).max() * 1e3 if fs.size else float('nan'):.1f} | "
            f"{np.percentile(lat, 95) * 1e3 if lat.size else float('nan'):.1f} | "
            f"{np.percentile(rest, 95) * 1e3 if rest.size else float('nan'):.1f} | "
            f"{p95(to):.1f} | {np.abs(to).max() * 1e3 if to.size else float('nan'):.1f} | "
            f"{self.to_missed}/{self.to_extra} | {100 * np.nanmax(self.rmse):.1f} |"
        )


HEADER = (
    "| data | true strikes | missed | extra | strike err mean ms | p95 abs ms | max abs ms | "
    "latency p95 ms | latency p95 ms (w/o first) | toe-off p95 abs ms | toe-off max abs ms | "
    "toe-off missed/extra | phase RMSE max % |\n|" + "---|" * 13
)


def simulated(seeds: int, noise: ImuNoise) -> None:
    for speed in (0.6, 0.9, 1.2, 1.5, 1.8):
        tally = Tally()
        for seed in range(seeds):
            for rate in (100.0, 200.0):
                sim = thigh_imu_from_reference(
                    speed,
                    n_strides=6,
                    rate_hz=rate,
                    noise=noise,
                    thigh_R_sensor=random_mounting(2000 + seed),
                    seed=seed,
                    stride_time_jitter=0.03,
                )
                tally.add(
                    score_online(estimate_online(sim.imu), sim.foot_strikes_s, sim.toe_offs_s)
                )
        print(tally.row(f"simulated {speed} m/s"))
    tally = Tally()
    for seed in range(seeds):
        sc = simulate_walks(
            [speed_change(0.7, 1.6, 10)], thigh_R_sensor=random_mounting(3000 + seed), seed=seed
        )
        tally.add(score_online(estimate_online(sc.imu), sc.foot_strikes_s, sc.toe_offs_s))
    print(tally.row("speed change 0.7 → 1.6 m/s over 3 strides"))


def opensim(mot: Path, seeds: int, noise: ImuNoise) -> None:
    motion = read_opensim_mot(mot)
    learned, calibrated = Tally(), Tally()
    for side in ("r", "l"):
        truth = opensim_true_events(motion, side)
        for seed in range(seeds):
            mount = random_mounting(1000 + seed)
            imu = thigh_imu_from_opensim(
                motion, side, rate_hz=200.0, noise=noise, thigh_R_sensor=mount, seed=seed
            )
            learned.add(score_online(estimate_online(imu), truth["foot_strike"], truth["toe_off"]))
            axis = mounting_calibration(imu)
            res = estimate_online(imu, sagittal_axis=axis)
            calibrated.add(score_online(res, truth["foot_strike"], truth["toe_off"]))
    print(learned.row("OpenSim trial, axis learned online from the 3.5 s trial"))
    print(calibrated.row("OpenSim trial, axis from a mounting calibration"))


def mounting_calibration(imu) -> SagittalAxis:
    """The mounting as a calibration would give it: the sagittal axis (with its sign) of the
    offline detector over the recording, the mean gravity direction as the zero angle."""
    axis = detect_from_thigh_imu(imu).sagittal_axis
    up = np.asarray(imu.accel_m_s2).mean(axis=0)
    up = up - (up @ axis) * axis
    return SagittalAxis(axis, up / np.linalg.norm(up), 0.0, float(imu.t_s[0]), 1.0)


def standing_and_stops(seeds: int, noise: ImuNoise) -> None:
    events = 0
    for seed in range(3):
        sc = simulate_walks(
            [], stand_s=60.0, noise=noise, thigh_R_sensor=random_mounting(seed), seed=seed
        )
        events += len(estimate_online(sc.imu).events)
    print(f"\nstanding still, 3 x 60 s: {events} events")
    outside = extra = missed = 0
    for seed in range(seeds):
        sc = simulate_walks(
            [[1.0] * 4, [1.4] * 4, [0.7] * 3],
            stand_s=4.0,
            noise=noise,
            thigh_R_sensor=random_mounting(3100 + seed),
            seed=seed,
        )
        res = estimate_online(sc.imu)
        t = np.array([e.detected_t_s for e in res.events])
        inside = np.zeros(t.size, dtype=bool)
        for a, b in sc.walking_intervals_s:
            inside |= (t >= a) & (t <= b + 0.05)
        outside += int((~inside).sum())
        s = score_online(res, sc.foot_strikes_s, sc.toe_offs_s)
        extra += s.foot_strike.extra + s.toe_off.extra
        missed += s.foot_strike.missed
    print(
        f"stop-and-go (3 bouts, 4 s stands), {seeds} seeds: {outside} events while standing, "
        f"{missed} strikes missed, {extra} extra events"
    )


def cost() -> None:
    sim = thigh_imu_from_reference(1.2, n_strides=30, rate_hz=200.0, seed=0)
    est = OnlineGaitEstimator()
    t0 = time.process_time()
    for t, g, a in zip(sim.imu.t_s, sim.imu.gyro_rad_s, sim.imu.accel_m_s2, strict=True):
        est.update(t, g, a)
    dt = time.process_time() - t0
    n = sim.imu.t_s.size
    print(
        f"\ncost: {n} samples in {dt:.2f} s CPU = {n / dt:.0f} samples/s on one core "
        f"({n / dt / 200:.0f}x a 200 Hz IMU; {1e6 * dt / n:.0f} µs per sample)"
    )


def plot(path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from kinematics.gait_phase_metrics import reference_phase

    sc = simulate_walks([speed_change(0.7, 1.6, 10)], thigh_R_sensor=random_mounting(3000), seed=0)
    res = estimate_online(sc.imu)
    fig, ax = plt.subplots(figsize=(10, 3.5))
    ax.plot(res.t_s, reference_phase(res.t_s, sc.foot_strikes_s), "k-", lw=1, label="reference")
    ax.plot(res.t_s, res.phase_cyc, "C0.", ms=1.5, label="online estimate")
    for t in sc.foot_strikes_s:
        ax.axvline(t, color="0.7", lw=0.8)
    ax.plot(
        res.times("foot_strike", detected=True),
        np.ones(len(res.times("foot_strike"))),
        "rv",
        label="strike detected",
    )
    ax.set_xlabel("t (s)")
    ax.set_ylabel("gait phase (cycles)")
    ax.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    print(f"wrote {path}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--mot", type=Path, default=DEFAULT_MOT)
    parser.add_argument("--plot", type=Path, default=None)
    args = parser.parse_args()
    logging.basicConfig(level=logging.ERROR)
    noise = ImuNoise()
    print(f"IMU noise: {noise}\n")
    print(HEADER)
    simulated(args.seeds, noise)
    if args.mot.exists():
        opensim(args.mot, args.seeds, noise)
    else:
        print(f"(no {args.mot}: OpenSim trial skipped)")
    standing_and_stops(args.seeds, noise)
    cost()
    if args.plot is not None:
        plot(args.plot)


if __name__ == "__main__":
    main()

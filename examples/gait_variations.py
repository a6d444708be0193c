"""Both gait detectors on what the shared walks do not vary: the sample rate, a long standing
start, slow prosthetic gait, long treadmill walks, and sensor faults.

Prints one row per variation and detector, as ``real_gait_accuracy.py`` scores them (strikes
matched within 0.25 s; median and worst |error|; events while standing; online latency p95;
phase RMSE, worst walk; online toe-offs found of the true ones on the synthetic walks):

* the Xsens thigh walk (``../shared/data/real_thigh_imu``) resampled to 100, 200 and 250 Hz;
  lengthened by 4 or 8 s of standing (its first second repeated, with a little noise); with
  ±1 ms of time-stamp jitter; 2 % and 5 % of its samples dropped, singly or three in a row; a
  0.05 rad/s gyro bias; a 0.3 m/s² accelerometer bias (skipped when the data is absent);
* the synthetic prosthesis side (:data:`kinematics.gait_patterns.PROSTHETIC_SIDE`): 12 strides
  after 3 or 11 s of standing at 100 and 250 Hz; 0.6 m/s on a treadmill and overground (reduced
  swing flexion); 30 strides on a treadmill at 1.0 m/s, 250 Hz, after 11 s of standing. Three
  mountings each (of the 24 axis arrangements, the second with a random rotation on top).

    python examples/gait_variations.py [--data ../shared/data/real_thigh_imu] [--quick]

``--quick``: one mounting per synthetic variation.
"""

from __future__ import annotations

import argparse
import dataclasses
import logging
from pathlib import Path

import numpy as np
from gait_walks import DEFAULT_DATA, Walk, real_walks
from real_gait_accuracy import Tally, run_offline, run_online

from kinematics.errors import GaitInputError
from kinematics.gait_patterns import PROSTHETIC_SIDE
from kinematics.gait_real import right_handed_arrangements
from kinematics.gait_scenarios import simulate_walks
from kinematics.gait_synth import random_mounting
from kinematics.imu import ImuSeries

TREADMILL = dataclasses.replace(PROSTHETIC_SIDE, treadmill=True)


def xsens_variations(walk: Walk):
    """(name, walk) pairs: the Xsens walk varied as the module docstring says."""
    imu, rng = walk.imu, np.random.default_rng(7)
    t, g, a = imu.t_s, imu.gyro_rad_s, imu.accel_m_s2
    for rate in (100.0, 200.0, 250.0):
        tn = np.arange(t[0], t[-1], 1.0 / rate)
        gn, an = (np.column_stack([np.interp(tn, t, x[:, k]) for k in range(3)]) for x in (g, a))
        yield f"resampled to {rate:.0f} Hz", ImuSeries(tn, gn, an), walk.strikes_s
    n1 = round(1.0 / float(np.median(np.diff(t))))
    for extra in (4, 8):
        gs = np.concatenate([g[:n1] + rng.normal(0, 0.002, (n1, 3)) for _ in range(extra)] + [g])
        as_ = np.concatenate([a[:n1] + rng.normal(0, 0.01, (n1, 3)) for _ in range(extra)] + [a])
        shift = extra * n1 * float(np.median(np.diff(t)))
        ts = t[0] + np.arange(len(gs)) * float(np.median(np.diff(t)))
        yield f"{extra} s more standing", ImuSeries(ts, gs, as_), walk.strikes_s + shift
    jittered = np.sort(t + rng.uniform(-0.001, 0.001, t.size))
    yield "±1 ms time-stamp jitter", ImuSeries(jittered, g, a), walk.strikes_s
    for share, run in ((0.02, 1), (0.05, 1), (0.02, 3)):
        keep = np.ones(t.size, bool)
        for s in np.flatnonzero(rng.random(t.size) < share / run):
            keep[s : s + run] = False
        name = f"{100 * share:.0f} % of samples dropped" + (f", {run} in a row" if run > 1 else "")
        yield name, ImuSeries(t[keep], g[keep], a[keep]), walk.strikes_s
    yield "gyro bias 0.05 rad/s", ImuSeries(t, g + np.array([0.05, -0.03, 0.02]), a), walk.strikes_s
    yield (
        "accelerometer bias 0.3 m/s²",
        ImuSeries(t, g, a + np.array([0.3, -0.2, 0.1])),
        walk.strikes_s,
    )


def synthetic_variations(quick: bool):
    """(name, [walks]) pairs of the prosthesis side (module docstring)."""
    arr = right_handed_arrangements()
    cases = [(f"{stand:.0f} s standing, {rate:.0f} Hz", PROSTHETIC_SIDE, 0.9, 12, rate, stand)
             for stand in (3.0, 11.0) for rate in (100.0, 250.0)]  # fmt: skip
    cases += [
        ("0.6 m/s treadmill, 100 Hz", TREADMILL, 0.6, 12, 100.0, 3.0),
        ("0.6 m/s overground, 250 Hz", PROSTHETIC_SIDE, 0.6, 12, 250.0, 3.0),
        ("30 strides, treadmill 1.0 m/s, 250 Hz, 11 s standing", TREADMILL, 1.0, 30, 250.0, 11.0),
    ]
    for name, pattern, speed, strides, rate, stand in cases:
        walks = []
        for k in range(1 if quick else 3):
            mount = arr[(7 * k + 3) % 24] @ (random_mounting(k) if k % 2 else np.eye(3))
            walks.append(simulate_walks([[speed] * strides], rate_hz=rate, thigh_R_sensor=mount,
                                        seed=300 + k, pattern=pattern, stand_s=stand))  # fmt: skip
        yield name, walks


def row(name: str, detector: str, tally: Tally, toe_offs: str = "–") -> str:
    e = np.abs(np.array(tally.errors)) * 1e3
    lat = f"{np.percentile(tally.latency, 95) * 1e3:.0f}" if tally.latency else "–"
    rmse = np.array(tally.rmse, dtype=float)
    phase = f"{100 * np.nanmax(rmse):.1f}" if np.isfinite(rmse).any() else "none"
    return (
        f"| {name} | {detector} | {tally.true} / {tally.found} / {tally.missed} / {tally.extra} "
        f"| {np.median(e):.0f} / {e.max():.0f} | {tally.standing} | {lat} | {phase} | {toe_offs} |"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA)
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    logging.basicConfig(level=logging.WARNING)
    print("| variation | detector | true / found / missed / extra | median / worst abs ms "
          "| events standing | latency p95 ms | phase RMSE % (worst walk) | toe-offs found |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|")
    xsens = [w for w in real_walks(args.data) if w.name.startswith("Xsens")]
    for base in xsens:
        for name, imu, strikes in xsens_variations(base):
            for detector, run in (("offline", run_offline), ("online", run_online)):
                tally = Tally()
                try:
                    run(Walk(name, imu, strikes), tally)
                except GaitInputError as err:  # the offline detector refuses long gaps
                    print(f"| Xsens walk, {name} | {detector} | refused: {err} |||||||")
                    continue
                print(row(f"Xsens walk, {name}", detector, tally), flush=True)
    for name, walks in synthetic_variations(args.quick):
        for detector, run in (("offline", run_offline), ("online", run_online)):
            tally = Tally()
            for sc in walks:
                run(Walk(name, sc.imu, sc.foot_strikes_s, toe_offs_s=sc.toe_offs_s), tally)
            found, true = tally.toe_offs
            toes = f"{found} of {true}" if detector == "online" else "–"
            print(row(f"prosthesis side, {name}", detector, tally, toes), flush=True)


if __name__ == "__main__":
    main()

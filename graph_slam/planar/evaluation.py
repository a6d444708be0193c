"""Errors per stride of each method against the simulated truth, and the table files.

Both methods are scored in the world frame, which for a position error is the same as in the
stride frame (the frames differ by a rigid motion). Per stride and method:

* ``ate_rmse_m`` / ``ate_max_m``: absolute trajectory error — the distance between estimated
  and true sensor positions over the stride's scans (scans without a pose are counted apart);
* ``step_error_max_m`` (and ``..._swing_m``, during swing): the largest error of the motion
  from one scan to the next — a registration that went wrong shows here whether or not it
  was reported (the sensor moves 2–4 cm between scans);
* ``reported_failures``: scans whose registration was reported as failed (the thesis pipeline
  uses the result anyway; the graph leaves it out and bridges with the motion prior).
"""

from __future__ import annotations

import csv
import json
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from graph_slam.planar import se2
from graph_slam.planar.thesis import PlanarEstimate
from graph_slam.planar.trajectory import GaitTrajectory


@dataclass(frozen=True)
class StrideError:
    """One row of the table."""

    speed_m_s: float
    stride: int
    method: str
    scans: int
    scans_without_pose: int
    ate_rmse_m: float
    ate_max_m: float
    heading_rmse_deg: float
    step_error_max_m: float
    step_error_max_swing_m: float
    reported_failures: int


def position_errors_m(estimate: PlanarEstimate, trajectory: GaitTrajectory) -> np.ndarray:
    """(n,) distance between estimated and true sensor positions (NaN where no pose)."""
    diff = estimate.world_T_sensor[:, :2, 2] - trajectory.world_T_sensor[:, :2, 2]
    return np.linalg.norm(diff, axis=1)


def heading_errors_rad(estimate: PlanarEstimate, trajectory: GaitTrajectory) -> np.ndarray:
    """(n,) wrapped heading error (NaN where no pose)."""
    est = np.arctan2(estimate.world_T_sensor[:, 1, 0], estimate.world_T_sensor[:, 0, 0])
    true = np.arctan2(trajectory.world_T_sensor[:, 1, 0], trajectory.world_T_sensor[:, 0, 0])
    return se2.wrap_angle(est - true)


def step_errors_m(estimate: PlanarEstimate, trajectory: GaitTrajectory) -> np.ndarray:
    """(n,) error of the motion since the previous scan of the same stride (NaN for a stride's
    first scan for the graph, which restarts there, and wherever a pose is missing)."""
    out = np.full(len(trajectory.t_s), np.nan)
    est, true = estimate.world_T_sensor, trajectory.world_T_sensor
    for k in range(1, len(out)):
        restart = estimate.method == "graph" and (
            trajectory.stride_index[k] != trajectory.stride_index[k - 1]
        )
        if restart or not (np.isfinite(est[k]).all() and np.isfinite(est[k - 1]).all()):
            continue
        true_rel = se2.inverse(true[k - 1]) @ true[k]
        est_rel = se2.inverse(est[k - 1]) @ est[k]
        out[k] = np.linalg.norm((se2.inverse(true_rel) @ est_rel)[:2, 2])
    return out


def _max(values: np.ndarray) -> float:
    values = values[np.isfinite(values)]
    return float(values.max()) if len(values) else np.nan


def stride_errors(estimate: PlanarEstimate, trajectory: GaitTrajectory) -> list[StrideError]:
    """The table rows of one method at one speed."""
    pos = position_errors_m(estimate, trajectory)
    head = heading_errors_rad(estimate, trajectory)
    step = step_errors_m(estimate, trajectory)
    rows = []
    for stride in range(len(trajectory.world_T_stride)):
        m = trajectory.stride_index == stride
        have = m & np.isfinite(pos)
        rows.append(
            StrideError(
                speed_m_s=trajectory.speed_m_s,
                stride=stride + 1,
                method=estimate.method,
                scans=int(m.sum()),
                scans_without_pose=int((m & ~np.isfinite(pos)).sum()),
                ate_rmse_m=float(np.sqrt(np.mean(pos[have] ** 2))) if have.any() else np.nan,
                ate_max_m=float(pos[have].max()) if have.any() else np.nan,
                heading_rmse_deg=float(np.degrees(np.sqrt(np.mean(head[have] ** 2))))
                if have.any()
                else np.nan,
                step_error_max_m=_max(step[m]),
                step_error_max_swing_m=_max(step[m & ~trajectory.in_stance]),
                reported_failures=sum(
                    1 for k in np.flatnonzero(m) if estimate.failure[k] is not None
                ),
            )
        )
    return rows


_HEADER = (
    "speed (m/s)",
    "stride",
    "method",
    "scans",
    "ATE RMSE (mm)",
    "ATE max (mm)",
    "heading RMSE (deg)",
    "step error max (mm)",
    "in swing (mm)",
    "reported failures",
    "no pose",
)


def table_markdown(rows: list[StrideError]) -> str:
    """The per-stride error table as markdown."""
    lines = ["| " + " | ".join(_HEADER) + " |", "|" + "---|" * len(_HEADER)]
    for r in rows:
        lines.append(
            f"| {r.speed_m_s:.2f} | {r.stride} | {r.method} | {r.scans} | "
            f"{r.ate_rmse_m * 1e3:.1f} | {r.ate_max_m * 1e3:.1f} | {r.heading_rmse_deg:.2f} | "
            f"{r.step_error_max_m * 1e3:.1f} | {r.step_error_max_swing_m * 1e3:.1f} | "
            f"{r.reported_failures} | {r.scans_without_pose} |"
        )
    lines += [
        "",
        "ATE: distance between estimated and true sensor positions. Step error: error "
        "of the motion from one scan to the next. Reported failures: registrations "
        "flagged as failed (the thesis uses them anyway; the graph leaves them out).",
    ]
    return "\n".join(lines) + "\n"


def write_table(rows: list[StrideError], out_dir: Path) -> list[Path]:
    """errors.md, errors.csv and errors.json in ``out_dir``."""
    out_dir.mkdir(parents=True, exist_ok=True)
    md = out_dir / "errors.md"
    md.write_text(table_markdown(rows), encoding="utf-8")
    path_csv = out_dir / "errors.csv"
    with path_csv.open("w", newline="", encoding="utf-8") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(asdict(rows[0])))
        writer.writeheader()
        for r in rows:
            writer.writerow(asdict(r))
    path_json = out_dir / "errors.json"
    records = [{k: _json_number(v) for k, v in asdict(r).items()} for r in rows]
    path_json.write_text(json.dumps(records, indent=2), encoding="utf-8")
    return [md, path_csv, path_json]


def _json_number(value: object) -> object:
    """NaN is not JSON: it becomes null."""
    return None if isinstance(value, float) and not np.isfinite(value) else value


def write_scan_log(trajectory: GaitTrajectory, estimates: list[PlanarEstimate], path: Path) -> Path:
    """One CSV row per scan: truth, each method's pose, error and failure reason."""
    true = np.array([se2.xyt(T) for T in trajectory.world_T_sensor])
    header = ["t_s", "stride", "stance", "true_x_m", "true_y_m", "true_theta_rad"]
    columns = [
        trajectory.t_s,
        trajectory.stride_index + 1,
        trajectory.in_stance.astype(int),
        *true.T,
    ]
    for est in estimates:
        xyt = np.array([se2.xyt(T) for T in est.world_T_sensor])
        header += [f"{est.method}_{c}" for c in ("x_m", "y_m", "theta_rad", "error_m")]
        columns += [*xyt.T, position_errors_m(est, trajectory)]
    with path.open("w", newline="", encoding="utf-8") as fh:
        writer = csv.writer(fh)
        writer.writerow(header + [f"{est.method}_failure" for est in estimates])
        for k in range(len(trajectory.t_s)):
            values = [f"{c[k]:.6g}" for c in columns]
            writer.writerow(values + [est.failure[k] or "" for est in estimates])
    return path

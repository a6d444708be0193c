"""2D point-to-plane ICP on line features (thesis 3.1.2, eq. 3.2–3.7).

Each iteration associates every source point with its nearest target point; when several
source points pick the same target point only the closer pair is kept (one-to-one). With the
reference normals n_i the transform minimises

    T_opt = argmin_T  sum_i ((T p_i - r_i) · n_i)^2                                (3.2)

Under the small-angle assumption R ≈ [[1, -θ], [θ, 1]] (3.3–3.4) every pair gives one row of
the linear system A x = b with x = [t_x, t_y, θ] (3.6),

    A_i = [n_ix, n_iy, p_ix n_iy - p_iy n_ix]                                       (3.5)
    b_i = r_ix n_ix + r_iy n_iy - p_ix n_ix - p_iy n_iy                             (3.7)

solved by least squares (the pseudoinverse, as in the thesis). The update is applied with the
exact rotation and the loop repeats until the update is below the tolerance (or the
association flips back and forth between two sets, a 2-cycle that otherwise never ends).

A registration that cannot be trusted is reported as a failure with its reason (too few
pairs, no convergence, a degenerate geometry such as a flat floor that leaves a direction
unconstrained); the transform found, if any, is returned beside the reason so that a caller
that — like the thesis — has no failure check can still use it, knowingly.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from graph_slam.planar import se2
from graph_slam.planar.config import IcpConfig
from graph_slam.planar.features import LineFeatures


@dataclass(frozen=True)
class IcpResult:
    """Outcome of one registration: ``target_T_source`` maps source points onto the target."""

    target_T_source: np.ndarray | None  # None: no estimate at all
    failure: str | None  # None: trusted; else why not (the first reason that applies)
    converged: bool
    n_pairs: int
    rms_m: float
    iterations: int
    information: np.ndarray  # A^T A at the solution, for a left update [t_x, t_y, θ]

    @property
    def ok(self) -> bool:
        return self.failure is None and self.target_T_source is not None


def associate(
    source_xy_m: np.ndarray, target_xy_m: np.ndarray, max_distance_m: float | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """One-to-one nearest neighbours: (source indices, target indices), closer pair kept."""
    dist, tgt = cKDTree(target_xy_m).query(source_xy_m, k=1)
    order = np.argsort(dist, kind="stable")
    if max_distance_m is not None:
        order = order[dist[order] <= max_distance_m]
    _, first = np.unique(tgt[order], return_index=True)
    src = np.sort(order[first])
    return src, tgt[src]


def linear_system(
    source_xy_m: np.ndarray, target_xy_m: np.ndarray, target_normals: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """A and b of eq. 3.5 and 3.7 for paired points p_i (source) and r_i, n_i (target)."""
    p, r, n = source_xy_m, target_xy_m, target_normals
    a = np.column_stack([n[:, 0], n[:, 1], p[:, 0] * n[:, 1] - p[:, 1] * n[:, 0]])
    b = np.sum(r * n, axis=1) - np.sum(p * n, axis=1)
    return a, b


def register(
    source_xy_m: np.ndarray,
    target: LineFeatures,
    config: IcpConfig,
    initial_target_T_source: np.ndarray | None = None,
) -> IcpResult:
    """Align ``source_xy_m`` (current scan's line points) to ``target`` (the reference scan)."""
    zero_info = np.zeros((3, 3))
    target_T_source = np.eye(3) if initial_target_T_source is None else initial_target_T_source
    if len(source_xy_m) < 3 or len(target.points_xy_m) < 3:
        n = min(len(source_xy_m), len(target.points_xy_m))
        return IcpResult(None, f"only {n} line points: no estimate", False, 0, np.nan, 0, zero_info)
    converged = False
    history = [se2.xyt(target_T_source)]
    for iteration in range(1, config.max_iterations + 1):
        moved = se2.apply(target_T_source, source_xy_m)
        src, tgt = associate(moved, target.points_xy_m, config.max_pair_distance_m)
        if len(src) < 3:  # eq. 3.5 needs three independent rows
            within = (
                ""
                if config.max_pair_distance_m is None
                else (f" within {config.max_pair_distance_m} m")
            )
            return IcpResult(
                None,
                f"only {len(src)} pairs{within}: no estimate",
                False,
                len(src),
                np.nan,
                iteration,
                zero_info,
            )
        a, b = linear_system(moved[src], target.points_xy_m[tgt], target.normals[tgt])
        x = np.linalg.pinv(a) @ b
        target_T_source = se2.se2(*x) @ target_T_source
        history.append(se2.xyt(target_T_source))
        # Converged when the update vanishes, or when the association flips between two sets
        # and the estimate returns to where it was two iterations ago (a 2-cycle).
        cycle = len(history) > 2 and np.linalg.norm(history[-1] - history[-3]) < config.tolerance
        if np.linalg.norm(x) < config.tolerance or cycle:
            converged = True
            break
    moved = se2.apply(target_T_source, source_xy_m)
    src, tgt = associate(moved, target.points_xy_m, config.max_pair_distance_m)
    a, b = linear_system(moved[src], target.points_xy_m[tgt], target.normals[tgt])
    info = a.T @ a
    rms = float(np.sqrt(np.mean(b**2))) if len(b) else np.nan
    failure = None
    min_eig = float(np.linalg.eigvalsh(info)[0]) if len(b) else 0.0
    if not converged:
        failure = f"did not converge in {config.max_iterations} iterations"
    elif len(src) < config.min_pairs:
        failure = f"only {len(src)} pairs (need {config.min_pairs})"
    elif min_eig < config.min_information:
        failure = (
            f"degenerate geometry: smallest eigenvalue of A^T A {min_eig:.3g} "
            f"< {config.min_information}"
        )
    return IcpResult(target_T_source, failure, converged, len(src), rms, iteration, info)

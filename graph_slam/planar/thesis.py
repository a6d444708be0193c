"""The thesis's 2D pipeline (Figure 3.2): features -> ICP -> pose accumulation -> trilateration.

Every scan is registered to the previous one (identity as the initial guess; the thesis has no
motion model in its 2D study), the transform found is accumulated into the current pose

    x_current <- x_current + x                                                      (3.8)

and the scan, moved into the world by x_current, gives the sensor position by trilateration
(eq. 3.9–3.10) while the heading comes from x_current. Eq. 3.8 writes the accumulation as a
sum, which is right only for increments expressed in the world frame; ICP's increment is in
the previous sensor frame, so it is composed: world_T_sensor(t) = world_T_sensor(t-1) · x.

Like the thesis, the pipeline has no failure check: it uses ICP's answer whenever there is
one, and records ICP's own verdict beside it. Where ICP gives no answer at all (too few line
points or pairs) the scan gets no pose (NaN) and a failure reason, and the next scan is
registered to the last scan that had one — a failed registration is never taken as zero
motion.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from graph_slam.planar import se2
from graph_slam.planar.config import PlanarConfig
from graph_slam.planar.features import extract_lines
from graph_slam.planar.icp import IcpResult, register
from graph_slam.planar.scanner import Scan
from graph_slam.planar.trilateration import trilaterate


@dataclass(frozen=True)
class PlanarEstimate:
    """A method's sensor poses, one per scan (NaN where it has none), and what went wrong."""

    method: str
    world_T_sensor: np.ndarray  # (n, 3, 3)
    failure: tuple[str | None, ...]  # per scan: None, or why this scan's registration failed
    icp: tuple[IcpResult | None, ...]  # per scan (None for a stride's first scan)


def run_thesis(
    scans: list[Scan], world_T_sensor0: np.ndarray, config: PlanarConfig
) -> PlanarEstimate:
    """Run the thesis pipeline from the true first pose; max-range returns are kept (3.2)."""
    drop = not config.thesis.keep_max_range
    poses = np.full((len(scans), 3, 3), np.nan)
    poses[0] = world_T_sensor0
    failures: list[str | None] = [None]
    results: list[IcpResult | None] = [None]
    x_current = world_T_sensor0
    reference = extract_lines(scans[0].points_xy_m(drop), config.features)
    for k in range(1, len(scans)):
        points = scans[k].points_xy_m(drop)
        lines = extract_lines(points, config.features)
        result = register(lines.points_xy_m, reference, config.icp)
        results.append(result)
        failures.append(result.failure)
        if result.target_T_source is None:
            continue
        x_current = x_current @ result.target_T_source  # eq. 3.8 (composed)
        position = trilaterate(se2.apply(x_current, points), np.hypot(*points.T))  # eq. 3.9-3.10
        poses[k] = se2.se2(position[0], position[1], se2.xyt(x_current)[2])
        reference = lines
    return PlanarEstimate("thesis", poses, tuple(failures), tuple(results))

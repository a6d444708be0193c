"""The thesis's 2D study (chapters 3.1–3.2) and the per-stride factor graph beside it.

A thigh-mounted 2D range sensor walks over an occupancy-grid terrain with gait kinematics;
its scans are registered by the thesis's pipeline (roughness features, point-to-plane ICP,
pose accumulation, trilateration) and by a per-stride Pose2 factor graph. Entry point:
:func:`run_planar`; the CLI is ``graph-slam planar --out DIR``. See docs/planar.md.
"""

from graph_slam.planar.config import PlanarConfig
from graph_slam.planar.study import PlanarResult, run_planar

__all__ = ["PlanarConfig", "PlanarResult", "run_planar"]

"""Typed configuration of the thesis baseline (Ch. 3.3-3.4): its registration, stop rule,
cloud and map (:class:`BaselineConfig`)."""

from __future__ import annotations

from pydantic import Field

from graph_slam.config import ConfigModel
from graph_slam.frontend.config import THESIS_LEVELS, RegistrationConfig

BASELINE_CLOUD_WIDTH_PX = 212
"""The thesis baseline's cloud width by default (``baseline.pixel_step`` None)."""


class BaselineConfig(ConfigModel):
    """The thesis pipeline (Ch. 3.3-3.4): reset at foot strike, ICP to the global map."""

    registration: RegistrationConfig = Field(
        default_factory=lambda: RegistrationConfig(
            method="colored",
            levels=THESIS_LEVELS,
            kernel="none",
            min_fitness=0.0,
            check_convergence=False,
        ),
        description="3 levels (4, 2, 1 cm), colored ICP (point_to_plane for depth-only "
        "sensors); min_fitness 0 here: the stop rule below decides; no convergence check "
        "(the thesis took Open3D's result, which does not say whether it converged)",
    )
    stop_fitness: float = Field(
        0.3, ge=0, le=1, description="fitness below this stops registration for the stride"
    )
    pixel_step: int | None = Field(
        None,
        ge=1,
        le=8,
        description="the cloud from every n-th row and column of the depth image; None: the "
        "212x120 cloud (image width // 212: 2 at 424x240, 4 at 848x480, 1 below), the "
        "default presets' budget; 1: every pixel (the accurate and thesis presets)",
    )

    def pixel_step_for(self, width_px: int) -> int:
        """The pixel step for an image ``width_px`` wide (``pixel_step``, or the 212x120
        cloud's)."""
        if self.pixel_step is not None:
            return self.pixel_step
        return max(1, int(width_px) // BASELINE_CLOUD_WIDTH_PX)

    stop_on_any_failure: bool = Field(
        True,
        description="a registration that fails otherwise also stops the stride; with the "
        "default registration these are the failures Open3D reports as fitness 0 (no "
        "overlap, an empty cloud) or a non-finite transform",
    )
    map_voxel_m: float = Field(
        0.01, gt=0, description="fusion: running mean per voxel of a grid fixed in the stride frame"
    )

"""graph_slam.viz.plots: every figure is written as a readable PNG of the expected size."""

from __future__ import annotations

import numpy as np
from PIL import Image

from graph_slam.terrain import ElevationConfig, Obstacle, elevation_grid
from graph_slam.viz import plots


def _png_size(path) -> tuple[int, int]:
    with Image.open(path) as image:
        assert image.format == "PNG"
        return image.size


def test_all_plots_write_pngs(tmp_path):
    rng = np.random.default_rng(3)
    t = np.linspace(0, 1, 30)
    truth = np.column_stack([0.8 * t, 0.05 * np.sin(6 * t), 0.5 + 0.02 * t])
    estimate = truth + rng.normal(0, 0.005, truth.shape)
    estimate[-5:] = np.nan
    points = np.column_stack(
        [rng.uniform(0, 1.5, 3000), rng.uniform(-0.5, 0.5, 3000), np.zeros(3000)]
    )
    box = Obstacle(0.2, 0.27, 0.19, 0.5, np.array([0.6, -0.3]), 100)
    grid = elevation_grid(points, ElevationConfig())
    written = [
        plots.plot_stride_trajectories(tmp_path / "traj.png", truth, {"graph": estimate}),
        plots.plot_error_over_gait_cycle(
            tmp_path / "err.png", {"graph": [(t * 100, np.abs(estimate[:, 0] - truth[:, 0]))]}, 62.0
        ),
        plots.plot_map_top_view(
            tmp_path / "map.png", points, rng.integers(0, 256, (3000, 3)), [box]
        ),
        plots.plot_elevation(tmp_path / "elev.png", grid),
        plots.plot_obstacle_boxes(
            tmp_path / "boxes.png",
            {"Box1": [box.size_m, box.size_m * 1.01]},
            {"Box1": np.array([0.2032, 0.2667, 0.1905])},
        ),
    ]
    sizes = [_png_size(p) for p in written]
    assert sizes[0] == (1440, 540) and sizes[4] == (1440, 540)
    assert all(w >= 600 and h >= 500 for w, h in sizes)

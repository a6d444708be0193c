"""The features' and the clearance's compiled loops loaded (or compiled, the first time in a
checkout) before a live run: :func:`warm_up` runs :func:`features_of_view
<graph_slam.terrain.features.extract.features_of_view>` and :func:`predict_clearance
<graph_slam.terrain.features.prediction.predict_clearance>` on a made-up grid that takes every
one of them (a flight of stairs, a curb, a ramp and a single step with a short top), so that
no live frame pays for it."""

from __future__ import annotations

import math

import numpy as np


def scene_heights(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The made-up terrain (stride frame, m; NaN: not seen): for y below -0.25 m three stairs
    up from x = 0.5 m, for y in [-0.2, 0.05] a 10 cm curb at x = 0.8 m, for y in [0.1, 0.3]
    an 8° ramp from x = 0.6 m to a landing, above y = 0.35 m a 10 cm step at x = 1.5 m whose
    top is seen for 20 cm."""
    stairs = np.clip(np.floor((x - 0.5) / 0.28) + 1, 0, 3) * 0.17
    curb = np.where(x >= 0.8, 0.1, 0.0)
    ramp = math.tan(math.radians(8.0)) * np.clip(x - 0.6, 0.0, 0.6)
    step = np.where(x >= 1.7, np.nan, np.where(x >= 1.5, 0.1, 0.0))
    z = np.where(y < -0.25, stairs, np.where(y <= 0.05, curb, np.where(y <= 0.3, ramp, step)))
    gaps = ((y > -0.25) & (y < -0.2)) | ((y > 0.05) & (y < 0.1)) | ((y > 0.3) & (y < 0.35))
    return np.where(gaps, np.nan, z)


def scene_view():
    """A :class:`~graph_slam.terrain.grid.view.TerrainView` of :func:`scene_heights` on the
    online grid's default layout (σ 1 mm depth noise, 1 mm pose part, 20 points a cell)."""
    from graph_slam.terrain.grid.online import CellSums, OnlineTerrainConfig
    from graph_slam.terrain.grid.view import TerrainView

    cfg = OnlineTerrainConfig()
    nx, ny = cfg.shape
    x = cfg.x_range_m[0] + (np.arange(nx)[:, None] + 0.5) * cfg.cell_m + np.zeros((1, ny))
    y = cfg.y_range_m[0] + (np.arange(ny)[None, :] + 0.5) * cfg.cell_m + np.zeros((nx, 1))
    z = scene_heights(x, y).ravel()
    seen = np.isfinite(z)
    var_depth, sigma_pose = 1e-6, 1e-3
    w = np.where(seen, 1.0 / (var_depth + sigma_pose**2), 0.0)
    zz = np.where(seen, z, 0.0)
    sums = CellSums(
        w=w,
        wz=w * zz,
        a=w * w * var_depth,
        b=w * sigma_pose,
        count=np.where(seen, 20, 0).astype(np.int64),
        last_t_s=np.where(seen, 0.0, np.nan),
        wz2=w * zz * zz,
        d=w * var_depth,
    )
    origin = np.array([cfg.x_range_m[0], cfg.y_range_m[0]])
    return TerrainView(0, 0.0, origin, cfg.cell_m, sums, (nx, ny), cfg.toe_x_m)


def warm_up():
    """Features and the stance-time prediction of :func:`scene_view` (returned: the
    features and the prediction)."""
    from graph_slam.terrain.features.extract import features_of_view
    from graph_slam.terrain.features.prediction import predict_clearance

    view = scene_view()
    features = features_of_view(view)
    return features, predict_clearance(view, features)

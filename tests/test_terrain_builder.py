"""Terrain maps as a pipeline output: the builder fuses a stride's frames with each pose set
and equals the one-call map of the same clouds and poses."""

from __future__ import annotations

import numpy as np

from graph_slam.session.records import CameraIntrinsics, RgbdFrame
from graph_slam.terrain.maps.builder import (
    TerrainBuilder,
    TerrainConfig,
    map_cloud,
    scaled_intrinsics,
)
from graph_slam.terrain.maps.stride_map import build_stride_map


def _frame(index, depth_m):
    rgb = np.full((*depth_m.shape, 3), 100, np.uint8)
    return RgbdFrame(index=index, t_s=0.1 * index, depth_m=depth_m, color_rgb=rgb)


def _intrinsics():
    return CameraIntrinsics(width_px=40, height_px=30, fx_px=30.0, fy_px=30.0, cx_px=19.5,
                            cy_px=14.5)  # fmt: skip


def test_map_cloud_step_is_the_subsampled_image():
    rng = np.random.default_rng(0)
    depth = rng.uniform(0.3, 2.5, (30, 40)).astype(np.float32)
    intr = _intrinsics()
    pts, _ = map_cloud(_frame(0, depth), intr, 2, 0.1, 2.0)
    sub = _frame(0, depth[::2, ::2])
    pts2, _ = map_cloud(sub, scaled_intrinsics(intr, 2), 1, 0.1, 2.0)
    np.testing.assert_allclose(pts, pts2, atol=1e-9)
    assert pts[:, 2].max() < 2.0


def test_builder_online_and_smoothed_maps_equal_the_one_call_map():
    intr = _intrinsics()
    cfg = TerrainConfig(pixel_step=1, max_depth_m=3.0)
    frames = [_frame(i, np.full((30, 40), 1.0 + 0.01 * i, np.float32)) for i in range(3)]
    online = np.tile(np.eye(4), (3, 1, 1))
    smoothed = online.copy()
    smoothed[:, 0, 3] = [0.0, 0.01, 0.02]
    b = TerrainBuilder(cfg, intr, 0.1, 3.0)
    for i, f in enumerate(frames):
        b.add_frame(i, f)
    t = b.close_stride(0, [0, 1, 2], online, smoothed)
    clouds = [map_cloud(f, intr, 1, 0.1, 3.0) for f in frames]
    ref = build_stride_map([c for c, _ in clouds], smoothed, [c for _, c in clouds], cfg.map)
    np.testing.assert_array_equal(t.smoothed.fused.points_m, ref.fused.points_m)
    assert not np.array_equal(t.online.fused.points_m, t.smoothed.fused.points_m)
    # the baseline: no smoother, one map serves both
    for i, f in enumerate(frames):
        b.add_frame(i, f)
    t2 = b.close_stride(1, [0, 1, 2], online, None)
    assert t2.smoothed is t2.online
    # off: nothing kept, nothing built
    off = TerrainBuilder(TerrainConfig(enabled=False), intr, 0.1, 3.0)
    off.add_frame(0, frames[0])
    assert off.close_stride(0, [0], online[:1], None).online is None

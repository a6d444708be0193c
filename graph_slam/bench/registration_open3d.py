"""The registration benchmark's reference on real frames: Open3D's own RGB-D odometry."""

from __future__ import annotations

import itertools
from collections.abc import Sequence

import numpy as np

from graph_slam.bench.registration_data import Dataset, pose_error, relative_truth
from graph_slam.session.records import RgbdFrame


def open3d_rgbd_odometry(data: Dataset, depth_max_m: float = 3.0) -> list[np.ndarray | None]:
    """Open3D's RGB-D odometry (hybrid term, default options) frame to frame:
    ``camera_k_T_camera_k+1`` per pair, ``None`` where it reports failure."""
    import open3d as o3d

    k = data.intrinsics
    intrinsic = o3d.camera.PinholeCameraIntrinsic(
        k.width_px, k.height_px, k.fx_px, k.fy_px, k.cx_px, k.cy_px
    )

    def rgbd(frame: RgbdFrame):
        return o3d.geometry.RGBDImage.create_from_color_and_depth(
            o3d.geometry.Image(np.ascontiguousarray(frame.color_rgb)),
            o3d.geometry.Image(np.ascontiguousarray(frame.depth_m)),
            depth_scale=1.0,
            depth_trunc=depth_max_m,
            convert_rgb_to_intensity=True,
        )

    images = [rgbd(f) for f in data.frames]
    out = []
    for target, source in itertools.pairwise(images):
        ok, source_to_target, _ = o3d.pipelines.odometry.compute_rgbd_odometry(
            source,
            target,
            intrinsic,
            np.eye(4),
            o3d.pipelines.odometry.RGBDOdometryJacobianFromHybridTerm(),
            o3d.pipelines.odometry.OdometryOption(),
        )
        out.append(np.asarray(source_to_target) if ok else None)
    return out


def odometry_errors(data: Dataset, estimates: Sequence[np.ndarray | None]) -> np.ndarray:
    """Per pair (translation m, rotation rad); NaN for a failed pair."""
    errors = np.full((len(estimates), 2), np.nan)
    for k, estimate in enumerate(estimates):
        if estimate is not None:
            errors[k] = pose_error(estimate, relative_truth(data.world_T_camera, k))
    return errors

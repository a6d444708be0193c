"""Colour registered to depth, compiled: :func:`~graph_slam.session.adapters.align.
align_color_to_depth` as one pass over the depth image (numba, no allocation per pixel, the
GIL released), for a live loop that registers every colour frame as it arrives.

The arithmetic is the reference's, operation for operation and in the same order (no fused
multiply-add, the distortion polynomial written as the reference writes it, the same fixed-point
inversion): the result is the reference's, pixel for pixel (tested against it, with every
distortion model). One difference of form, not of result: the inversion stops as soon as the
iterations reach a fixed point or a cycle of two (the last bit flipping), and takes the value the
reference's remaining iterations would end on.

``Registration(depth_camera, color_camera, color_T_depth)`` holds what does not change from frame
to frame (every pixel's ray, the rotation and translation, the colour camera's model);
``registration(depth_m, color_rgb)`` gives an :class:`~graph_slam.session.adapters.align.
Alignment`. :func:`warm_up` compiles the kernel (about a second the first time, loaded from
numba's cache after that).
"""

from __future__ import annotations

import numba
import numpy as np

from graph_slam.errors import ConversionError
from graph_slam.session.adapters.align import (
    UNDISTORT_ITERATIONS,
    Alignment,
    CameraModel,
    pixel_rays,
)

_KIND = {"none": 0, "forward": 1, "inverse": 2}


@numba.njit(cache=True, nogil=True, inline="always")
def _polynomial(x, y, k1, k2, p1, p2, k3):  # pragma: no cover - compiled
    r2 = x * x + y * y
    f = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
    return (
        x * f + 2 * p1 * x * y + p2 * (r2 + 2 * x * x),
        y * f + 2 * p2 * x * y + p1 * (r2 + 2 * y * y),
    )


@numba.njit(cache=True, nogil=True, inline="always")
def _invert(xd, yd, k1, k2, p1, p2, k3, iterations):  # pragma: no cover - compiled
    x, y = xd, yd
    bx, by = np.nan, np.nan  # the value before (x, y)
    for i in range(iterations):
        px, py = _polynomial(x, y, k1, k2, p1, p2, k3)
        nx, ny = x + (xd - px), y + (yd - py)
        if nx == x and ny == y:
            break  # a fixed point: every further iteration gives the same
        if nx == bx and ny == by:  # a cycle of two (the last bit flipping): as if iterated on
            return (nx, ny) if (iterations - 1 - i) % 2 == 0 else (x, y)
        bx, by, x, y = x, y, nx, ny
    return x, y


@numba.njit(cache=True, nogil=True)
def _register(depth_m, rays, rot, trans, color, cam, kind, k, iterations, out, has):
    """Fill ``out`` (H·W×3 uint8) and ``has`` (H·W bool); returns (no depth, outside)."""  # pragma: no cover
    fx, fy, cx, cy = cam[0], cam[1], cam[2], cam[3]
    ch, cw = color.shape[0], color.shape[1]
    k1, k2, p1, p2, k3 = k[0], k[1], k[2], k[3], k[4]
    no_depth = 0
    outside = 0
    flat = depth_m.reshape(-1)
    for i in range(flat.size):
        out[i, 0] = 0
        out[i, 1] = 0
        out[i, 2] = 0
        has[i] = False
        z = np.float64(flat[i])
        if not z > 0:
            no_depth += 1
            continue
        px, py, pz = rays[i, 0] * z, rays[i, 1] * z, rays[i, 2] * z
        qx = px * rot[0, 0] + py * rot[0, 1] + pz * rot[0, 2] + trans[0]
        qy = px * rot[1, 0] + py * rot[1, 1] + pz * rot[1, 2] + trans[1]
        qz = px * rot[2, 0] + py * rot[2, 1] + pz * rot[2, 2] + trans[2]
        if not qz > 0:
            outside += 1
            continue
        x, y = qx / qz, qy / qz
        if kind == 1:
            x, y = _polynomial(x, y, k1, k2, p1, p2, k3)
        elif kind == 2:
            x, y = _invert(x, y, k1, k2, p1, p2, k3, iterations)
        col = np.floor(x * fx + cx + 0.5)
        row = np.floor(y * fy + cy + 0.5)
        if not (col >= 0 and col < cw and row >= 0 and row < ch):
            outside += 1
            continue
        c, r = int(col), int(row)
        out[i, 0] = color[r, c, 0]
        out[i, 1] = color[r, c, 1]
        out[i, 2] = color[r, c, 2]
        has[i] = True
    return no_depth, outside


class Registration:
    """Colour registered to depth for one camera pair (module docstring)."""

    def __init__(
        self, depth_camera: CameraModel, color_camera: CameraModel, color_T_depth: np.ndarray
    ) -> None:
        self.depth_camera, self.color_camera = depth_camera, color_camera
        self.rays = np.ascontiguousarray(pixel_rays(depth_camera))
        pose = np.asarray(color_T_depth, dtype=np.float64)
        self.rot = np.ascontiguousarray(pose[:3, :3])
        self.trans = np.ascontiguousarray(pose[:3, 3])
        self.cam = np.array([color_camera.fx_px, color_camera.fy_px, color_camera.cx_px,
                             color_camera.cy_px], dtype=np.float64)  # fmt: skip
        self.kind = _KIND[color_camera.kind]  # refuses unsupported models here, not per frame
        self.k = color_camera._k()

    def __call__(self, depth_m: np.ndarray, color_rgb: np.ndarray) -> Alignment:
        d, c = self.depth_camera, self.color_camera
        height, width = depth_m.shape
        if (width, height) != (d.width_px, d.height_px):
            raise ConversionError(
                f"depth image is {width}×{height}, its camera {d.width_px}×{d.height_px}"
            )
        ch, cw = color_rgb.shape[:2]
        if (cw, ch) != (c.width_px, c.height_px) or color_rgb.ndim != 3:
            raise ConversionError(
                f"colour image is {cw}×{ch}, its camera {c.width_px}×{c.height_px}"
            )
        out = np.empty((height * width, 3), dtype=np.uint8)
        has = np.empty(height * width, dtype=np.bool_)
        no_depth, outside = _register(
            np.ascontiguousarray(depth_m), self.rays, self.rot, self.trans,
            np.ascontiguousarray(color_rgb, dtype=np.uint8), self.cam, self.kind, self.k,
            UNDISTORT_ITERATIONS, out, has,
        )  # fmt: skip
        return Alignment(
            color_rgb=out.reshape(height, width, 3),
            has_color=has.reshape(height, width),
            no_depth=int(no_depth),
            outside=int(outside),
        )


def warm_up() -> None:
    """Compile the kernel (or load it from numba's cache) for float32 and float64 depth."""
    cam = CameraModel(4, 3, 2.0, 2.0, 1.5, 1.0, "inverse_brown_conrady", (0.01, 0, 0, 0, 0))
    reg = Registration(cam, cam, np.eye(4))
    color = np.zeros((3, 4, 3), dtype=np.uint8)
    for dtype in (np.float32, np.float64):
        reg(np.ones((3, 4), dtype=dtype), color)

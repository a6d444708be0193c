"""Colour registered to depth: what the RealSense SDK's ``align`` to depth does, in numpy.

For every depth pixel with a reading: deproject it to a 3D point in the depth camera (with the
depth camera's distortion), move the point into the colour camera (``color_T_depth``), project
it with the colour intrinsics and distortion, and take the colour of the nearest colour pixel.
A depth pixel without a reading (0), behind the colour camera, or projecting outside the colour
image gets no colour (black, and ``False`` in the returned mask) and is counted by the caller.

Distortion models (as recorded in ``CameraInfo.distortion_model``; the SDK writes its own names,
normalised here: ``"Brown Conrady"`` → ``brown_conrady``):

- ``plumb_bob`` / ``brown_conrady``: OpenCV's model, coefficients ``k1 k2 p1 p2 k3``, mapping an
  ideal normalised point to the distorted one. Projection applies it; deprojection inverts it by
  fixed-point iteration.
- ``inverse_brown_conrady``: the same polynomial mapping a *distorted* normalised point to the
  ideal one (librealsense's colour model on D415/D435). Deprojection applies it; projection
  inverts it by iteration. (librealsense's own projection applies the polynomial forward, an
  approximation; this is the exact inverse.)
- ``none`` (or any model whose coefficients are all zero): pinhole.

Other models (modified Brown-Conrady, F-theta, Kannala-Brandt, rational polynomial) with non-zero
coefficients are refused with :class:`ConversionError` naming the model.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from graph_slam.errors import ConversionError

#: names as written by ROS (camera_info) and by librealsense (rs2_distortion_to_string)
_FORWARD = frozenset({"plumb_bob", "brown_conrady"})
_INVERSE = frozenset({"inverse_brown_conrady"})
_NONE = frozenset({"none", ""})
#: fixed-point iterations when inverting the distortion polynomial (converges to < 1e-9 px for
#: the few-percent distortion of RealSense lenses)
UNDISTORT_ITERATIONS = 20


def normalise_model(name: str) -> str:
    """``"Inverse Brown Conrady"`` → ``inverse_brown_conrady``."""
    return "_".join(str(name).strip().lower().replace("-", " ").split())


@dataclass(frozen=True)
class CameraModel:
    """A camera as recorded: size, pinhole matrix and distortion (model name and coefficients)."""

    width_px: int
    height_px: int
    fx_px: float
    fy_px: float
    cx_px: float
    cy_px: float
    distortion_model: str = "none"
    coeffs: tuple[float, ...] = ()

    @property
    def kind(self) -> str:
        """``forward``, ``inverse`` or ``none``: how the coefficients act (see the module doc)."""
        model = normalise_model(self.distortion_model)
        if not any(self.coeffs) or model in _NONE:
            return "none"
        if model in _FORWARD:
            return "forward"
        if model in _INVERSE:
            return "inverse"
        raise ConversionError(
            f"distortion model {self.distortion_model!r} with non-zero coefficients is not "
            "supported (supported: plumb_bob, brown_conrady, inverse_brown_conrady, none)"
        )

    def _k(self) -> np.ndarray:
        k = np.zeros(5)
        c = np.asarray(self.coeffs, dtype=np.float64)[:5]
        k[: c.size] = c
        return k

    def project(self, points: np.ndarray) -> np.ndarray:
        """N×3 points (z > 0) in this camera → N×2 pixel coordinates (u right, v down)."""
        x = points[:, 0] / points[:, 2]
        y = points[:, 1] / points[:, 2]
        kind = self.kind
        if kind == "forward":
            x, y = _polynomial(x, y, self._k())
        elif kind == "inverse":
            x, y = _invert(x, y, self._k())
        return np.column_stack([x * self.fx_px + self.cx_px, y * self.fy_px + self.cy_px])

    def rays(self, u: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Pixel coordinates → N×3 rays with z = 1 (multiply by depth for the 3D point)."""
        x = (np.asarray(u, dtype=np.float64) - self.cx_px) / self.fx_px
        y = (np.asarray(v, dtype=np.float64) - self.cy_px) / self.fy_px
        kind = self.kind
        if kind == "forward":
            x, y = _invert(x, y, self._k())
        elif kind == "inverse":
            x, y = _polynomial(x, y, self._k())
        return np.column_stack([x, y, np.ones_like(x)])


def _polynomial(x: np.ndarray, y: np.ndarray, k: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Brown-Conrady (OpenCV): radial k1 k2 k3, tangential p1 p2."""
    k1, k2, p1, p2, k3 = k
    r2 = x * x + y * y
    f = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
    return (
        x * f + 2 * p1 * x * y + p2 * (r2 + 2 * x * x),
        y * f + 2 * p2 * x * y + p1 * (r2 + 2 * y * y),
    )


def _invert(xd: np.ndarray, yd: np.ndarray, k: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The (x, y) with ``_polynomial(x, y) = (xd, yd)``, by fixed-point iteration."""
    x, y = xd.copy(), yd.copy()
    for _ in range(UNDISTORT_ITERATIONS):
        px, py = _polynomial(x, y, k)
        x, y = x + (xd - px), y + (yd - py)
    return x, y


@dataclass(frozen=True)
class Alignment:
    """Colour registered to the depth image, and how many depth pixels got none."""

    color_rgb: np.ndarray  #: H×W×3 uint8 at the depth image's size; black where ``~has_color``
    has_color: np.ndarray  #: H×W bool
    no_depth: int  #: depth pixels without a reading
    outside: int  #: depth pixels whose point projects outside the colour image or behind it


def align_color_to_depth(
    depth_m: np.ndarray,
    color_rgb: np.ndarray,
    depth_camera: CameraModel,
    color_camera: CameraModel,
    color_T_depth: np.ndarray,
    depth_rays: np.ndarray | None = None,
) -> Alignment:
    """Give every depth pixel the colour it sees (nearest colour pixel).

    ``depth_m`` H×W metres (0 = no reading) on ``depth_camera``; ``color_rgb`` h×w×3 uint8 on
    ``color_camera``; ``color_T_depth`` 4×4 maps points from the depth camera to the colour
    camera. ``depth_rays`` (H·W×3, from :func:`pixel_rays`) may be passed to reuse them across
    frames (the deprojection of every pixel does not change).
    """
    height, width = depth_m.shape
    if (width, height) != (depth_camera.width_px, depth_camera.height_px):
        raise ConversionError(
            f"depth image is {width}×{height}, its camera {depth_camera.width_px}×"
            f"{depth_camera.height_px}"
        )
    ch, cw = color_rgb.shape[:2]
    if (cw, ch) != (color_camera.width_px, color_camera.height_px):
        raise ConversionError(
            f"colour image is {cw}×{ch}, its camera {color_camera.width_px}×"
            f"{color_camera.height_px}"
        )
    rays = pixel_rays(depth_camera) if depth_rays is None else depth_rays
    z = depth_m.reshape(-1).astype(np.float64)
    valid = z > 0
    points = rays[valid] * z[valid, None]
    rot, trans = np.asarray(color_T_depth)[:3, :3], np.asarray(color_T_depth)[:3, 3]
    in_color = points @ rot.T + trans
    front = in_color[:, 2] > 0
    uv = np.full((in_color.shape[0], 2), -1.0)
    uv[front] = color_camera.project(in_color[front])
    col = np.floor(uv[:, 0] + 0.5).astype(np.int64)
    row = np.floor(uv[:, 1] + 0.5).astype(np.int64)
    inside = front & (col >= 0) & (col < cw) & (row >= 0) & (row < ch)
    out = np.zeros((height * width, 3), dtype=np.uint8)
    idx = np.flatnonzero(valid)[inside]
    out[idx] = color_rgb[row[inside], col[inside]]
    has = np.zeros(height * width, dtype=bool)
    has[idx] = True
    return Alignment(
        color_rgb=out.reshape(height, width, 3),
        has_color=has.reshape(height, width),
        no_depth=int((~valid).sum()),
        outside=int((~inside).sum()),
    )


def pixel_rays(camera: CameraModel) -> np.ndarray:
    """The z = 1 ray of every pixel centre, row-major (H·W×3)."""
    v, u = np.mgrid[0 : camera.height_px, 0 : camera.width_px]
    return camera.rays(u.ravel(), v.ravel())

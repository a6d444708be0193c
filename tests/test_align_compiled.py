"""The compiled colour registration against the numpy reference (align_color_to_depth): the same
colours, mask and counts, pixel for pixel, for every supported distortion model, a colour
camera offset and rotated from the depth camera, pixels without depth, behind the colour camera
and outside its image."""

from __future__ import annotations

import numpy as np
import pytest

from graph_slam.errors import ConversionError
from graph_slam.session.adapters.align import CameraModel, align_color_to_depth, pixel_rays
from graph_slam.session.adapters.align_compiled import Registration

#: the reference's distortion polynomial overflows on the points far outside the image (x/z large)
pytestmark = pytest.mark.filterwarnings("ignore:overflow:RuntimeWarning",
                                        "ignore:invalid value:RuntimeWarning")  # fmt: skip

DEPTH = CameraModel(64, 48, 55.0, 54.0, 31.7, 23.2, "brown_conrady", (0.0,) * 5)
COEFFS = (0.05, -0.02, 0.001, -0.002, 0.003)


def _color_camera(model: str, coeffs: tuple[float, ...]) -> CameraModel:
    return CameraModel(96, 72, 80.0, 79.0, 47.3, 36.1, model, coeffs)


def _pose() -> np.ndarray:
    from scipy.spatial.transform import Rotation

    pose = np.eye(4)
    pose[:3, :3] = Rotation.from_euler("xyz", [0.02, -0.03, 0.01]).as_matrix()
    pose[:3, 3] = [-0.059, 0.0003, 0.0005]
    return pose


def _depth(rng: np.random.Generator, dtype) -> np.ndarray:
    depth = rng.uniform(0.05, 4.0, (DEPTH.height_px, DEPTH.width_px))
    depth[rng.random(depth.shape) < 0.1] = 0.0  # no reading
    depth[:3, :] = 0.01  # so near that the 59 mm offset puts the point outside the image
    return depth.astype(dtype)


@pytest.mark.parametrize(
    ("model", "coeffs"),
    [("none", ()), ("brown_conrady", (0.0,) * 5), ("plumb_bob", COEFFS),
     ("brown_conrady", COEFFS), ("inverse_brown_conrady", COEFFS),
     ("Inverse Brown Conrady", (0.004, -0.001, 0.0002, 0.0001, 0.0))],
)  # fmt: skip
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_compiled_registration_equals_the_reference(model, coeffs, dtype) -> None:
    rng = np.random.default_rng(7)
    color_camera = _color_camera(model, coeffs)
    color = rng.integers(0, 256, (color_camera.height_px, color_camera.width_px, 3), np.uint8)
    depth = _depth(rng, dtype)
    pose = _pose()
    reference = align_color_to_depth(depth, color, DEPTH, color_camera, pose, pixel_rays(DEPTH))
    got = Registration(DEPTH, color_camera, pose)(depth, color)
    np.testing.assert_array_equal(got.color_rgb, reference.color_rgb)
    np.testing.assert_array_equal(got.has_color, reference.has_color)
    assert (got.no_depth, got.outside) == (reference.no_depth, reference.outside)
    # the case is not trivial: colour, no depth and outside all occur
    assert reference.has_color.mean() > 0.3 and reference.no_depth > 0 and reference.outside > 0


def test_behind_the_colour_camera_and_a_bgr_view() -> None:
    rng = np.random.default_rng(3)
    color_camera = _color_camera("none", ())
    pose = _pose()
    pose[:3, 3] = [0.0, 0.0, -2.0]  # the colour camera 2 m ahead: near points are behind it
    bgr = rng.integers(0, 256, (color_camera.height_px, color_camera.width_px, 3), np.uint8)
    rgb_view = bgr[:, :, ::-1]  # not contiguous, as a BGR stream is turned into RGB
    depth = _depth(rng, np.float32)
    reference = align_color_to_depth(depth, np.ascontiguousarray(rgb_view), DEPTH,
                                     color_camera, pose)  # fmt: skip
    got = Registration(DEPTH, color_camera, pose)(depth, rgb_view)
    np.testing.assert_array_equal(got.color_rgb, reference.color_rgb)
    assert got.outside == reference.outside > 0.3 * depth.size


def test_sizes_and_models_are_checked() -> None:
    reg = Registration(DEPTH, _color_camera("none", ()), np.eye(4))
    with pytest.raises(ConversionError, match="depth image is 10×10"):
        reg(np.ones((10, 10), np.float32), np.zeros((72, 96, 3), np.uint8))
    with pytest.raises(ConversionError, match="colour image is 10×72"):
        reg(np.ones((48, 64), np.float32), np.zeros((72, 10, 3), np.uint8))
    with pytest.raises(ConversionError, match="kannala_brandt"):
        Registration(DEPTH, _color_camera("kannala_brandt", COEFFS), np.eye(4))

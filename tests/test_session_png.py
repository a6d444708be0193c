"""The session's PNG encoder: every PNG reader gets the array back, bit for bit."""

import zlib

import numpy as np
import pytest
from PIL import Image

from graph_slam.session import io
from graph_slam.session.png import encode_png


def _images():
    rng = np.random.default_rng(7)
    y, x = np.mgrid[0:37, 0:53]
    smooth = (4000 + 25 * y + 3 * x).astype(np.uint16)
    return {
        "depth smooth": smooth,
        "depth with holes": np.where(rng.random(smooth.shape) < 0.2, 0, smooth).astype(np.uint16),
        "depth full range": rng.integers(0, 65536, (29, 31)).astype(np.uint16),
        "colour noise": rng.integers(0, 256, (21, 34, 3)).astype(np.uint8),
        "one row": rng.integers(0, 65536, (1, 17)).astype(np.uint16),
        "one pixel": np.array([[[255, 0, 7]]], np.uint8),
    }


@pytest.mark.parametrize("level", [0, 1, 6])
@pytest.mark.parametrize("name", list(_images()))
def test_pillow_decodes_what_was_encoded(tmp_path, name, level):
    array = _images()[name]
    path = tmp_path / "x.png"
    io.write_png(path, array, compress_level=level)
    with Image.open(path) as im:
        im.verify()  # the chunks' CRCs and layout
    back = io.read_png(path, expect_mode="depth16" if array.ndim == 2 else "rgb8")
    assert back.dtype == array.dtype and back.shape == array.shape
    np.testing.assert_array_equal(back, array)


def test_rows_are_up_filtered_and_level_0_is_stored():
    array = np.tile(np.arange(40, dtype=np.uint16) * 300, (30, 1))  # every row the same
    packed = encode_png(array, 1)
    raw = zlib.decompress(packed[packed.index(b"IDAT") + 4 : -12 - 4])
    rows = np.frombuffer(raw, np.uint8).reshape(30, 81)
    assert rows[0, 0] == 0 and (rows[1:, 0] == 2).all()  # None, then Up
    assert not rows[1:, 1:].any()  # a row equal to the one above filters to zeros
    assert len(packed) < len(encode_png(array, 0)) / 10  # ... and deflates to little
    assert len(encode_png(array, 0)) > array.nbytes  # stored: the raw bytes and headers


@pytest.mark.parametrize(
    "array",
    [np.zeros((4, 4), np.float32), np.zeros((4, 4, 4), np.uint8), np.zeros((0, 3), np.uint16)],
)
def test_unsupported_images_are_refused(array):
    with pytest.raises(ValueError, match="encode_png"):
        encode_png(array)


def test_level_out_of_range_is_refused():
    with pytest.raises(ValueError, match="level"):
        encode_png(np.zeros((2, 2), np.uint16), 10)

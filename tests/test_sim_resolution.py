"""``graph-slam simulate --resolution``: the D455's real-time modes, intrinsics scaled with the
image, ``--fast`` as the 212x120 alias, sizes the profile cannot bin to rejected."""

from __future__ import annotations

import pytest

from graph_slam.errors import ConfigError, SimulationError
from graph_slam.sim.config import CameraProfile, SimConfig, load_profile
from graph_slam.sim.render import image_size, intrinsics_for


@pytest.fixture(scope="module")
def d455() -> CameraProfile:
    return load_profile(CameraProfile, "d455")


@pytest.mark.parametrize(("resolution", "scale"), [("848x480", 1), ("424x240", 2), ("212x120", 4)])
def test_intrinsics_scale_with_the_image(d455, resolution, scale) -> None:
    full = intrinsics_for(d455)
    k = intrinsics_for(d455, resolution=resolution)
    assert (k.width_px, k.height_px) == (848 // scale, 480 // scale)
    assert k.fx_px == pytest.approx(full.fx_px / scale, rel=1e-12)
    assert k.fy_px == pytest.approx(full.fy_px / scale, rel=1e-12)
    # pixel centres: (c + 0.5) / scale - 0.5, the principal point stays at the centre
    assert k.cx_px == pytest.approx((full.cx_px + 0.5) / scale - 0.5)
    assert k.cy_px == pytest.approx((full.cy_px + 0.5) / scale - 0.5)


def test_fast_is_the_212x120_mode(d455) -> None:
    assert intrinsics_for(d455, fast=True) == intrinsics_for(d455, resolution="212x120")


@pytest.mark.parametrize("resolution", ["640x480", "1696x960", "424x241", "4x2"])
def test_sizes_the_profile_cannot_bin_to_are_rejected(d455, resolution) -> None:
    with pytest.raises(SimulationError, match="848x480, 424x240, 212x120"):
        image_size(d455, resolution=resolution)


def test_config_takes_one_size_option() -> None:
    from graph_slam.config import config_from_dict

    with pytest.raises(ConfigError, match="either fast"):
        config_from_dict(SimConfig, {"fast": True, "resolution": "212x120"})
    with pytest.raises(ConfigError, match="resolution"):
        config_from_dict(SimConfig, {"resolution": "424 x 240"})


def test_a_short_session_at_424x240(tmp_path) -> None:
    from graph_slam.session import open_session
    from graph_slam.sim import simulate

    cfg = SimConfig(strides=1, seed=4, resolution="424x240", drops="none", quicklook=False)
    cfg = cfg.model_copy(update={"motion": cfg.motion.model_copy(update={"lead_out_s": 0.0})})
    simulate(cfg, tmp_path / "s")
    s = open_session(tmp_path / "s")
    assert s.intrinsics == intrinsics_for(load_profile(CameraProfile, "d455"), resolution="424x240")
    frame = s.frame(0)
    assert frame.depth_m.shape == (240, 424) and frame.color_rgb.shape == (240, 424, 3)
    assert s.n_frames > 100  # drops none: every frame of the 90 Hz stream


def test_cli_rejects_a_size_the_camera_has_not(tmp_path) -> None:
    import subprocess
    import sys

    out = subprocess.run(
        [sys.executable, "-m", "graph_slam", "simulate", "--out", str(tmp_path / "x"),
         "--resolution", "640x480"],
        capture_output=True, text=True, check=False,
    )  # fmt: skip
    assert out.returncode == 2 and "848x480, 424x240, 212x120" in out.stderr
    assert not (tmp_path / "x").exists()

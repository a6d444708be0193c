"""The frame-only part of the real-time preparation done ahead (another thread in the live loop):
``prepare_depth`` with it gives the same arrays as without; it is taken only by the frame made
of the same arrays, with the same use of colour, once; and a pipeline given it for some frames
(with a stranger's thrown in) poses every frame exactly as one never given it."""

from __future__ import annotations

import numpy as np
from test_frontend_projective import CFG, SMALL, frame_at
from test_frontend_registration import K

from graph_slam.frontend.methods import OrganisedAhead
from graph_slam.frontend.projective import organise_depth, prepare_depth
from graph_slam.session.records import RgbdFrame

FIELDS = ("points_m", "normals", "intensity", "gradients", "pixel_voxel", "pixel_points_m")


def _same(a, b) -> None:
    for name in FIELDS:
        x, y = getattr(a, name), getattr(b, name)
        assert (x is None) == (y is None), name
        if x is not None:
            np.testing.assert_array_equal(x, y, err_msg=name)
    assert a.camera == b.camera


def test_prepared_with_the_organised_part_done_ahead_is_the_same() -> None:
    frame = frame_at(SMALL, seed=3)
    grid = np.eye(4)
    grid[:3, 3] = [0.013, -0.007, 0.002]  # a grid not the frame's own
    for color in (True, False):
        plain = prepare_depth(frame, K, CFG, None, grid, color)
        ahead = organise_depth(frame, K, CFG, None, color)
        _same(prepare_depth(frame, K, CFG, None, grid, color, ahead), plain)
        assert ahead.color == color
    assert len(plain.points_m) > 100


def test_the_organised_part_of_another_frame_or_colour_is_not_used() -> None:
    frame = frame_at(SMALL, seed=3)
    other = frame_at(SMALL, seed=4)  # same pose, other noise: other arrays
    same_values = RgbdFrame(frame.t_s, frame.depth_m.copy(), frame.color_rgb, frame.index)
    mine = organise_depth(frame, K, CFG)
    assert mine.fits(frame, True) and not mine.fits(frame, False)
    assert not mine.fits(other, True) and not mine.fits(same_values, True)
    assert mine.fits(frame.renumbered(9), True)  # the same arrays
    _same(prepare_depth(other, K, CFG, organised=mine), prepare_depth(other, K, CFG))
    depth_only = organise_depth(frame, K, CFG, use_color=False)
    _same(prepare_depth(frame, K, CFG, organised=depth_only), prepare_depth(frame, K, CFG))


def test_the_ahead_queue_gives_each_one_once_to_its_frame_and_drops_the_oldest() -> None:
    frames = [frame_at(SMALL, seed=s) for s in range(4)]
    ahead = OrganisedAhead(size=3)
    for f in frames:
        ahead.put(organise_depth(f, K, CFG))
    assert len(ahead) == 3
    assert ahead.take(frames[0], True) is None  # dropped: the oldest
    got = ahead.take(frames[2], True)
    assert got is not None and got.depth_m is frames[2].depth_m
    assert ahead.take(frames[2], True) is None  # taken once
    assert ahead.take(frames[3], False) is None and len(ahead) == 2


def test_a_pipeline_given_frames_ahead_poses_them_as_one_never_given_them(tmp_path) -> None:
    """A simulated stride with colour at 212×120 (the real-time preset's projective front end,
    compiled and single-threaded: run twice, the same floats)."""
    from graph_slam.pipelines.config import PipelineConfig, with_preset
    from graph_slam.pipelines.runner import open_pipeline
    from graph_slam.sim import SimConfig, simulate

    simulate(SimConfig(strides=1, seed=2, resolution="212x120", drops="none", quicklook=False),
             tmp_path / "sim")  # fmt: skip
    cfg = PipelineConfig.model_validate(
        with_preset({"variant": "icp+imu+kin", "max_frames": 40}, "realtime")
    )

    def run(ahead: bool) -> list[tuple]:
        session, streams, pipe = open_pipeline(tmp_path / "sim", cfg)
        pipe.add_imu(streams.imu_t_s, streams.gyro_rad_s, streams.accel_m_s2)
        pipe.add_joints(streams.joints_t_s, streams.knee_rad, streams.ankle_rad)
        out, t_prev = [], -np.inf
        frames = list(session.iter_frames(0, cfg.max_frames))
        for i, frame in enumerate(frames):
            if ahead and i % 3 != 2:  # some frames not given ahead
                pipe.prepare_ahead(frame)
                if i % 2 == 0 and i + 1 < len(frames):
                    pipe.prepare_ahead(frames[i + 1])  # a stranger's, taken by its own later
            for t in (t for t in streams.foot_strikes_s if t_prev < t <= frame.t_s):
                pipe.foot_strike(t)
            o = pipe.add_frame(frame, streams.foot_loaded(frame.t_s))
            t_prev = frame.t_s
            pose = None if o.stride_T_camera is None else o.stride_T_camera.copy()
            out.append((o.stride_index, pose, o.fitness, o.registered_to, o.flags))
        return out

    plain, ahead = run(False), run(True)
    assert len(plain) == 40 and sum(o[3] is not None for o in plain) >= 20  # registered
    for a, b in zip(plain, ahead, strict=True):
        assert (a[0], a[3], a[4]) == (b[0], b[3], b[4])
        np.testing.assert_array_equal(a[1], b[1])
        assert a[2] == b[2] or (np.isnan(a[2]) and np.isnan(b[2]))

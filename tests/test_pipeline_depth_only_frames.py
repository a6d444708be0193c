"""Frames recorded without colour (colour slower than depth, or missing) in a colour session:
every frame is registered, the colourless ones (and those whose keyframe has no colour) with
the graph's depth-only settings; the thesis baseline runs the session without colour."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from graph_slam.pipelines.config import PipelineConfig
from graph_slam.pipelines.runner import run_session
from graph_slam.session import open_session
from graph_slam.sim import SimConfig, simulate

FRAMES = 30


@pytest.fixture(scope="module")
def _walk(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("walk") / "s"
    simulate(SimConfig(strides=1, seed=2, resolution="106x60", drops="none", quicklook=False), out)
    return out


@pytest.fixture
def walk(_walk: Path, tmp_path: Path) -> Path:
    copy = tmp_path / "s"
    shutil.copytree(_walk, copy)
    return copy


def _drop_colour(session: Path, every: int) -> int:
    """Blank the colour of every ``every``-th frame (as a 30 Hz colour beside faster depth)."""
    lines = (session / "frames.csv").read_text().splitlines()
    out, blanked = [lines[0]], 0
    for k, line in enumerate(lines[1:]):
        fields = line.split(",")
        if k % every == 1:
            fields[3] = ""
            blanked += 1
        out.append(",".join(fields))
    (session / "frames.csv").write_text("\n".join(out) + "\n")
    return blanked


def test_graph_registers_colourless_frames_with_the_depth_only_settings(
    walk: Path,
) -> None:
    blanked = _drop_colour(walk, 3)
    session = open_session(walk)
    assert session.manifest.sensors.camera.has_color
    assert session.n_color_frames == session.n_frames - blanked
    config = PipelineConfig(variant="icp+imu+kin", max_frames=FRAMES, preset="accurate")
    results = run_session(session, config)
    assert len(results.frames) == FRAMES
    assert all(f.stride_T_camera is not None for f in results.frames if f.stride_index >= 0)
    registered = [f for f in results.frames if f.registered_to is not None]
    colourless = [f for f in registered if f.frame_index % 3 == 1]
    ok = [f for f in colourless if not any("failed" in fl for fl in f.flags)]
    # a colourless frame registers point-to-plane (a colored ICP against it would refuse);
    # at this low resolution some registrations fail with or without colour
    assert len(colourless) >= 5 and len(ok) >= len(colourless) // 2
    assert all(np.isfinite(f.fitness) and f.fitness > 0.3 for f in ok)


def test_thesis_baseline_runs_a_session_with_colourless_frames(walk: Path) -> None:
    _drop_colour(walk, 3)
    config = PipelineConfig(variant="icp", max_frames=FRAMES)
    results = run_session(walk, config)
    assert len(results.frames) == FRAMES


def _blank_colour(session: Path, first: int, last: int) -> None:
    """No colour image for frames ``first``..``last`` (a gap in the colour stream)."""
    lines = (session / "frames.csv").read_text().splitlines()
    out = [lines[0]]
    for k, line in enumerate(lines[1:]):
        fields = line.split(",")
        if first <= k <= last:
            fields[3] = ""
        out.append(",".join(fields))
    (session / "frames.csv").write_text("\n".join(out) + "\n")


@pytest.mark.parametrize("recolour", [True, False])
def test_a_coloured_frame_replaces_a_keyframe_without_colour(
    walk: Path, monkeypatch: pytest.MonkeyPatch, recolour: bool
) -> None:
    """A colour gap longer than twice the keyframe interval leaves a colourless keyframe; with
    ``graph.recolour_keyframe`` the first frame with colour after the gap becomes the keyframe
    and the frames after it register with colour again; without, they register without
    colour until the keyframe is reset."""
    from graph_slam.pipelines.graph import GraphPipeline

    _blank_colour(walk, 5, 16)  # 12 frames at 90 Hz: 0.13 s > 2 × 0.05 s
    seen: list[tuple[int, bool]] = []
    coloured = GraphPipeline._coloured

    def spy(self, frame, index, key_index):
        used = coloured(self, frame, index, key_index)
        seen.append((index, used))
        return used

    monkeypatch.setattr(GraphPipeline, "_coloured", spy)
    config = PipelineConfig.model_validate(
        {"variant": "icp+imu+kin", "max_frames": FRAMES, "graph": {"recolour_keyframe": recolour}}
    )
    results = run_session(walk, config)
    assert len(results.frames) == FRAMES
    assert any(used for index, used in seen if index < 5)  # with colour before the gap
    assert not any(used for index, used in seen if 5 <= index <= 17)
    # the frames after the gap, before anything else resets the keyframe in this walk (a
    # colourless keyframe is dropped by frame 25 here either way)
    after = [used for index, used in seen if 19 <= index <= 24]
    assert len(after) == 6
    if recolour:
        assert all(after), str(seen)
    else:
        assert not any(after), str(seen)


def test_the_realtime_preset_registers_a_106x60_walk(walk: Path) -> None:
    """The projective preset's voxel, depth-jump and correspondence limits grow with the
    decimated pixel's angle: on a 106×60 image its 2 cm voxels held one pixel each and every
    frame failed as an empty source; now nearly all register (colour kept, every frame)."""
    from graph_slam.frontend.config import ProjectiveConfig
    from graph_slam.frontend.methods import projective_for_camera

    session = open_session(walk)
    base = ProjectiveConfig()
    small = projective_for_camera(base, session.intrinsics)
    scale = small.voxel_m / base.voxel_m
    assert 1.5 < scale < 2.2  # fx ≈ 56 px against the preset's 100 px
    assert small.max_jump_ratio == pytest.approx(base.max_jump_ratio * scale)
    assert small.max_correspondence_m == pytest.approx(base.max_correspondence_m * scale)
    wide = _scaled_intrinsics(session.intrinsics, 4)  # the same camera at 424×240
    assert projective_for_camera(base, wide) is base  # unchanged at 212×120 and above

    results = run_session(session, PipelineConfig(variant="icp+imu+kin", max_frames=FRAMES))
    registered = [f for f in results.frames if f.registered_to is not None]
    failed = [f for f in registered if any("failed" in fl for fl in f.flags)]
    assert len(registered) >= FRAMES - 3 and len(failed) <= 2, [f.flags for f in failed]


def _scaled_intrinsics(intrinsics, factor: int):
    """``intrinsics`` of the same camera at ``factor`` times the size."""
    import dataclasses

    return dataclasses.replace(
        intrinsics,
        width_px=intrinsics.width_px * factor,
        height_px=intrinsics.height_px * factor,
        fx_px=intrinsics.fx_px * factor,
        fy_px=intrinsics.fy_px * factor,
        cx_px=intrinsics.cx_px * factor,
        cy_px=intrinsics.cy_px * factor,
    )

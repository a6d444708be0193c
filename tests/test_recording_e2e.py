"""A recording end to end, as a researcher gets one: a RealSense SDK recording written by
librealsense (colour not aligned to depth, at its own rate and size; the cameras' extrinsics in
the recording) and a prosthesis log on its own clock, exported from the
simulator (``graph-slam simulate --export realsense-sdk-bag``), then ``graph-slam convert``
with only the topic preset and the log's column mapping, then ``graph-slam run`` — the
commands of docs/recording.md, through the CLI's entry point."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from graph_slam.cli import main

pytest.importorskip("rosbags")
pytest.importorskip("pyrealsense2")

CLOCK_OFFSET_S = 3.217
STRIDES = 5  # 6 foot strikes: the clock offset needs at least 5 matched
RUN_FRAMES = 70  # run covers the first ~1.5 strides (keeps the test fast)


def _cli(*args: str) -> None:
    with pytest.raises(SystemExit) as done:
        main([str(a) for a in args])
    assert done.value.code == 0, f"graph-slam {' '.join(map(str, args))} failed"


@pytest.fixture(scope="module")
def converted(tmp_path_factory) -> tuple[Path, Path]:
    """(the exported recording's folder, the converted session)."""
    base = tmp_path_factory.mktemp("e2e")
    rec, session = base / "rec", base / "walk"
    _cli("simulate", "--export", "realsense-sdk-bag", "--out", rec, "--strides", STRIDES,
         "--resolution", "106x60", "--no-blur", "--seed", "2",
         "--clock-offset", CLOCK_OFFSET_S)  # fmt: skip
    _cli("convert", rec / "recording.db3", session, "--config", rec / "convert.yaml")
    return rec, session


@pytest.fixture(scope="module")
def ran(converted, tmp_path_factory) -> Path:
    _, session = converted
    base = tmp_path_factory.mktemp("run")
    cfg = base / "run.yaml"
    cfg.write_text(
        yaml.safe_dump(
            {
                "variants": ["icp+imu+kin"],
                # colored ICP and the stride maps (checked below); no mount pitch: estimated
                "pipeline": {"preset": "accurate", "max_frames": RUN_FRAMES},
                "rrd": False,
            }
        )
    )
    out = base / "out"
    _cli("run", session, "--out", out, "--config", cfg)
    return out


def test_convert_config_sets_no_offset_and_no_extrinsics(converted) -> None:
    rec, _ = converted
    cfg = yaml.safe_load((rec / "convert.yaml").read_text())
    assert set(cfg) == {"bag", "prosthesis_log", "calibration"}
    assert cfg["bag"] == {"preset": "realsense-sdk"} and set(cfg["calibration"]) == {"camera_T_imu"}
    assert set(cfg["prosthesis_log"]) == {"path", "time", "knee", "ankle", "load"}


def test_clock_offset_estimated_within_10_ms(converted) -> None:
    _, session = converted
    report = yaml.safe_load((session / "conversion_report.yaml").read_text())
    offset = report["clock_offset"]
    assert offset["source"] == "estimated"
    assert offset["offset_s"] == pytest.approx(CLOCK_OFFSET_S, abs=0.010)
    assert offset["n_matched"] >= 5


def test_extrinsics_come_from_the_recording_and_the_config(converted) -> None:
    """color_T_depth from the recording's tf text; camera_T_imu (which librealsense does not
    record for motion streams) from convert.yaml."""
    rec, session = converted
    truth = yaml.safe_load((rec / "export.yaml").read_text())
    calib = yaml.safe_load((session / "conversion_report.yaml").read_text())["calibration"]
    assert calib["color_T_depth"]["source"].startswith("bag (")
    # the SDK's text keeps 6 decimals
    np.testing.assert_allclose(calib["color_T_depth"]["value"], truth["color_T_depth"], atol=2e-6)
    resolved = yaml.safe_load((session / "conversion.yaml").read_text())
    np.testing.assert_allclose(resolved["calibration"]["camera_T_imu"], truth["camera_T_imu"],
                               atol=1e-9)  # fmt: skip


def test_aligned_colour_matches_the_simulators_registered_colour(converted) -> None:
    """Known answer: the colour the simulator renders from the depth camera itself (what a
    perfectly registered colour is) against the bag's colour camera registered by convert.
    Stated tolerance: ≥ 93 % of the depth pixels that got a colour within 30 grey levels
    (max over channels; measured 95-97 %, and 89-92 % within 20); the residual comes from the noisy depth used to deproject, the
    nearest-pixel lookup in a colour image of another resolution, and texture edges. A
    2-pixel shift of the reference must score clearly worse (the check resolves 2 px)."""
    from graph_slam.session import open_session
    from graph_slam.sim import SimConfig
    from graph_slam.sim.recording import prepare
    from graph_slam.sim.render import Renderer, intrinsics_for

    rec, session_path = converted
    truth = yaml.safe_load((rec / "export.yaml").read_text())
    cfg = SimConfig(**truth["sim"])
    sim = prepare(cfg)
    renderer = Renderer(
        sim.scene, intrinsics_for(sim.camera, cfg.fast, cfg.resolution), sim.camera,
        motion_blur=False,
    )  # fmt: skip
    session = open_session(session_path)
    assert session.manifest.sensors.camera.has_color
    epoch = truth["export"]["camera_epoch_s"]
    # colour frames at 30 Hz from the first depth frame: registered ones within 1 ms of
    # their depth frame (the others moved with the leg in between)
    export = truth["export"]
    t = session.frame_times_s
    t_color = t[0] + export["color_delay_s"] + np.arange(200) / export["color_rate_hz"]
    near = [k for k in range(t.size) if np.min(np.abs(t_color - t[k])) < 1e-3]
    assert len(near) >= 6
    for index in (near[len(near) // 5], near[len(near) // 2], near[4 * len(near) // 5]):
        frame = session.frame(index)
        world_T_camera = sim.motion.world_T(np.array([frame.t_s - epoch]), sim.thigh_T_camera)
        expected = renderer.render_color(world_T_camera[0]).astype(int)
        got = frame.color_rgb.astype(int)
        coloured = (frame.depth_m > 0) & (got.sum(axis=-1) > 0)
        assert coloured.sum() > 0.3 * coloured.size
        close = np.abs(expected - got).max(axis=-1)[coloured] <= 30
        shifted = np.abs(np.roll(expected, 2, axis=1) - got).max(axis=-1)[coloured] <= 30
        assert close.mean() >= 0.93, (index, close.mean())
        assert shifted.mean() < close.mean() - 0.2, (index, shifted.mean(), close.mean())


def test_run_writes_its_artefacts_with_colored_icp(ran) -> None:
    cfg = yaml.safe_load((ran / "config.yaml").read_text())
    assert cfg["pipeline"]["graph"]["registration"]["method"] == "colored"
    summary = yaml.safe_load((ran / "run.json").read_text())
    (session_name,) = summary["sessions"]  # the manifest's name: the bag's stem
    assert session_name == "recording"
    folder = ran / session_name / "icp_imu_kin"
    for name in ("online.tum", "smoothed.tum", "online_world.tum", "smoothed_world.tum",
                 "frames.csv", "timing.csv"):  # fmt: skip
        assert (folder / name).is_file(), name
    assert list((folder / "maps").glob("s*_*.ply"))
    assert (ran / "report.md").is_file() and (ran / "run.json").is_file()
    strides = summary["sessions"][session_name]["variants"]["icp+imu+kin"]["strides"]
    assert "mount pitch" in (ran / "report.md").read_text().lower()
    # depth-only frames (no colour image within 20 ms: colour is at 30 Hz) register
    # point-to-plane, whose floor-dominated view holds fewer directions ("partial")
    registered = sum(s["registered"] + s["partial"] for s in strides)
    assert registered >= 0.8 * RUN_FRAMES


def test_mount_pitch_is_estimated_from_the_recording(ran, converted) -> None:
    """No hand-set mount: the converted session's thigh_T_camera is the identity, so the pitch
    comes from its foot-flat stance (graph_slam.strides.mount); the export's is 35°."""
    rec, _ = converted
    truth = yaml.safe_load((rec / "export.yaml").read_text())["sim"]["mount_pitch_deg"]
    mount = yaml.safe_load((ran / "run.json").read_text())["sessions"]["recording"]["mount_pitch"]
    assert mount["source"] == "estimated"
    assert mount["pitch_deg"] == pytest.approx(truth, abs=1.0)
    assert mount["n_samples"] >= 100


def _read_tum(path: Path) -> tuple[np.ndarray, np.ndarray]:
    table = np.loadtxt(path, comments="#", ndmin=2)
    return table[:, 0], table[:, 1:4]


def test_trajectory_is_close_to_the_ground_truth(ran, converted) -> None:
    """The smoothed world trajectory against the exported ground truth (not used by convert
    or run) after a rigid alignment of the positions, over ~1.5 strides at 106×60: RMS below
    2 cm. Colour is at 30 Hz beside 90 Hz depth, so two thirds of the frames register without
    colour (point-to-plane): measured 4.1 mm (4.9 cm without the first stride's second
    smoothing, ``backend.priors.first_stride_refit: false``: the frames before the first foot
    strike are then tilted by the first frame's gravity estimate)."""
    rec, _ = converted
    t_est, p_est = _read_tum(ran / "recording" / "icp_imu_kin" / "smoothed_world.tum")
    t_gt, p_gt = _read_tum(rec / "ground_truth.tum")
    idx = np.clip(np.searchsorted(t_gt, t_est - 1e-4), 0, t_gt.size - 1)
    assert np.all(np.abs(t_gt[idx] - t_est) < 1e-4)
    assert t_est.size >= 0.8 * RUN_FRAMES
    p_gt = p_gt[idx]
    from graph_slam.report.summary import rigid_fit

    rot, t = rigid_fit(p_est, p_gt)
    aligned = p_est @ rot.T + t
    rms = float(np.sqrt(np.mean(np.sum((aligned - p_gt) ** 2, axis=1))))
    travelled = float(np.linalg.norm(p_gt[-1] - p_gt[0]))
    assert travelled > 0.5
    assert rms < 0.02, rms


def test_an_unknown_export_is_a_clear_error(tmp_path: Path, capsys) -> None:
    with pytest.raises(SystemExit) as done:
        main(["simulate", "--export", "rosbag2", "--out", str(tmp_path / "x"), "--strides", "1"])
    assert done.value.code == 2
    assert "--export 'rosbag2': choose session or realsense-sdk-bag" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()


def test_a_clock_offset_without_an_export_is_a_clear_error(tmp_path: Path, capsys) -> None:
    with pytest.raises(SystemExit) as done:
        main(["simulate", "--clock-offset", "2.0", "--out", str(tmp_path / "x"), "--strides", "1"])
    assert done.value.code == 2
    assert "--clock-offset: only with --export realsense-sdk-bag" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()

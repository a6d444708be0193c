"""compare / demo / view: a smoke run writes every promised file; view without a display; errors."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from graph_slam.cli import main

pytest.importorskip("evo")

# Coarse, fast settings: one quarter-resolution stride, the baseline with one ICP level and the
# cheap graph variant (both pipeline kinds, online and smoothed), coarse map clouds.
FAST_CONFIG = {
    "variants": ["icp", "imu+kin"],
    "pipeline": {
        "baseline": {
            "registration": {
                "levels": [{"voxel_m": 0.04, "max_correspondence_m": 0.04, "max_iterations": 15}]
            }
        },
        "terrain": {"pixel_step": 2},
    },
    "rrd_frame_step": 10,
}


@pytest.fixture(scope="module")
def tiny_session(tmp_path_factory) -> Path:
    from graph_slam.sim import SimConfig, simulate

    out = tmp_path_factory.mktemp("sim") / "session"
    cfg = SimConfig(strides=1, fast=True, drops="bursty", seed=3, quicklook=False)
    return simulate(cfg, out).path


@pytest.fixture(scope="module")
def report_dir(tiny_session: Path, tmp_path_factory) -> tuple[Path, subprocess.CompletedProcess]:
    import yaml

    base = tmp_path_factory.mktemp("cmp")
    cfg_path = base / "compare.yaml"
    cfg_path.write_text(yaml.safe_dump(FAST_CONFIG))
    out = base / "report"
    run = subprocess.run(
        [sys.executable, "-m", "graph_slam", "compare", str(tiny_session), "--out", str(out),
         "--config", str(cfg_path)],
        capture_output=True, text=True, timeout=300, check=False,
    )  # fmt: skip
    return out, run


def test_compare_writes_every_promised_file(report_dir) -> None:
    from graph_slam.evaluation import read_metrics_json

    out, run = report_dir
    assert run.returncode == 0, run.stderr
    assert "Table 4.2" in run.stdout and "Table 4.1" in run.stdout
    for name in ("report.md", "metrics.json", "config.yaml", "recording.rrd"):
        assert (out / name).is_file() and (out / name).stat().st_size > 0, name
    doc = read_metrics_json(out / "metrics.json")
    assert set(doc["variants"]) == {"icp", "imu+kin", "imu+kin smoothed"}
    assert set(doc["maps"]) == {"icp", "imu+kin", "ground truth"}
    assert len(doc["maps"]["ground truth"]["strides"]) == 1
    strides = doc["variants"]["imu+kin"]["strides"]
    assert len(strides) == 1 and strides[0]["frames"]["recorded"] > 10
    assert strides[0]["trajectory"]["n_evaluated"] == strides[0]["frames"]["recorded"]
    report = (out / "report.md").read_text()
    assert "Table 4.2" in report and "Table 4.1" in report and "| Walking speed |" in report
    assert "## Warnings" in report and isinstance(doc["warnings"], list)  # docs/reliability.md
    assert (out / ".graph-slam-output").is_file()  # written whole, then renamed (atomic)
    (session_dir,) = (out / "trajectories").iterdir()
    tums = {p.name for p in session_dir.glob("*.tum")}
    assert tums == {
        "icp_online.tum",
        "icp_smoothed.tum",
        "imu_kin_online.tum",
        "imu_kin_smoothed.tum",
        "ground_truth.tum",
    }
    # the main variant's (the last asked for) and the truth's maps by default; the rest on
    # request (map_files: all), every one scored either way (doc["maps"] above)
    for variant in ("imu_kin", "ground_truth"):
        assert list((out / "maps" / variant).glob("*_s00.ply")), variant
    assert not (out / "maps" / "icp").exists()
    assert doc["preset"] == "realtime"
    plots = {p.name.split("_")[0] for p in (out / "plots").glob("*.png")}
    assert {"trajectory", "error", "map", "elevation", "obstacles"} <= plots


def test_compare_reports_the_deadline_and_the_live_grid(report_dir) -> None:
    """The deadline section in report.md and metrics.json (schema 4) for the baseline and the
    graph variant, the gait-phase plot, and the main variant's live grid in the recording."""
    from graph_slam.evaluation import read_metrics_json

    out, run = report_dir
    assert run.returncode == 0, run.stderr
    doc = read_metrics_json(out / "metrics.json")
    assert doc["schema_version"] == 4
    deadlines = doc["terrain_deadlines"]
    assert set(deadlines) == {"icp", "imu+kin"}
    for section in deadlines.values():
        assert len(section["strides"]) == 1
        assert section["all"]["n"] == sum(len(s["obstacles"]) for s in section["strides"])
    assert "## Obstacles known before toe-off" in (out / "report.md").read_text()
    assert "| imu+kin | all | 1 |" in (out / "report.md").read_text()
    assert (out / "plots" / "obstacle_known_gait_phase.png").is_file()
    # the final grids' features against the scene, the swing clearance against the truth
    features = doc["terrain_features"]
    assert set(features) == {"icp", "imu+kin"}
    for f in features.values():
        assert f["grids"] == 1 and set(f) >= {"steps", "ramps", "curbs", "boxes"}
        clearance = f["swing_clearance"]
        assert clearance["n"] in (0, 1)
        if clearance["n"]:
            assert clearance["rmse"] < 0.05
        assert f["warnings"]["swings"] == clearance["n"]
        assert f["warnings"]["flagged_below_margin"] <= f["warnings"]["true_below_margin"]
    assert "## Terrain features and toe clearance" in (out / "report.md").read_text()
    from rerun.chunk import RrdReader

    paths = set(RrdReader(out / "recording.rrd").store().schema().entity_paths())
    assert {"/world/stride/terrain/height", "/world/stride/terrain/sigma"} <= paths, paths


def test_ground_truth_tum_matches_the_session(report_dir, tiny_session: Path) -> None:
    """The reference trajectory starts each stride at the heel: camera ~0.9 m above the floor."""
    from graph_slam.session.io import read_tum

    out, run = report_dir
    assert run.returncode == 0, run.stderr
    (session_dir,) = (out / "trajectories").iterdir()
    t_s, poses = read_tum(session_dir / "ground_truth.tum")
    assert t_s.size > 10
    assert 0.5 < poses[0, 2, 3] < 1.2  # camera height above the heel, metres
    assert abs(poses[0, 1, 3]) < 0.2  # camera roughly above the foot's line


def test_truth_stride_frame_known_answer() -> None:
    # Foot pitched 20° toe-up, yawed 30°, heel at (1, 2, 0); camera 1 m above the heel.
    from scipy.spatial.transform import Rotation

    from graph_slam.strides.reference import truth_world_T_stride

    world_T_foot = np.eye(4)
    world_T_foot[:3, :3] = Rotation.from_euler("ZY", [30, -20], degrees=True).as_matrix()
    world_T_foot[:3, 3] = [1.0, 2.0, 0.0]
    foot_T_camera = np.eye(4)
    foot_T_camera[:3, 3] = [0.1, 0.0, 1.0]
    w_T_s = truth_world_T_stride(world_T_foot @ foot_T_camera, foot_T_camera)
    np.testing.assert_allclose(w_T_s[:3, 3], [1.0, 2.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(w_T_s[:3, 2], [0, 0, 1], atol=1e-12)
    yaw = np.radians(30)
    np.testing.assert_allclose(w_T_s[:3, 0], [np.cos(yaw), np.sin(yaw), 0], atol=1e-12)


def test_view_without_display_prints_how_to_open(tmp_path: Path, monkeypatch, capsys) -> None:
    (tmp_path / "recording.rrd").write_bytes(b"RRF2")
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    with pytest.raises(SystemExit) as exc:
        main(["view", str(tmp_path)])
    assert exc.value.code == 0
    assert f"rerun {tmp_path / 'recording.rrd'}" in capsys.readouterr().out


def test_view_missing_recording_names_the_file(tmp_path: Path, capsys) -> None:
    """A folder without any .rrd, and a .rrd path that does not exist: exit 2, the file named."""
    with pytest.raises(SystemExit) as exc:
        main(["view", str(tmp_path)])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and f"{tmp_path / 'recording.rrd'}: no such recording" in err
    with pytest.raises(SystemExit) as exc:
        main(["view", str(tmp_path / "other.rrd")])
    assert exc.value.code == 2
    assert f"{tmp_path / 'other.rrd'}: no such recording" in capsys.readouterr().err


def test_view_with_a_display_starts_rerun_detached(tmp_path: Path, monkeypatch, capsys) -> None:
    """With a display, ``rerun FILE`` is started in its own session (Popen replaced: no viewer)."""
    import graph_slam.commands.compare as command

    rrd = tmp_path / "recording.rrd"
    rrd.write_bytes(b"RRF2")
    exe = tmp_path / "rerun"
    exe.write_text("#!/bin/sh\n")
    calls = []
    monkeypatch.setenv("DISPLAY", ":0")
    monkeypatch.setattr(command.shutil, "which", lambda name: str(exe))
    monkeypatch.setattr(command.subprocess, "Popen", lambda *a, **k: calls.append((a, k)))
    with pytest.raises(SystemExit) as exc:
        main(["view", str(rrd)])
    assert exc.value.code == 0
    assert calls == [(([str(exe), str(rrd)],), {"start_new_session": True})]
    assert f"opened {rrd}" in capsys.readouterr().out

    # A display but no rerun executable: how to open it, exit 0, nothing started.
    calls.clear()
    monkeypatch.setattr(command.shutil, "which", lambda name: None)
    monkeypatch.setattr(command.sys, "executable", str(tmp_path / "bin" / "python"))
    with pytest.raises(SystemExit) as exc:
        main(["view", str(tmp_path)])
    assert exc.value.code == 0 and calls == []
    out = capsys.readouterr().out
    assert "no rerun executable" in out and f"rerun {rrd}" in out


def test_compare_errors_exit_2(tmp_path: Path, capsys) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["compare", str(tmp_path / "nope"), "--out", str(tmp_path / "r")])
    assert exc.value.code == 2
    assert capsys.readouterr().err.startswith("error: ")
    with pytest.raises(SystemExit) as exc:
        main(["compare", str(tmp_path), "--out", str(tmp_path / "r"), "--variants", "icp,slam"])
    assert exc.value.code == 2
    assert "slam" in capsys.readouterr().err


def test_compare_without_ground_truth_runs_and_skips_scoring(tiny_session: Path, tmp_path) -> None:
    """A recording without ground truth still gets its trajectories and maps; the tables
    leave it out and the report says so (before: AttributeError in the speed label)."""
    import shutil

    import yaml

    from graph_slam.report import CompareConfig, compare

    copy = tmp_path / "no_gt"
    shutil.copytree(tiny_session, copy)
    manifest = yaml.safe_load((copy / "session.yaml").read_text())
    manifest["files"]["ground_truth"] = None
    manifest["files"]["ground_truth_hf"] = None
    (copy / "session.yaml").write_text(yaml.safe_dump(manifest))
    cfg = CompareConfig.model_validate({**FAST_CONFIG, "rrd": False})
    report = compare([copy], tmp_path / "report", cfg)
    assert report.unscored == report.sessions and len(report.sessions) == 1
    assert all(not v.strides for v in report.variants.values())
    names = {p.name for p in report.files}
    assert "icp_online.tum" in names and "imu_kin_smoothed.tum" in names
    assert "ground_truth.tum" not in names
    md = (tmp_path / "report" / "report.md").read_text()
    assert f"Not scored (no ground truth): {report.sessions[0]}" in md


def test_variants_strides_are_matched_by_their_frames_not_their_number() -> None:
    """Regression: the graph numbers the part before the first foot strike as stride 0, the
    baseline does not; a report that matched strides by number scored the graph's map of one
    stride against the boxes of the next (Table 4.1 widths of 428 mm for a 265 mm box)."""
    from types import SimpleNamespace

    from graph_slam.report.scoring import SessionRun
    from graph_slam.strides.reference import StrideReference
    from graph_slam.variants import Variant

    def results(cuts):
        return SimpleNamespace(
            strides=[SimpleNamespace(index=i, frame_indices=list(c)) for i, c in enumerate(cuts)]
        )

    baseline = results([range(22, 60), range(60, 95)])
    graph = results([range(0, 22), range(22, 60), range(60, 95)])
    ref = StrideReference(1, np.arange(60, 95), np.zeros(35), np.eye(4), np.zeros((35, 4, 4)),
                          0.0, 1.0, None)  # fmt: skip
    run = SessionRun(SimpleNamespace(path="mem"), "Slow",
                     {Variant.ICP: baseline, Variant.ICP_IMU_KIN: graph}, [ref], 0)  # fmt: skip
    run.check_same_strides()
    assert run.stride_of(Variant.ICP, ref).index == 1
    assert run.stride_of(Variant.ICP_IMU_KIN, ref).index == 2


def test_compare_refuses_settings_without_the_maps_it_scores() -> None:
    from graph_slam.errors import ConfigError
    from graph_slam.report import CompareConfig

    with pytest.raises(ConfigError, match=r"pipeline\.terrain\.enabled"):
        CompareConfig(pipeline={"terrain": {"enabled": False}})
    with pytest.raises(ConfigError, match=r"pipeline\.terrain\.poses.*add 'smoothed'"):
        CompareConfig(pipeline={"terrain": {"poses": ["online"]}})
    assert CompareConfig(pipeline={"terrain": {"poses": ["smoothed"]}}).truth_map

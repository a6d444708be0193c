"""run: every variant on a recording without ground truth writes every promised artefact."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml

# Coarse, fast settings (as tests/test_compare.py): the baseline with one ICP level and the cheap
# graph variant (both pipeline kinds, online and smoothed), coarse map clouds.
FAST = {
    "variants": ["icp", "imu+kin"],
    "pipeline": {
        "preset": "accurate",  # stride maps and elevation grids from kept clouds (checked below)
        "baseline": {
            "registration": {
                "levels": [{"voxel_m": 0.04, "max_correspondence_m": 0.04, "max_iterations": 15}]
            }
        },
        "terrain": {"pixel_step": 2},
    },
    "rrd_frame_step": 10,
    "kitti": True,
}


@pytest.fixture(scope="module")
def no_truth_session(tmp_path_factory) -> Path:
    """One simulated stride at 212x120 with its ground truth removed from the manifest."""
    from graph_slam.sim import SimConfig, simulate

    base = tmp_path_factory.mktemp("run_sim")
    path = simulate(
        SimConfig(strides=1, fast=True, drops="bursty", seed=3, quicklook=False), base / "sim"
    ).path
    copy = base / "walk"
    shutil.copytree(path, copy)
    manifest = yaml.safe_load((copy / "session.yaml").read_text())
    manifest["files"]["ground_truth"] = None
    manifest["files"]["ground_truth_hf"] = None
    (copy / "session.yaml").write_text(yaml.safe_dump(manifest))
    return copy


@pytest.fixture(scope="module")
def ran(no_truth_session: Path, tmp_path_factory):
    """The library call, keeping the pipelines' results to check the files against."""
    import importlib

    from graph_slam.report import RunConfig, run

    run_module = importlib.import_module("graph_slam.report.run")  # the function shadows it

    kept = {}
    original = run_module.run_variants

    def keep(session, *args):
        kept.update(original(session, *args))
        return kept

    run_module.run_variants = keep
    try:
        out = tmp_path_factory.mktemp("run") / "out"
        report = run([no_truth_session], out, RunConfig.model_validate(FAST))
    finally:
        run_module.run_variants = original
    return report, kept


def test_run_writes_every_artefact_without_ground_truth(ran) -> None:
    report, _ = ran
    out = report.out
    for name in ("report.md", "run.json", "config.yaml", "recording.rrd", ".graph-slam-output"):
        assert (out / name).is_file(), name
    assert all(f.is_file() for f in report.files)
    for tag in ("icp", "imu_kin"):
        folder = out / report.sessions[0] / tag
        for name in ("online.tum", "smoothed.tum", "online_world.tum", "smoothed_world.tum",
                     "online.kitti", "smoothed.kitti.times.txt", "frames.csv", "timing.csv"):  # fmt: skip
            assert (folder / name).is_file() and (folder / name).stat().st_size > 0, (tag, name)
        assert list((folder / "maps").glob("s*_*.ply")), tag
        assert list((folder / "maps").glob("s*_*_elevation.csv")), tag
        assert list((folder / "maps").glob("s*_*_terrain.json")), tag
    # the graph has both maps, the baseline one (its smoothed poses are its online ones)
    assert list((out / report.sessions[0] / "imu_kin" / "maps").glob("s*_smoothed.ply"))
    assert not list((out / report.sessions[0] / "icp" / "maps").glob("s*_smoothed*"))
    assert yaml.safe_load((out / "config.yaml").read_text())["variants"] == ["icp", "imu+kin"]


def test_report_names_the_counts(ran) -> None:
    report, results = ran
    doc = json.loads((report.out / "run.json").read_text())
    assert doc == json.loads(json.dumps(report.summary))
    sess = doc["sessions"][report.sessions[0]]
    assert sess["ground_truth"] is False and doc["reference"] == "imu+kin"
    md = (report.out / "report.md").read_text()
    assert doc["preset"] == "accurate" and "Preset: accurate." in md  # the preset it ran
    for variant, res in results.items():
        v = sess["variants"][str(variant)]
        assert v["frames"] == len(res.frames)
        in_strides = sum(s["frames"] for s in v["strides"])
        assert in_strides + v["frames_outside_strides"] == len(res.frames)
        assert in_strides > 10
        n_reg = sum(s["registered"] for s in v["strides"])
        n_bridged = sum(s["bridged"] for s in v["strides"])
        # the baseline registers; imu+kin has no ICP: every frame after a stride's first bridged
        assert n_reg > 10 if variant.is_baseline else (n_reg == 0 and n_bridged > 10)
        assert v["timing"]["total"]["n"] == len(res.frames)
        row = f"| {variant} | {len(v['strides'])} | {len(res.frames)} | {n_reg} |"
        assert row in md
    agree = sess["agreement"]["icp"]  # the strides both cut at the same frames
    assert len(agree) >= 1 and list(sess["agreement"]) == ["icp"]
    full = max(agree, key=lambda r: r["online_frames"])
    # the baseline's frame restarts at its own reset: compared after a rigid fit, the two
    # agree to centimetres on the simulated stride, not to metres (a wrong frame convention)
    assert full["aligned"] and full["online_frames"] > 10
    assert 0 < full["online_position_rms_mm"] < 50
    assert full["elevation"]["cells"] > 50
    assert full["elevation"]["median_mm"] <= full["elevation"]["p95_mm"]
    assert f"## Session {report.sessions[0]}" in md and "### Agreement" in md
    assert "| icp (rigidly aligned) |" in md
    assert "Where the baseline stopped" in md


def test_grids_and_obstacles_match_the_results(ran) -> None:
    from graph_slam.report.artefacts import read_elevation_csv, read_terrain_json
    from graph_slam.session.adapters.ply import read_ply
    from graph_slam.variants import Variant

    report, results = ran
    res = results[Variant("imu+kin")]
    checked = 0
    for stride in res.strides:
        if stride.terrain is None or stride.terrain.smoothed is None:
            continue
        smap = stride.terrain.smoothed
        base = (
            report.out / report.sessions[0] / "imu_kin" / "maps" / f"s{stride.index:02d}_smoothed"
        )
        doc = read_terrain_json(Path(f"{base}_terrain.json"))
        assert doc["grid"]["shape"] == list(smap.elevation.shape)
        height, _ = read_elevation_csv(Path(f"{base}_elevation.csv"), tuple(doc["grid"]["shape"]))
        np.testing.assert_array_equal(np.isnan(height), np.isnan(smap.elevation.height_m))
        np.testing.assert_allclose(height, smap.elevation.height_m, atol=1e-6, equal_nan=True)
        n_obs = 0 if smap.obstacles is None else len(smap.obstacles.obstacles)
        assert len(doc["obstacles"]) == n_obs
        cloud = read_ply(base.with_suffix(".ply"))
        assert b"property float x" in base.with_suffix(".ply").read_bytes()[:300]  # float32
        np.testing.assert_allclose(cloud.points_m, smap.fused.points_m, atol=1e-5)
        checked += 1
    assert checked >= 1


def test_trajectories_are_at_frame_times_and_kitti_has_12_numbers(ran) -> None:
    from graph_slam.report.artefacts import read_kitti
    from graph_slam.session.io import read_tum
    from graph_slam.variants import Variant

    report, results = ran
    res = results[Variant("imu+kin")]
    folder = report.out / report.sessions[0] / "imu_kin"
    t_s, poses = read_tum(folder / "smoothed.tum")
    have = np.isfinite(res.smoothed_stride_T_camera).all(axis=(1, 2))
    np.testing.assert_allclose(t_s, res.t_s[have], atol=1e-6)
    np.testing.assert_allclose(poses[:, :3, 3], res.smoothed_stride_T_camera[have][:, :3, 3],
                               atol=1e-6)  # fmt: skip
    lines = (folder / "online.kitti").read_text().splitlines()
    assert lines and all(len(line.split()) == 12 for line in lines)
    kt, kposes = read_kitti(folder / "online.kitti")
    online = res.online_stride_T_camera
    keep = np.isfinite(online).all(axis=(1, 2))
    np.testing.assert_allclose(kt, res.t_s[keep], atol=1e-6)
    np.testing.assert_allclose(kposes, online[keep], atol=1e-6)
    frames = (folder / "frames.csv").read_text().splitlines()
    assert len(frames) == len(res.frames) + 1 and frames[0].startswith("frame_index,t_s,stride")


def test_plain_progress_prints_lines_when_not_a_terminal(capsys) -> None:
    """Under pytest stderr is no terminal: a plain line per update at interval 0, and the last
    step always (without a clock: every_s huge, only the first and the final step print)."""
    from graph_slam.commands._common import progress_bar

    with progress_bar("running variants", every_s=0.0) as update:
        for i in range(1, 4):
            update(i, 3)
    lines = capsys.readouterr().err.strip().splitlines()
    assert lines == [f"running variants: {i}/3 ({100 * i / 3:.0f} %), 0 s" for i in (1, 2, 3)]
    with progress_bar("rendering", every_s=1e9) as update:
        for i in range(1, 11):
            update(i, 10)
    lines = capsys.readouterr().err.strip().splitlines()
    assert [x.split(",")[0] for x in lines] == [
        "rendering: 1/10 (10 %)",
        "rendering: 10/10 (100 %)",
    ]


def test_run_cli_refuses_a_reference_not_run(
    no_truth_session: Path, tmp_path: Path, capsys
) -> None:
    from graph_slam.cli import main

    cfg = tmp_path / "run.yaml"
    cfg.write_text(yaml.safe_dump({"variants": ["icp"], "reference": "icp+imu+kin"}))
    with pytest.raises(SystemExit) as exc:
        main(["run", str(no_truth_session), "--out", str(tmp_path / "o"), "--config", str(cfg)])
    assert exc.value.code == 2
    assert "field 'reference'" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_rigid_fit_recovers_a_known_motion() -> None:
    from scipy.spatial.transform import Rotation

    from graph_slam.report.summary import rigid_fit

    rng = np.random.default_rng(5)
    src = rng.normal(size=(30, 3))
    rot = Rotation.from_rotvec([0.3, -0.2, 0.9]).as_matrix()
    t = np.array([0.5, -1.0, 2.0])
    r_fit, t_fit = rigid_fit(src, src @ rot.T + t)
    np.testing.assert_allclose(r_fit, rot, atol=1e-12)
    np.testing.assert_allclose(t_fit, t, atol=1e-12)


def test_workers_give_the_same_trajectories_and_counts(ran, no_truth_session, tmp_path) -> None:
    """Two worker processes (the baseline's task first) give what one process gave: the same
    trajectories, grids and per-stride counts (imu+kin is deterministic; the baseline's Open3D
    registration was too on this stride)."""
    from graph_slam.report import RunConfig, run

    report, _ = ran
    two = run(
        [no_truth_session], tmp_path / "two", RunConfig.model_validate({**FAST, "workers": 2})
    )
    session = report.sessions[0]
    for tag in ("icp", "imu_kin"):
        for name in ("online.tum", "smoothed.tum", "frames.csv"):
            a = (report.out / session / tag / name).read_text()
            assert a == (two.out / session / tag / name).read_text(), (tag, name)
    one_doc = json.loads((report.out / "run.json").read_text())
    two_doc = json.loads((two.out / "run.json").read_text())
    for variant in ("icp", "imu+kin"):
        strides = one_doc["sessions"][session]["variants"][variant]["strides"]
        assert strides == two_doc["sessions"][session]["variants"][variant]["strides"]


def test_features_files_hold_the_grids_features_and_clearances(ran) -> None:
    from graph_slam.terrain.features.extract import features_of_view
    from graph_slam.terrain.features.io import read_features_json
    from graph_slam.variants import Variant

    report, results = ran
    res = results[Variant("imu+kin")]
    read = measured = 0
    for stride in res.strides:
        if stride.smoothed_grid is None:
            continue
        path = (
            report.out
            / report.sessions[0]
            / "imu_kin"
            / "maps"
            / f"s{stride.index:02d}_features.json"
        )
        doc = read_features_json(path)
        want = features_of_view(stride.smoothed_grid, source="smoothed")
        assert doc["smoothed"].to_dict() == want.to_dict()
        assert doc["predicted_clearance"] is not None
        # the encoders and the smoothed poses give the swing's toe path (a level walk)
        swing = doc["swing_clearance"]
        if swing is not None and not doc["swing_clearance_skipped"]:
            assert -0.05 < swing.min_m < 0.3 and swing.edge != "unknown"
            measured += 1
        else:  # e.g. imu+kin's first anchored stride: no plane settles its up, no cell known
            assert doc["swing_clearance_skipped"]
            assert swing is None or not np.isfinite(swing.min_m)
        read += 1
    assert read >= 1 and measured >= 1

"""``graph-slam demo`` end to end on a tiny configuration, and ``graph-slam view`` without a viewer.

The demo test simulates one stride per walking speed at 212x120 (the default is 424x240), runs
the demo's four variants (the baseline with one coarse ICP level, the graph variants on the
real-time preset) and checks the report folder holds everything docs/evaluation.md promises. It
takes about a minute on two loaded cores.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from graph_slam.cli import main

pytest.importorskip("evo")

TINY = """\
pipeline:
  baseline:
    registration:
      levels:
        - {voxel_m: 0.04, max_correspondence_m: 0.04, max_iterations: 15}
rrd_frame_step: 10
"""
SPEEDS = {"slow": "0.8mps", "normal": "1.1mps", "fast": "1.4mps"}


@pytest.fixture(scope="module")
def demo_run(tmp_path_factory) -> tuple[Path, subprocess.CompletedProcess]:
    base = tmp_path_factory.mktemp("demo")
    (base / "tiny.yaml").write_text(TINY)
    out = base / "out"
    run = subprocess.run(
        [sys.executable, "-m", "graph_slam", "demo", "--out", str(out), "--strides", "1,1,1",
         "--resolution", "212x120", "--config", str(base / "tiny.yaml")],
        capture_output=True, text=True, timeout=400, check=False,
    )  # fmt: skip
    return out, run


def test_demo_writes_the_whole_report(demo_run) -> None:
    from graph_slam.evaluation import read_metrics_json
    from graph_slam.session.adapters.ply import read_ply
    from graph_slam.session.io import read_tum

    out, run = demo_run
    assert run.returncode == 0, run.stderr[-3000:]
    for title in ("Table 4.2 (online poses", "Table 4.2 (smoothed poses)", "Table 4.1"):
        assert title in run.stdout, title
    assert "demo done in" in run.stdout
    assert "sessions removed" in run.stdout
    for speed in SPEEDS:  # the inputs are removed; their README simulates them again
        assert not (out / "sessions" / speed).exists(), speed
    regenerate = (out / "sessions" / "README.md").read_text()
    assert regenerate.count("graph-slam simulate --scene thesis-boxes") == 3
    assert "--strides 1 --seed 1 --drops bursty --resolution 212x120" in regenerate

    report = out / "report"
    text = (report / "report.md").read_text()
    assert "## Table 4.2 — online poses" in text and "## Table 4.1" in text
    assert "| Object | measured | skipped: edge of map |" in text  # box counts beside 4.1

    doc = read_metrics_json(report / "metrics.json")
    assert doc["schema_version"] == 4
    graphs = ("icp+imu", "imu+kin", "icp+imu+kin")
    assert set(doc["terrain_deadlines"]) == {"icp", *graphs}
    assert set(doc["variants"]) == {"icp", *graphs, *(f"{g} smoothed" for g in graphs)}
    for name, variant in doc["variants"].items():
        assert set(variant) == {"strides", "summary", "timing", "obstacles"}, name
        assert [s["speed"] for s in variant["strides"]] == ["Slow", "Normal", "Fast"], name
        assert variant["summary"]["strides"] == 3
        assert variant["timing"]["n"] > 0
    assert set(doc["maps"]) == {"icp", *graphs, "ground truth"}
    truth_map = doc["maps"]["ground truth"]
    assert truth_map["poses"] == "ground truth" and doc["maps"]["icp"]["poses"] == "online"
    assert set(truth_map["counts"]) == {
        "measured", "skipped", "missed", "unmatched", "no_map", "by_box"
    }  # fmt: skip
    assert len(truth_map["strides"]) == 3
    boxes = [b for s in truth_map["strides"] for b in s["boxes"]]
    assert boxes and {b["status"] for b in boxes} <= {"measured", "skipped", "missed"}
    measured = [b for b in boxes if b["status"] == "measured"]
    assert measured, "the true poses' maps should measure at least one whole box"
    # The Table 4.1 statistics count exactly the measured boxes.
    n_stats = sum(dims["height"]["n"] for dims in truth_map["obstacles"].values())
    assert n_stats == len(measured) == truth_map["counts"]["measured"]
    for b in boxes:
        assert (b["reason"] is not None) == (b["status"] == "skipped"), b

    for speed_tag in SPEEDS.values():
        (folder,) = (report / "trajectories").glob(f"*{speed_tag}*")
        for name in ("ground_truth", "icp_online", "icp_imu_kin_online", "icp_imu_kin_smoothed"):
            t_s, poses = read_tum(folder / f"{name}.tum")
            assert t_s.size > 5 and poses.shape == (t_s.size, 4, 4), (speed_tag, name)
    for source in ("icp_imu_kin", "ground_truth"):  # the main variant's and the truth's
        plys = sorted((report / "maps" / source).glob("*.ply"))
        assert len(plys) == 3, source
        assert len(read_ply(plys[0]).points_m) > 1000, source
        assert b"property float x" in plys[0].read_bytes()[:300]  # compact: float32
    for source in ("icp", "icp_imu", "imu_kin"):  # scored (metrics.json), written on request
        assert not (report / "maps" / source).exists(), source
    plots = {p.name.split("_")[0] for p in (report / "plots").glob("*.png")}
    assert {"trajectory", "error", "map", "elevation", "obstacles"} <= plots
    import yaml

    resolved = yaml.safe_load((report / "config.yaml").read_text())
    assert resolved["pipeline"]["graph"]["registration"]["method"] == "projective"  # realtime
    assert resolved["pipeline"]["preset"] == doc["preset"] == "realtime"  # the default
    assert resolved["pipeline"]["baseline"]["pixel_step"] is None  # the 212x120 cloud
    assert "Preset: realtime." in text
    rrd = report / "recording.rrd"
    assert rrd.is_file() and rrd.stat().st_size > 10_000


def test_view_finds_the_demo_recording_without_a_display(demo_run, monkeypatch, capsys) -> None:
    out, run = demo_run
    assert run.returncode == 0, run.stderr[-3000:]
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    with pytest.raises(SystemExit) as exc:
        main(["view", str(out)])  # the demo folder: the recording is in report/
    assert exc.value.code == 0
    printed = capsys.readouterr().out
    assert "no display" in printed and f"rerun {out / 'report' / 'recording.rrd'}" in printed


def test_demo_resolution_option_is_checked(tmp_path: Path, capsys) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["demo", "--out", str(tmp_path / "d"), "--resolution", "640x480"])
    assert exc.value.code == 2
    assert "--resolution" in capsys.readouterr().err
    assert not (tmp_path / "d").exists()


def test_demo_strides_option_is_checked(tmp_path: Path, capsys) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["demo", "--out", str(tmp_path / "d"), "--strides", "1,0"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "--strides" in err and "1,0" in err
    assert not (tmp_path / "d").exists()  # checked before anything is simulated


def test_demo_course_option_is_checked(tmp_path: Path, capsys) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["demo", "--out", str(tmp_path / "d"), "--course", "hills"])
    assert exc.value.code == 2
    assert "--course" in capsys.readouterr().err
    assert not (tmp_path / "d").exists()

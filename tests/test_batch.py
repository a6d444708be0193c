"""graph-slam batch on a 2-worker local cluster: isolation, worker deaths, resume, pooling, and
the spec's bad input refused before anything starts (tiny simulated sessions, one variant)."""

from __future__ import annotations

import ast
import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

pytest.importorskip("distributed")
pytest.importorskip("evo")

from graph_slam.batch import ClusterOptions, load_spec, run_batch
from graph_slam.batch.pool import timing
from graph_slam.batch.run import STUDY_MARKER, _outcome, check_study_folder
from graph_slam.batch.spec import TEST_HOOKS_ENV
from graph_slam.batch.tasks import Task, plan_tasks
from graph_slam.errors import BatchError, ConfigError
from graph_slam.session.atomic import MARKER_NAME

ROOT = Path(__file__).resolve().parents[1]
# The cheapest scoring run: the baseline with one ICP level, coarse map clouds (test_compare).
FAST = {
    "pipeline": {
        "baseline": {
            "registration": {
                "levels": [{"voxel_m": 0.04, "max_correspondence_m": 0.04, "max_iterations": 15}]
            }
        },
        "terrain": {"pixel_step": 2},
    }
}


# Generous Dask timeouts: the cluster shares two loaded cores with other work, and a worker's
# event loop may stall for seconds while its task holds the GIL (the workers inherit these).
PATIENT_DASK = {
    "distributed.comm.timeouts.connect": "300s",
    "distributed.comm.timeouts.tcp": "300s",
    "distributed.scheduler.worker-ttl": "30 minutes",
}


def _spec(folder: Path, name: str = "spec.yaml", **fields) -> Path:
    data = {"variants": ["icp"], "config": FAST, "retries": 1, **fields}
    path = folder / name
    path.write_text(yaml.safe_dump(data))
    return path


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    """One batch: two good sessions (same content, different names), one with a corrupt PNG,
    one whose task kills its worker (the test-only switch)."""
    from graph_slam.sim import SimConfig, simulate

    base = tmp_path_factory.mktemp("batch")
    first = simulate(
        SimConfig(strides=1, fast=True, drops="bursty", seed=3, quicklook=False), base / "s" / "a"
    ).path
    for name in ("b", "bad", "crash"):
        shutil.copytree(first, base / "s" / name)
    png = sorted((base / "s" / "bad" / "depth").glob("*.png"))[5]
    png.write_bytes(png.read_bytes()[:40])
    mp = pytest.MonkeyPatch()
    mp.setenv(TEST_HOOKS_ENV, "1")
    spec = _spec(base, sessions=["s/*"], test_kill_worker=["s-crash"])
    import dask

    with dask.config.set(PATIENT_DASK):
        result = run_batch(spec, base / "out", ClusterOptions(workers=2, threads_per_worker=1))
    mp.undo()
    return base, spec, result


def test_a_failing_and_a_worker_killing_task_are_recorded_and_the_others_finish(study) -> None:
    _, _, result = study
    status = {k: s["status"] for k, s in result.states.items()}
    assert status == {
        "s-a__icp__default": "done",
        "s-b__icp__default": "done",
        "s-bad__icp__default": "failed",
        "s-crash__icp__default": "failed",
    }
    bad = result.states["s-bad__icp__default"]["error"]
    assert bad.startswith("ImageError:") and "000005.png" in bad  # the typed message
    assert "KilledWorker" in result.states["s-crash__icp__default"]["error"]
    assert not result.ok
    task_json = json.loads((result.out / "tasks" / "s-bad__icp__default" / "task.json").read_text())
    assert task_json["status"] == "failed" and task_json["hash"]
    study_json = json.loads((result.out / "study.json").read_text())
    assert study_json["counts"] == {"done": 2, "failed": 2, "not_run": 0}
    assert "## Failed tasks" in (result.out / "report.md").read_text()
    assert (result.out / "plots" / "error_by_speed.png").stat().st_size > 0


def _table_body(markdown: str, heading: str) -> list[list[str]]:
    """The rows of the first table after ``heading`` (cells, speed column dropped)."""
    lines = markdown[markdown.index(heading) :].splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith("|"))
    rows = []
    for line in lines[start + 2 :]:
        if not line.startswith("|"):
            break
        rows.append([c.strip() for c in line.strip("|").split("|")][1:])
    return rows


def test_pooled_tables_equal_the_per_session_ones_combined(study) -> None:
    _, _, result = study
    out = result.out
    pooled = json.loads((out / "study.json").read_text())["pooled"]["default"]
    per_task = [out / "tasks" / f"s-{s}__icp__default" / "report" for s in ("a", "b")]
    # Table 4.2: the per-session reports' rows (compare's own markdown), one after another.
    expected = [
        row
        for r in per_task
        for row in _table_body((r / "report.md").read_text(), "Table 4.2 — online")
    ]
    got = _table_body(pooled["table_4_2_online"], "| Walking")
    assert got == expected and len(got) == 2
    # Box counts summed, Table 4.1 over the pooled measurements (n adds up).
    metrics = [json.loads((r / "metrics.json").read_text()) for r in per_task]
    for source in ("icp", "ground truth"):
        counts = pooled["box_counts"][source]
        assert counts["measured"] == sum(m["maps"][source]["counts"]["measured"] for m in metrics)
        assert counts["missed"] == sum(m["maps"][source]["counts"]["missed"] for m in metrics)
        for box, dims in pooled["box_accuracy"][source].items():
            n = sum(m["maps"][source]["obstacles"].get(box, {}).get("width", {}).get("n", 0)
                    for m in metrics)  # fmt: skip
            assert dims["width"]["n"] == n
    rmse = [m["variants"]["icp"]["strides"][0]["trajectory"]["rmse_aligned_m"] for m in metrics]
    dist = pooled["variants"]["icp"]["rmse_aligned"]
    assert dist["n"] == 2 and dist["max_m"] == pytest.approx(max(rmse), abs=1e-12)


def test_resume_skips_finished_tasks_and_reruns_a_changed_config(study) -> None:
    base, _, first = study
    out = first.out
    done_a = out / "tasks" / "s-a__icp__default" / "task.json"
    stamp = done_a.stat().st_mtime_ns
    # Same spec without the crashing and the corrupt session: nothing to run, no cluster.
    same = _spec(base, "same.yaml", sessions=["s/a", "s/b"])
    again = run_batch(same, out)
    assert {s["this_run"] for s in again.states.values()} == {"skipped"}
    assert again.ok and again.cluster == "" and done_a.stat().st_mtime_ns == stamp
    assert (out / STUDY_MARKER).is_file()
    # A changed setting re-runs the task (new hash); the other session's task is left alone.
    changed = _spec(base, "changed.yaml", sessions=["s/a"], config={**FAST, "match_margin_m": 0.06})
    import dask

    with dask.config.set(PATIENT_DASK):
        rerun = run_batch(changed, out, ClusterOptions(workers=1))
    state = rerun.states["s-a__icp__default"]
    assert (
        state["this_run"] == "done"
        and state["hash"]
        != json.loads((out / "tasks" / "s-b__icp__default" / "task.json").read_text())["hash"]
    )
    assert json.loads(done_a.read_text())["hash"] == state["hash"]


def test_the_hash_follows_session_content_and_config(study, tmp_path) -> None:
    base, _, _ = study
    spec = _spec(base, "plan.yaml", sessions=["s/a", "s/b"])
    before = {t.id: t.hash for t in plan_tasks(load_spec(spec), tmp_path)}
    assert len(set(before.values())) == 1  # same content, same config: same inputs
    copy = tmp_path / "s" / "b"
    shutil.copytree(base / "s" / "b", copy)
    (copy / "imu.csv").write_text((copy / "imu.csv").read_text() + "\n")
    spec2 = _spec(tmp_path, "plan.yaml", sessions=[str(base / "s" / "a"), "s/b"])
    after = {t.session_key: t.hash for t in plan_tasks(load_spec(spec2), tmp_path)}
    assert after["a"] == before["s-a__icp__default"] and after["s-b"] != after["a"]


@pytest.mark.parametrize(
    ("fields", "message"),
    [
        ({"variants": ["icp", "icp+lidar"]}, "field 'variants': icp+lidar not known"),
        ({"sessions": ["nothing/*"]}, "field 'sessions.0': 'nothing/*' matches no folder"),
        ({"sessions": ["s/none"]}, "field 'sessions.0':"),
        ({"sessions": ["spec.yaml"]}, "is not a readable session folder"),
        (
            {"configurations": {"x": {"pipeline": {"no_such_key": 1}}}},
            "field 'configurations.x.pipeline.no_such_key'",
        ),
        ({"configurations": {"x": {"variants": ["icp"]}}}, "set the variants at the top level"),
        ({"test_kill_worker": ["s-a"]}, f"refused unless {TEST_HOOKS_ENV}=1"),
        ({"retries": -1}, "field 'retries'"),
    ],
)
def test_bad_spec_is_refused_before_anything_starts(study, tmp_path, fields, message) -> None:
    base, _, _ = study
    shutil.copytree(base / "s" / "a", tmp_path / "s" / "a")
    spec = _spec(tmp_path, **{"sessions": ["s/a"], **fields})
    with pytest.raises(ConfigError, match=f"spec.yaml: .*{_escape(message)}"):
        run_batch(spec, tmp_path / "out")
    assert not (tmp_path / "out").exists()


def _escape(text: str) -> str:
    import re

    return re.escape(text)


def test_cli_bad_spec_and_missing_extra_are_one_line_exit_2(tmp_path, monkeypatch, capsys) -> None:
    from graph_slam.cli import main

    spec = _spec(tmp_path, sessions=["missing/*"])
    with pytest.raises(SystemExit) as exit_:
        main(["batch", str(spec), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert exit_.value.code == 2 and "matches no folder" in err and "Traceback" not in err
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(
        importlib.util, "find_spec", lambda n, *a: None if n == "distributed" else real(n, *a)
    )
    with pytest.raises(BatchError, match=r"pip install 'graph_slam\[batch\]'"):
        run_batch(spec, tmp_path / "out")


def test_dask_is_imported_only_by_the_batch_package_and_lazily() -> None:
    offenders = []
    for path in (ROOT / "graph_slam").rglob("*.py"):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        top = {id(n) for n in tree.body}
        for node in ast.walk(tree):
            names = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module:
                names = [node.module]
            if any(n.split(".")[0] in ("dask", "distributed") for n in names):
                inside = path.is_relative_to(ROOT / "graph_slam" / "batch")
                if not inside or id(node) in top:
                    offenders.append(str(path.relative_to(ROOT)))
    assert offenders == []
    code = "import sys, graph_slam.batch, graph_slam.cli; assert 'distributed' not in sys.modules"
    subprocess.run([sys.executable, "-c", code], check=True, timeout=600)


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {
        p.relative_to(folder).as_posix(): p.read_bytes() for p in folder.rglob("*") if p.is_file()
    }


@pytest.mark.parametrize("marked", [True, False], ids=["another-command", "a-user-folder"])
def test_out_that_batch_did_not_write_is_refused_and_left_untouched(
    study, tmp_path, capsys, marked
) -> None:
    from graph_slam.cli import main

    base, _, _ = study
    out = tmp_path / "report"  # e.g. a compare report: report.md, plots/, the marker
    (out / "plots").mkdir(parents=True)
    (out / "report.md").write_text("# compare\n")
    (out / "plots" / "error.png").write_bytes(b"png")
    if marked:
        (out / MARKER_NAME).write_text("written by graph-slam\n")
    before = _snapshot(out)
    spec = _spec(tmp_path, sessions=[str(base / "s" / "a")])
    why = "another graph-slam command's output" if marked else "files graph-slam did not write"
    with pytest.raises(BatchError, match=f"{_escape(str(out))}: not a batch study folder .*{why}"):
        run_batch(spec, out)
    with pytest.raises(SystemExit) as exit_:
        main(["batch", str(spec), "--out", str(out)])
    err = capsys.readouterr().err
    assert exit_.value.code == 2 and "not a batch study folder" in err and "Traceback" not in err
    assert _snapshot(out) == before


def test_a_batch_folder_new_empty_interrupted_or_older_is_accepted(tmp_path) -> None:
    assert check_study_folder(tmp_path / "new") == tmp_path / "new"
    (tmp_path / "empty").mkdir()
    check_study_folder(tmp_path / "empty")
    interrupted = tmp_path / "interrupted"  # stopped before its first study.json
    (interrupted / "tasks").mkdir(parents=True)
    (interrupted / STUDY_MARKER).write_text("")
    (interrupted / MARKER_NAME).write_text("")
    check_study_folder(interrupted)
    older = tmp_path / "older"  # written before the marker existed
    older.mkdir()
    (older / MARKER_NAME).write_text("")
    (older / "study.json").write_text(json.dumps({"schema": "graph_slam.study"}))
    check_study_folder(older)
    (older / "study.json").write_text(json.dumps({"schema": "graph_slam.metrics"}))
    with pytest.raises(BatchError, match="not a batch study folder"):
        check_study_folder(older)


class _CancelledFuture:
    """What distributed hands back for a cancelled task: ``exception()`` raises."""

    status = "cancelled"

    def exception(self):
        from concurrent.futures import CancelledError

        raise CancelledError("graph-slam-x")


def test_a_cancelled_task_is_recorded_as_failed(tmp_path) -> None:
    task = Task("x", "s", "s", "icp", "default", {}, "h", str(tmp_path / "x"))
    state = _outcome(task, _CancelledFuture(), retries=1)
    assert state["status"] == "failed" and state["error"].startswith("cancelled:")
    assert json.loads((tmp_path / "x" / "task.json").read_text())["status"] == "failed"


def test_pooled_timing_leaves_out_tasks_without_timed_frames() -> None:
    zero = {"n": 0, "mean_s": 0.0, "max_s": 0.0, "median_s": 0.0}
    assert timing([zero, zero, None]) is None
    one = {"n": 3, "mean_s": 0.02, "max_s": 0.05, "median_s": 0.01}
    two = {"n": 1, "mean_s": 0.06, "max_s": 0.06, "median_s": 0.06}
    pooled = timing([zero, one, two])
    assert pooled["n"] == 4 and pooled["mean_s"] == pytest.approx(0.03, abs=1e-15)
    assert pooled["task_median_min_s"] == 0.01 and pooled["max_s"] == 0.06


def test_the_preset_option_is_the_configurations_default(synthetic_session, tmp_path) -> None:
    spec = _spec(
        tmp_path, "presets.yaml", sessions=[str(synthetic_session)],
        configurations={"plain": {}, "own": {"pipeline": {"preset": "thesis"}}},
    )  # fmt: skip
    default = load_spec(spec).configurations
    assert {n: c.pipeline.preset for n, c in default.items()} == {
        "plain": "realtime",
        "own": "thesis",
    }
    picked = load_spec(spec, preset="accurate").configurations
    assert {n: c.pipeline.preset for n, c in picked.items()} == {
        "plain": "accurate",
        "own": "thesis",
    }
    assert picked["plain"].pipeline.baseline.pixel_step == 1  # the preset's, every pixel
    assert picked["plain"].pipeline.terrain.enabled  # compare scores the stride maps
    with pytest.raises(ConfigError, match="--preset 'fast'"):
        load_spec(spec, preset="fast")

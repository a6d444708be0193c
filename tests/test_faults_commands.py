"""The fault matrix (docs/reliability.md), commands: options, converters and output folders
end in exit code 2 and one line ``error: <file>: <rule>``, before any work, writing nothing."""

from __future__ import annotations

import pytest
import yaml
from fault_helpers import (
    cli,
    compare_refuses,
    manifest,
    one_line_error,
    write_manifest,
)

from graph_slam.session.atomic import MARKER_NAME, marker_text


def test_compare_without_ground_truth_labels_the_speed_unknown(synthetic_session) -> None:
    from graph_slam.report.compare import SessionSpec, _speed_of
    from graph_slam.session import open_session

    data = manifest(synthetic_session)
    data["files"]["ground_truth"] = None
    data["files"]["ground_truth_hf"] = None
    write_manifest(synthetic_session, data)
    session = open_session(synthetic_session)
    assert _speed_of(SessionSpec(synthetic_session), session) == "unknown"


@pytest.mark.parametrize(
    "content",
    [b"\xff\xfe\x80\x81 not a bag", b"#ROSBAG V2.0\n\xff\xfe\x80 garbage", b""],
    ids=["not-utf8", "bad-header", "empty"],
)
def test_convert_of_a_corrupt_bag_is_one_line(tmp_path, capsys, content: bytes) -> None:
    pytest.importorskip("rosbags")
    bag = tmp_path / "walk.bag"
    bag.write_bytes(content)
    code, _, err = cli(["convert", bag, tmp_path / "s"], capsys)
    assert code == 2
    one_line_error(err, str(bag), "cannot read the bag")
    assert not (tmp_path / "s").exists()


def test_gait_events_on_a_png_is_one_line(tmp_path, capsys) -> None:
    png = tmp_path / "frame.png"
    png.write_bytes(b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR\xff\xfe")
    code, _, err = cli(["gait-events", png], capsys)
    assert code == 2
    one_line_error(err, str(png), "not a UTF-8 text CSV")


def test_gait_events_accepts_the_session_imu_header(synthetic_session, tmp_path, capsys) -> None:
    code, _, err = cli(
        ["gait-events", synthetic_session / "imu.csv", "--out", tmp_path / "e.csv"], capsys
    )
    assert code == 0, err
    assert (tmp_path / "e.csv").read_text().startswith("t_s,kind")


def test_out_that_is_a_file_is_refused_before_any_work(synthetic_session, tmp_path, capsys):
    target = tmp_path / "taken"
    target.write_text("a user's file\n")
    runs = {
        "compare": ["compare", synthetic_session, "--out", target, "--variants", "icp"],
        "simulate": ["simulate", "--out", target, "--overwrite", "--strides", "1"],
        "convert": ["convert", synthetic_session, target, "--overwrite"],
    }
    for name, argv in runs.items():
        code, _, err = cli(argv, capsys)
        assert code == 2, name
        one_line_error(err, str(target))
        assert target.read_text() == "a user's file\n", name


def test_out_below_a_file_is_refused_before_any_work(synthetic_session, tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    target = blocker / "sub"
    for argv in (
        ["compare", synthetic_session, "--out", target, "--variants", "icp"],
        ["simulate", "--out", target, "--strides", "1"],
        ["convert", synthetic_session, target],
    ):
        code, _, err = cli(argv, capsys)
        assert code == 2, argv[0]
        one_line_error(err, str(target), "is a file, not a folder")


@pytest.mark.skipif(
    not hasattr(__import__("os"), "geteuid") or __import__("os").geteuid() == 0,
    reason="root writes anywhere: permission bits cannot be tested",
)
def test_out_in_a_read_only_folder_is_refused(synthetic_session, tmp_path, capsys):
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o500)
    try:
        for argv in (
            ["compare", synthetic_session, "--out", locked / "r", "--variants", "icp"],
            ["simulate", "--out", locked / "s", "--strides", "1"],
            ["convert", synthetic_session, locked / "c"],
        ):
            code, _, err = cli(argv, capsys)
            assert code == 2, argv[0]
            one_line_error(err, "permission denied")
    finally:
        locked.chmod(0o700)


def test_config_yaml_error_is_one_line(synthetic_session, tmp_path, capsys) -> None:
    cfg = tmp_path / "c.yaml"
    cfg.write_text("variants: [icp\npipeline: {\n")
    code, _, err = cli(
        ["compare", synthetic_session, "--out", tmp_path / "r", "--config", cfg], capsys
    )
    assert code == 2
    one_line_error(err, str(cfg), "not valid YAML at line")
    assert len(err.strip().splitlines()) == 1
    assert not (tmp_path / "r").exists()


def test_compare_config_records_the_variants_that_ran(tmp_path) -> None:
    from graph_slam.config import load_config
    from graph_slam.report import CompareConfig
    from graph_slam.report.checks import write_compare_config

    cfg = CompareConfig(variants=["icp+imu+kin"])
    path = write_compare_config(cfg, tmp_path / "config.yaml")
    data = yaml.safe_load(path.read_text())
    assert "variant" not in data["pipeline"] and data["variants"] == ["icp+imu+kin"]
    assert load_config(CompareConfig, path).variants == cfg.variants


def test_simulate_refuses_an_existing_session_naming_the_flag(tmp_path, capsys) -> None:
    target = tmp_path / "s"
    target.mkdir()
    (target / "session.yaml").write_text("schema_version: 1\n")
    (target / MARKER_NAME).write_text(marker_text("simulate"))
    code, _, err = cli(["simulate", "--out", target, "--strides", "1"], capsys)
    assert code == 2
    line = one_line_error(err, str(target), "pass --overwrite")
    assert "overwrite=True" not in line


def test_compare_refuses_a_users_non_empty_folder(synthetic_session, tmp_path, capsys) -> None:
    user = tmp_path / "mine"
    user.mkdir()
    (user / "notes.txt").write_text("keep me")
    for extra in ([], ["--overwrite"]):
        code, _, err = cli(["compare", synthetic_session, "--out", user, *extra], capsys)
        assert code == 2
        one_line_error(err, str(user), "was not written by graph-slam")
    assert [p.name for p in user.iterdir()] == ["notes.txt"]


def test_demo_checks_its_folder_before_simulating(tmp_path, capsys) -> None:
    user = tmp_path / "mine"
    user.mkdir()
    (user / "notes.txt").write_text("keep me")
    code, _, err = cli(["demo", "--out", user, "--strides", "1,1,1"], capsys)
    assert code == 2
    one_line_error(err, str(user), "was not written by graph-slam")
    assert [p.name for p in user.iterdir()] == ["notes.txt"]


def test_missing_session_folder(tmp_path, capsys) -> None:
    code, _, err = cli(["compare", tmp_path / "nope", "--out", tmp_path / "r"], capsys)
    assert code == 2
    one_line_error(err, "nope", "not a session folder")
    assert not (tmp_path / "r").exists()


def test_unknown_variant_names_the_choices(synthetic_session, tmp_path, capsys) -> None:
    code, _, err = cli(
        ["compare", synthetic_session, "--out", tmp_path / "r", "--variants", "icp+gps"], capsys
    )
    assert code == 2
    one_line_error(err, "--variants", "icp+gps", "choose from")


def test_missing_evo_is_named_before_any_work(synthetic_session, tmp_path, capsys, monkeypatch):
    import sys

    for name in ("evo", "evo.core", "evo.core.metrics", "evo.core.trajectory"):
        monkeypatch.setitem(sys.modules, name, None)
    compare_refuses(synthetic_session, tmp_path, capsys, "need evo", "pip install")


def test_simulate_bad_option_values(tmp_path, capsys) -> None:
    for argv, needle in (
        (["simulate", "--out", tmp_path / "s", "--strides", "0"], "strides"),
        (["simulate", "--out", tmp_path / "s", "--speed", "warp"], "--speed 'warp'"),
        (["simulate", "--out", tmp_path / "s", "--scene", "atlantis"], "atlantis"),
    ):
        code, _, err = cli(argv, capsys)
        assert code == 2, argv
        one_line_error(err, needle)
    assert not (tmp_path / "s").exists()


def test_compare_config_file_missing(synthetic_session, tmp_path, capsys) -> None:
    cfg = tmp_path / "nope.yaml"
    code, _, err = cli(
        ["compare", synthetic_session, "--out", tmp_path / "r", "--config", cfg], capsys
    )
    assert code == 2
    one_line_error(err, str(cfg), "cannot read config file")


def test_convert_missing_source_and_overlap(synthetic_session, tmp_path, capsys) -> None:
    code, _, err = cli(["convert", tmp_path / "nothing.bag", tmp_path / "s"], capsys)
    assert code == 2
    one_line_error(err, "nothing.bag", "no such file or folder")
    code, _, err = cli(["convert", synthetic_session, synthetic_session / "inside"], capsys)
    assert code == 2
    one_line_error(err, "overlaps the source")


def test_planar_out_below_a_file(tmp_path, capsys) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("x")
    code, _, err = cli(["planar", "--out", blocker / "sub"], capsys)
    assert code == 2
    one_line_error(err, "sub", "cannot create the output folder")


# --- every float setting finite; every option value a typed error (docs/reliability.md) ----

INFINITE_SETTINGS = {
    "match_margin_m": "match_margin_m: 1e400\n",
    "pipeline.cloud.max_depth_m": "pipeline: {cloud: {max_depth_m: 1e400}}\n",
    "terrain_deadline_interval_s": "terrain_deadline_interval_s: 1e400\n",
    "pipeline.baseline.registration.levels.0.voxel_m": (
        "pipeline: {baseline: {registration: {levels: [{voxel_m: 1e400, iterations: 5}]}}}\n"
    ),
    "pipeline.backend": "pipeline: {backend: {imu_rate_hz: .nan}}\n",
}


@pytest.mark.parametrize("field", list(INFINITE_SETTINGS))
@pytest.mark.parametrize("command", ["compare", "run"])
def test_an_infinite_setting_is_a_config_error_before_any_work(
    synthetic_session, tmp_path, capsys, field, command
) -> None:
    cfg = tmp_path / "c.yaml"
    cfg.write_text(INFINITE_SETTINGS[field])
    out = tmp_path / "r"
    code, _, err = cli([command, synthetic_session, "--out", out, "--config", cfg], capsys)
    assert code == 2, err
    line = one_line_error(err, str(cfg), f"field '{field}")
    assert "Extra inputs" in line or "not a finite number" in line, line
    assert not out.exists()


def test_every_float_of_every_config_model_must_be_finite() -> None:
    """Each float field of each config model (built with its defaults) refuses inf and NaN,
    naming the field: one rule in graph_slam.config, inherited by every model."""
    import importlib
    import pkgutil
    import typing

    from pydantic import ValidationError

    import graph_slam
    from graph_slam.config import ConfigModel

    for mod in pkgutil.walk_packages(graph_slam.__path__, "graph_slam."):
        if not mod.name.endswith("__main__"):
            importlib.import_module(mod.name)
    stack, models = [ConfigModel], set()
    while stack:
        for sub in stack.pop().__subclasses__():
            models.add(sub)
            stack.append(sub)
    checked = 0
    for model in sorted(models, key=lambda m: m.__qualname__):
        try:
            defaults = model().model_dump()
        except ValidationError:
            continue  # needs values: its float fields are checked where it is nested
        for name, info in model.model_fields.items():
            if float not in (info.annotation, *typing.get_args(info.annotation)):
                continue
            for bad in (float("inf"), float("nan")):
                with pytest.raises(ValidationError) as caught:  # the rule or the field's bound
                    model.model_validate({**defaults, name: bad})
                assert caught.value.errors()[0]["loc"][0] == name, (model, name)
            checked += 1
    assert checked > 200, checked  # the configs hold hundreds of float settings


def test_a_batch_configuration_with_an_infinite_value_is_refused(
    synthetic_session, tmp_path, capsys
) -> None:
    pytest.importorskip("dask.distributed")
    spec = tmp_path / "batch.yaml"
    spec.write_text(
        yaml.safe_dump(
            {
                "sessions": [str(synthetic_session)],
                "variants": ["icp"],
                "configurations": {"wide": {"match_margin_m": "1e400"}},
            }
        )
    )
    code, _, err = cli(["batch", spec, "--out", tmp_path / "b"], capsys)
    assert code == 2
    one_line_error(err, str(spec), "configurations.wide.match_margin_m", "not a finite number")
    assert not (tmp_path / "b").exists()


@pytest.mark.parametrize(
    ("argv", "needles"),
    [
        (["run", "{s}", "--map-dtype", "float16"], ["map_dtype", "'float32' or 'float64'"]),
        (["run", "{s}", "--variants", "icp,icp"], ["--variants", "icp listed more than once"]),
        (["demo", "--strides-scale", "inf"], ["--strides-scale", "inf"]),
        (["demo", "--seed", "-1", "--strides", "1,1,1"], ["demo options", "field 'seed'"]),
        (["planar", "--seed", "-3"], ["--seed", "greater than or equal to 0"]),
        (
            ["simulate", "--export", "realsense-sdk-bag", "--clock-offset", "nan"],
            ["--clock-offset", "clock_offset_s", "not a finite number"],
        ),
        (["batch", "{spec}", "--scheduler", "notaurl"], ["--scheduler 'notaurl'", "tcp://"]),
        (["batch", "{spec}", "--memory-limit", "lots"], ["--memory-limit", "'lots'", "4GiB"]),
    ],
    ids=["map-dtype", "variants-twice", "strides-scale", "demo-seed", "planar-seed", "clock-offset",
         "scheduler", "memory-limit"],
)  # fmt: skip
def test_a_bad_option_value_is_a_typed_error(
    synthetic_session, tmp_path, capsys, argv, needles
) -> None:
    if "batch" in argv:
        pytest.importorskip("dask.distributed")
    spec = tmp_path / "batch.yaml"
    spec.write_text(yaml.safe_dump({"sessions": [str(synthetic_session)], "variants": ["icp"]}))
    out = tmp_path / "out"
    argv = [a.format(s=synthetic_session, spec=spec) for a in argv] + ["--out", out]
    code, _, err = cli(argv, capsys)
    assert code == 2, err
    one_line_error(err, *needles)
    assert not out.exists()  # no empty study folder either


@pytest.mark.parametrize("target", ["folder", "missing-parent", "the-input"])
@pytest.mark.parametrize("online", [False, True], ids=["offline", "online"])
def test_gait_events_out_that_cannot_be_written_is_one_line(
    synthetic_session, tmp_path, capsys, target, online
) -> None:
    imu = synthetic_session / "imu.csv"
    before = imu.read_bytes()
    out, rule = {
        "folder": (tmp_path, "is a folder"),
        "missing-parent": (tmp_path / "nope" / "e.csv", "does not exist"),
        "the-input": (imu, "is an input of this run"),
    }[target]
    code, _, err = cli(
        ["gait-events", imu, "--out", out, *(["--online"] if online else [])], capsys
    )
    assert code == 2
    one_line_error(err, str(out), rule)
    assert imu.read_bytes() == before


@pytest.mark.parametrize("command", ["run", "compare"])
def test_a_pipeline_variant_that_does_not_run_is_refused(
    synthetic_session, tmp_path, capsys, command
) -> None:
    cfg = tmp_path / "c.yaml"
    cfg.write_text("pipeline: {variant: icp}\n")
    out = tmp_path / "o"
    argv = [command, synthetic_session, "--out", out, "--config", cfg]
    code, _, err = cli([*argv, "--variants", "icp+imu+kin"], capsys)
    assert code == 2
    one_line_error(err, str(cfg), "field 'pipeline'", "variant icp is not among the variants")
    assert not out.exists()


@pytest.mark.parametrize(
    ("text", "needles"),
    [
        ("reference: icp\nvariants: [icp+imu]\n", ["field 'reference'", "icp is not among"]),
        ("variants: [icp, icp]\n", ["field 'variants'", "icp listed more than once"]),
    ],
    ids=["reference-not-run", "variants-twice"],
)
def test_run_config_errors_name_the_file(synthetic_session, tmp_path, capsys, text, needles):
    cfg = tmp_path / "run.yaml"
    cfg.write_text(text)
    code, _, err = cli(["run", synthetic_session, "--out", tmp_path / "o", "--config", cfg], capsys)
    assert code == 2
    one_line_error(err, str(cfg), *needles)


# --- prosthesis logs: a unit the mapping gets wrong stops the conversion --------------------

LOG_MAPPING = {
    "time": {"column": "time_ms", "unit": "ms"},
    "knee": {"column": "knee", "unit": "deg"},
    "ankle": {"column": "ankle", "unit": "deg"},
    "load": {"column": "load", "foot_strike_above_n": 50, "toe_off_below_n": 20},
}


def _controller_log(path, *, knee_scale=1.0, load_scale=1.0, time_scale=1.0, jump_at=None):
    """A 2 s walk at 100 Hz: time in ms, knee and ankle in degrees, load in newtons (750 N body
    weight), each multiplied by its ``*_scale`` (a unit mistake); ``jump_at``: the clock is
    reset (back to 0) at that row."""
    import numpy as np

    t_ms = np.arange(200) * 10.0
    if jump_at is not None:
        t_ms[jump_at:] -= t_ms[jump_at]
    s = np.sin(2 * np.pi * np.arange(200) / 100.0)
    knee, ankle, load = 30 + 30 * s, 5 * s, 750 * np.maximum(s, 0)
    rows = ["time_ms,knee,ankle,load"] + [
        f"{t * time_scale:.6f},{k * knee_scale:.6f},{a * knee_scale:.6f},{f * load_scale:.6f}"
        for t, k, a, f in zip(t_ms, knee, ankle, load, strict=True)
    ]
    path.write_text("\n".join(rows) + "\n")
    return path


@pytest.mark.parametrize(
    ("fault", "log_kwargs", "mapping", "needles"),
    [
        ("radians-as-degrees", {"knee_scale": 3.14159 / 180}, {}, ["knee.unit: rad"]),
        (
            "degrees-as-radians",
            {},
            {"knee": {"column": "knee", "unit": "rad"}},
            ["prosthesis_log.knee.unit is rad", "set prosthesis_log.knee.unit: deg"],
        ),
        ("load-in-kg", {"load_scale": 1 / 9.80665}, {}, ["in kg", "load.scale: 9.80665"]),
        ("load-in-counts", {"load_scale": 40.0}, {}, ["not in newtons", "load.scale"]),
        ("clock-reset", {"jump_at": 120}, {}, ["'time_ms' steps back by 1.19 s", "line 122"]),
    ],
    ids=lambda v: v if isinstance(v, str) else "",
)
def test_a_prosthesis_log_unit_mistake_stops_the_conversion(
    tmp_path, capsys, fault, log_kwargs, mapping, needles
) -> None:
    log = _controller_log(tmp_path / "controller.csv", **log_kwargs)
    cfg = tmp_path / "mapping.yaml"
    cfg.write_text(yaml.safe_dump({"prosthesis_log": {**LOG_MAPPING, **mapping}}))
    before = log.read_bytes()
    code, _, err = cli(["convert", log, tmp_path / "s", "--config", cfg], capsys)
    assert code == 2, err
    one_line_error(err, str(log), *needles)
    assert not (tmp_path / "s").exists() and log.read_bytes() == before


def test_a_correct_prosthesis_log_converts(tmp_path, capsys) -> None:
    log = _controller_log(tmp_path / "controller.csv")
    cfg = tmp_path / "mapping.yaml"
    cfg.write_text(yaml.safe_dump({"prosthesis_log": LOG_MAPPING}))
    code, _, err = cli(["convert", log, tmp_path / "s", "--config", cfg], capsys)
    assert code == 0, err


def test_a_log_time_unit_against_the_camera_span(tmp_path, capsys) -> None:
    """Milliseconds declared as seconds, merged into a camera recording: the spans disagree by
    1000x and ms makes them agree (before: "set the offset by hand" for a decades-long shift)."""
    from pathlib import Path

    import numpy as np

    from graph_slam.errors import ConversionError
    from graph_slam.session.adapters.log_checks import check_span

    tum = Path(__file__).parent / "data" / "tum_fr1_xyz_mini"
    log = _controller_log(tmp_path / "controller.csv", time_scale=0.1)  # 0.2 s, as the camera
    cfg = tmp_path / "mapping.yaml"
    wrong = {**LOG_MAPPING, "time": {"column": "time_ms", "unit": "s"}, "path": str(log)}
    cfg.write_text(yaml.safe_dump({"prosthesis_log": {**wrong, "time_offset_s": 1305031102.1}}))
    code, _, err = cli(["convert", tum, tmp_path / "s", "--config", cfg], capsys)
    assert code == 2, err
    one_line_error(err, str(log), "the log's time is in ms, not s", "time.unit: ms")
    assert not (tmp_path / "s").exists()
    camera = np.linspace(0.0, 20.0, 600)
    with pytest.raises(ConversionError, match="time is in us, not ms"):
        check_span(log, np.linspace(0, 20e3, 100), camera, "ms")  # microseconds as ms
    assert check_span(log, np.linspace(0, 600.0, 100), camera, "s") is None  # a longer log
    caveat = check_span(log, np.linspace(0, 2e5, 100), camera, "s")  # no unit fits
    assert caveat is not None and "check prosthesis_log.time.unit" in caveat


def test_the_pooled_report_names_the_sessions_it_could_not_score(tmp_path) -> None:
    """A session without ground truth has no scored stride: the pooled study says so and names
    it, rather than leaving it out of the tables in silence."""
    from pathlib import Path

    from graph_slam.batch.pool import pool_study
    from graph_slam.batch.spec import ResolvedSpec, SessionEntry
    from graph_slam.batch.tasks import Task
    from graph_slam.report import CompareConfig
    from graph_slam.variants import Variant

    cfg = CompareConfig(variants=["icp"])
    sessions = [SessionEntry("walk", Path("walk")), SessionEntry("street", Path("street"))]
    resolved = ResolvedSpec(
        tmp_path / "batch.yaml", None, sessions, [Variant("icp")], {"default": cfg}
    )
    tasks = [
        Task(f"{s.key}__icp__default", str(s.path), s.key, "icp", "default", {}, "h", "f")
        for s in sessions
    ]
    frames = {"recorded": 40, "registered": 40, "bridged": 0}
    scored = {
        "index": 0,
        "speed": "Normal",
        "number": 1,
        "frames": frames,
        "trajectory": {"rmse_aligned_m": 0.02},
    }
    docs = {
        tasks[0].id: {"variants": {"icp": {"strides": [scored], "timing": None}}},
        tasks[1].id: {"variants": {"icp": {"strides": [], "timing": None}}},  # no ground truth
    }
    pooled = pool_study(resolved, tasks, docs)
    assert pooled["default"]["sessions_not_scored"] == ["street"]


@pytest.mark.parametrize(
    "argv",
    [
        ["bench", "session-io", "--minutes", "nan"],
        ["bench", "session-io", "--rate-hz", "inf"],
        ["bench", "registration", "--rate-hz", "nan"],
        ["bench", "simulate", "--strides", "0"],
    ],
    ids=lambda a: "-".join(a[1:3]),
)
def test_a_bad_bench_option_is_a_typed_error(capsys, argv) -> None:
    code, _, err = cli(argv, capsys)
    assert code == 2, err
    one_line_error(err, argv[2].removeprefix("--") if argv[1] == "simulate" else argv[2])

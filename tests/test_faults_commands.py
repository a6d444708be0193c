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

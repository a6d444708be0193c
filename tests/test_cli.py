"""The CLI: instant --help without heavy imports, true rates from info, errors as one line + exit 2."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from graph_slam.cli import main


def test_cli_import_pulls_no_heavy_library() -> None:
    code = (
        "import sys, graph_slam.cli; "
        "heavy = [m for m in ('open3d', 'gtsam', 'pinocchio', 'rerun', 'matplotlib', 'scipy') if m in sys.modules]; "
        "print(','.join(heavy))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""


def test_version(capsys) -> None:
    try:
        main(["--version"])
    except SystemExit as exc:
        assert exc.code == 0
    assert capsys.readouterr().out.startswith("graph-slam 0.")


def _run(argv: list[str]) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "graph_slam", *argv],
        check=False,
        capture_output=True,
        text=True,
        timeout=120,
    )


def test_info_prints_true_rates(synthetic_session: Path) -> None:
    out = _run(["info", str(synthetic_session)])
    assert out.returncode == 0, out.stderr
    rows = {
        line.split("│")[1].strip(): line for line in out.stdout.splitlines() if line.count("│") > 5
    }
    assert "30.00" in rows["frames"] and "200.00" in rows["imu"] and "500.00" in rows["joints"]
    assert "2 complete (3 foot strikes" in out.stdout


def test_validate_ok_and_bad_session_is_one_line_exit_2(synthetic_session: Path) -> None:
    ok = _run(["validate", str(synthetic_session)])
    assert ok.returncode == 0 and ok.stdout.startswith("valid:")
    data = yaml.safe_load((synthetic_session / "session.yaml").read_text())
    data["schema_version"] = 7
    (synthetic_session / "session.yaml").write_text(yaml.safe_dump(data))
    for command in ("info", "validate"):
        bad = _run([command, str(synthetic_session)])
        assert bad.returncode == 2
        assert "Traceback" not in bad.stderr
        assert bad.stderr.splitlines()[0].startswith("error: ")
        assert "schema_version" in bad.stderr


def test_missing_folder_is_exit_2(tmp_path: Path) -> None:
    bad = _run(["info", str(tmp_path / "nope")])
    assert bad.returncode == 2
    assert (
        bad.stderr.strip()
        == f"error: {tmp_path / 'nope'}: not a session folder (no such directory)"
    )


@pytest.mark.parametrize("command", ["run", "compare", "demo"])
def test_every_pipeline_command_takes_the_shared_options(command, tmp_path: Path, capsys) -> None:
    args = [command] + ([] if command == "demo" else [str(tmp_path)])
    with pytest.raises(SystemExit) as exc:
        main([*args, "--out", str(tmp_path / "o"), "--preset", "fast"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "--preset 'fast'" in err and "realtime" in err and "accurate" in err
    assert not (tmp_path / "o").exists()  # refused before any work

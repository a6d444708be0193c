"""Shared helpers of the fault-matrix tests (tests/test_faults*.py, docs/reliability.md)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml

from graph_slam.cli import main


def cli(argv: list[str], capsys) -> tuple[int, str, str]:
    """Run the CLI in-process: (exit code, stdout, stderr)."""
    try:
        main([str(a) for a in argv])
        code = 0
    except SystemExit as exc:
        code = int(exc.code or 0)
    out = capsys.readouterr()
    return code, out.out, out.err


def one_line_error(err: str, *needles: str) -> str:
    """The stderr holds exactly one line ``error: ...`` (and no traceback) naming ``needles``."""
    lines = [line for line in err.splitlines() if line.startswith("error: ")]
    assert len(lines) == 1, err
    assert "Traceback" not in err, err
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])
    return lines[0]


def manifest(session: Path) -> dict:
    return yaml.safe_load((session / "session.yaml").read_text())


def write_manifest(session: Path, data: dict) -> None:
    (session / "session.yaml").write_text(yaml.safe_dump(data, sort_keys=False))


def read_csv(path: Path) -> tuple[str, np.ndarray]:
    header, *rows = path.read_text().splitlines()
    return header, np.array([[float(x) for x in r.split(",")] for r in rows])


def write_csv(path: Path, header: str, data: np.ndarray) -> None:
    path.write_text(
        header + "\n" + "".join(",".join(repr(float(x)) for x in r) + "\n" for r in data)
    )


def compare_refuses(session: Path, tmp_path: Path, capsys, *needles: str, variants="icp"):
    out = tmp_path / "report"
    code, _, err = cli(["compare", session, "--out", out, "--variants", variants], capsys)
    assert code == 2, err
    line = one_line_error(err, *needles)
    assert not out.exists(), "compare wrote a report for a refused session"
    assert not list(tmp_path.glob(".report.partial-*"))
    return line


def validate_refuses(session: Path, capsys, *needles: str) -> None:
    code, out, err = cli(["validate", session], capsys)
    assert code == 2, out + err
    assert any(all(n in line for n in needles) for line in err.splitlines()), err


def snapshot(root: Path) -> dict[str, bytes]:
    """Every file under ``root`` (relative path -> bytes), to show that nothing changed."""
    return {p.relative_to(root).as_posix(): p.read_bytes() for p in root.rglob("*") if p.is_file()}

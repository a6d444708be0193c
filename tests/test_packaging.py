"""The installed package finds its model files; a built wheel carries them; nothing is unlisted."""

from __future__ import annotations

import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

import graph_slam_models
import pytest

REPO = Path(__file__).resolve().parents[1]


def test_installed_package_finds_model_files() -> None:
    path = graph_slam_models.model_path("sensors/synthetic.yaml")
    assert path.is_file()
    assert "camera" in path.read_text()


def test_model_path_refuses_escape_and_missing() -> None:
    with pytest.raises(ValueError, match="escapes"):
        graph_slam_models.model_path("../pyproject.toml")
    with pytest.raises(FileNotFoundError, match=r"nope\.yaml"):
        graph_slam_models.model_path("sensors/nope.yaml")


def test_every_package_on_disk_is_listed_in_pyproject() -> None:
    listed = set(
        tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"]
    )
    on_disk = set()
    for root in ("graph_slam", "kinematics"):
        for init in (REPO / root).rglob("__init__.py"):
            on_disk.add(".".join(init.parent.relative_to(REPO).parts))
    assert on_disk - listed == set(), "add these to [tool.setuptools] packages"


def test_wheel_contains_models_and_cli(tmp_path: Path) -> None:
    subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q",
         "-w", str(tmp_path), str(REPO)],
        check=True, capture_output=True, timeout=300,
    )  # fmt: skip
    (wheel,) = tmp_path.glob("graph_slam-*.whl")
    names = zipfile.ZipFile(wheel).namelist()
    models = [n for n in (REPO / "models").rglob("*") if n.is_file() and n.suffix != ".pyc"]
    for model in models:
        rel = model.relative_to(REPO / "models").as_posix()
        assert f"graph_slam_models/{rel}" in names, rel
    entry_points = next(n for n in names if n.endswith("entry_points.txt"))
    assert "graph-slam = graph_slam.cli:main" in zipfile.ZipFile(wheel).read(entry_points).decode()

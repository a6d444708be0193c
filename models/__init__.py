"""Data shipped with graph_slam: URDF, sensor profiles, scenes and gait tables.

Installed as the import package ``graph_slam_models`` (see pyproject.toml). Code finds a file
with :func:`model_path`, which refuses paths that leave this folder.
"""

from __future__ import annotations

from pathlib import Path

MODELS_DIR = Path(__file__).resolve().parent


def model_path(relative: str) -> Path:
    """Absolute path of a shipped model file, e.g. ``model_path("sensors/d455.yaml")``.

    Raises FileNotFoundError naming the file when it does not exist, and ValueError when
    ``relative`` escapes the models folder.
    """
    path = (MODELS_DIR / relative).resolve()
    if not path.is_relative_to(MODELS_DIR):
        raise ValueError(f"model path {relative!r} escapes the models folder {MODELS_DIR}")
    if not path.exists():
        raise FileNotFoundError(f"model file {relative!r} not found under {MODELS_DIR}")
    return path

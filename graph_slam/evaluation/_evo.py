"""Lazy access to evo (GPL-3, the optional ``eval`` extra): only this package imports it."""

from __future__ import annotations

from types import SimpleNamespace

from graph_slam.errors import EvaluationError


def require_evo() -> SimpleNamespace:
    """evo's ``metrics`` and ``trajectory`` modules, or a clear error naming the extra."""
    try:
        from evo.core import metrics, trajectory
    except ImportError as err:
        raise EvaluationError(
            "trajectory metrics need evo, which is not installed: "
            "pip install 'graph_slam[eval]' (evo is GPL-3, so it is an optional extra) "
            f"[{err}]"
        ) from None
    return SimpleNamespace(metrics=metrics, trajectory=trajectory)

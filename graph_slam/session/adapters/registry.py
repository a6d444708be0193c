"""The explicit registry of sources, and how a source is chosen for a path.

Every adapter implements :class:`~graph_slam.session.adapters.base.SourceAdapter`; the list
below is the whole set (no discovery, no probing). ``format: auto`` asks each adapter's
``detect()``; exactly one must claim the path.
"""

from __future__ import annotations

from pathlib import Path
from typing import get_args

from graph_slam.errors import ConversionError, MissingStreamError
from graph_slam.session.adapters.base import SourceAdapter
from graph_slam.session.adapters.config import SourceFormat
from graph_slam.session.adapters.euroc import EurocAdapter
from graph_slam.session.adapters.native import SessionAdapter, SyntheticAdapter
from graph_slam.session.adapters.prosthesis_log import ProsthesisLogAdapter
from graph_slam.session.adapters.rosbag import RosbagAdapter
from graph_slam.session.adapters.tum import TumRgbdAdapter

ADAPTERS: dict[str, SourceAdapter] = {
    adapter.name: adapter
    for adapter in (
        RosbagAdapter(),
        TumRgbdAdapter(),
        EurocAdapter(),
        ProsthesisLogAdapter(),
        SessionAdapter(),
        SyntheticAdapter(),
    )
}


def format_names() -> tuple[str, ...]:
    """The values ``ConvertConfig.format`` accepts (a test checks they match ADAPTERS)."""
    return get_args(SourceFormat)


def select_adapter(path: Path, fmt: str = "auto") -> SourceAdapter:
    """The adapter for ``path``: the one named by ``fmt``, or the single one that detects it."""
    path = Path(path)
    if fmt != "auto":
        if fmt not in ADAPTERS:
            raise ConversionError(f"unknown source format {fmt!r}; known: {sorted(ADAPTERS)}")
        return ADAPTERS[fmt]
    if not path.exists():
        raise MissingStreamError(f"{path}: no such file or folder")
    claims = [a for a in ADAPTERS.values() if a.detect(path)]
    if len(claims) == 1:
        return claims[0]
    if not claims:
        raise ConversionError(
            f"{path}: not a recognised source; give --format, one of {sorted(ADAPTERS)} "
            "(see docs/adapters.md)"
        )
    raise ConversionError(
        f"{path}: could be any of {[a.name for a in claims]}; choose one with --format"
    )

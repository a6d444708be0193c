"""Adapters: foreign recordings in (bags, TUM RGB-D, EuRoC, prosthesis logs), standard files out
(PLY maps; TUM trajectories are ``graph_slam.session.io.read_tum`` / ``write_tum``). See
docs/adapters.md.

``convert(src, dst, config)`` turns any registered source into a session folder; the sources
are the explicit :data:`ADAPTERS` registry, each a :class:`SourceAdapter`.
"""

from graph_slam.session.adapters.base import (
    ConversionReport,
    Recording,
    SourceAdapter,
    StreamReport,
)
from graph_slam.session.adapters.config import ConvertConfig
from graph_slam.session.adapters.convert import ConversionResult, convert
from graph_slam.session.adapters.ply import read_ply, write_ply
from graph_slam.session.adapters.registry import ADAPTERS, select_adapter

__all__ = [
    "ADAPTERS",
    "ConversionReport",
    "ConversionResult",
    "ConvertConfig",
    "Recording",
    "SourceAdapter",
    "StreamReport",
    "convert",
    "read_ply",
    "select_adapter",
    "write_ply",
]

"""3D views of a run: entity-path constants, a null logger (the default) and a rerun logger.

``rerun`` is imported only when a :class:`RerunLogger` is made.
"""

from graph_slam.viz.rerun_logger import (
    CAMERA,
    CLOUD,
    COLOR,
    DEPTH,
    IMAGE,
    MAP,
    OBSTACLES,
    STRIDE,
    TERRAIN_HEIGHT,
    TERRAIN_OBSTACLES,
    TERRAIN_SIGMA,
    TIMELINE_STRIDE,
    TIMELINE_TIME,
    TRAJECTORY,
    WORLD,
    Logger,
    NullLogger,
    RerunLogger,
    make_logger,
)

__all__ = [
    "CAMERA",
    "CLOUD",
    "COLOR",
    "DEPTH",
    "IMAGE",
    "MAP",
    "OBSTACLES",
    "STRIDE",
    "TERRAIN_HEIGHT",
    "TERRAIN_OBSTACLES",
    "TERRAIN_SIGMA",
    "TIMELINE_STRIDE",
    "TIMELINE_TIME",
    "TRAJECTORY",
    "WORLD",
    "Logger",
    "NullLogger",
    "RerunLogger",
    "make_logger",
]

"""Terrain maps of a stride (``maps``): fused clouds, an elevation grid, the floor and the boxes.

Inputs are plain arrays (camera-frame clouds and ``stride_T_camera`` poses), so the same
functions serve the online poses, the smoothed poses and any pipeline. The per-frame grid for
the controller is in ``grid``, the features and toe clearance in ``features``:
docs/terrain.md.
"""

from graph_slam.terrain.grid.carry import carry_map
from graph_slam.terrain.grid.online import (
    DepthNoiseModel,
    OnlineElevationMap,
    OnlineTerrainConfig,
    fuse_frames,
)
from graph_slam.terrain.grid.view import TerrainView
from graph_slam.terrain.maps.elevation import ElevationConfig, ElevationGrid, elevation_grid
from graph_slam.terrain.maps.floor import FloorPlane, ObstacleConfig, fit_floor
from graph_slam.terrain.maps.fusion import FusedMap, fuse_clouds, voxel_keys
from graph_slam.terrain.maps.obstacles import (
    SKIP_REASONS,
    Coverage,
    Obstacle,
    ObstacleMap,
    extract_obstacles,
)
from graph_slam.terrain.maps.stride_map import MappingConfig, StrideMap, build_stride_map

__all__ = [
    "SKIP_REASONS",
    "Coverage",
    "DepthNoiseModel",
    "ElevationConfig",
    "ElevationGrid",
    "FloorPlane",
    "FusedMap",
    "MappingConfig",
    "Obstacle",
    "ObstacleConfig",
    "ObstacleMap",
    "OnlineElevationMap",
    "OnlineTerrainConfig",
    "StrideMap",
    "TerrainView",
    "build_stride_map",
    "carry_map",
    "elevation_grid",
    "extract_obstacles",
    "fit_floor",
    "fuse_clouds",
    "fuse_frames",
    "voxel_keys",
]

"""The registration front end: depth → cloud → fixed-grid voxel pyramid and normals →
point-to-plane or colored ICP (frame-to-frame or frame-to-local-map) → a result with its quality
report (information matrix, degeneracy), or a typed failure; ``make_registration`` builds the
method a config names (Open3D ICP, GICP, projective) behind one interface. See
docs/frontend.md."""

from graph_slam.errors import RegistrationError, RegistrationFailure
from graph_slam.frontend.cloud import (
    Cloud,
    CloudCounts,
    Pyramid,
    build_pyramid,
    depth_to_cloud,
    estimate_normals,
    voxel_downsample,
)
from graph_slam.frontend.config import (
    CloudConfig,
    LevelConfig,
    RefineConfig,
    RegistrationConfig,
    colored_registration,
    fast_point_to_plane,
    refined_colored_registration,
    thesis_registration,
)
from graph_slam.frontend.degeneracy import DegeneracyReport
from graph_slam.frontend.local_map import LocalMap
from graph_slam.frontend.methods import PreparedFrame, Registration, make_registration
from graph_slam.frontend.registration import register
from graph_slam.frontend.result import RegistrationResult, RegistrationStatus

__all__ = [
    "Cloud",
    "CloudConfig",
    "CloudCounts",
    "DegeneracyReport",
    "LevelConfig",
    "LocalMap",
    "PreparedFrame",
    "Pyramid",
    "RefineConfig",
    "Registration",
    "RegistrationConfig",
    "RegistrationError",
    "RegistrationFailure",
    "RegistrationResult",
    "RegistrationStatus",
    "build_pyramid",
    "colored_registration",
    "depth_to_cloud",
    "estimate_normals",
    "fast_point_to_plane",
    "make_registration",
    "refined_colored_registration",
    "register",
    "thesis_registration",
    "voxel_downsample",
]

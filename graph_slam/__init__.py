"""graph_slam: per-stride factor-graph SLAM for a thigh-mounted RGB-D camera on a prosthesis."""

import logging

from graph_slam._version import __version__
from graph_slam.errors import GraphSlamError

logging.getLogger(__name__).addHandler(logging.NullHandler())

__all__ = ["GraphSlamError", "__version__"]

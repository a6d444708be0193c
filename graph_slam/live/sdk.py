"""pyrealsense2 (the optional extra ``realsense``), imported lazily with a clear error."""

from __future__ import annotations

from graph_slam.errors import MissingExtraError

INSTALL_HINT = (
    "RealSense SDK recordings and cameras need the optional extra 'realsense' (pyrealsense2): "
    "pip install 'graph_slam[realsense]'"
)


def rs_module():
    """``pyrealsense2``; :class:`MissingExtraError` naming the extra when it is missing."""
    try:
        import pyrealsense2 as rs
    except ImportError:
        raise MissingExtraError(INSTALL_HINT) from None
    return rs

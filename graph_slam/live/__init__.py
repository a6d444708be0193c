"""Live: a RealSense camera (or a recording played back in real time) and the prosthesis's
streams into the causal real-time pipeline (``graph-slam live``; docs/recording.md)."""

from graph_slam.live.camera import CameraSetup, ImuMerger, RealsenseSource
from graph_slam.live.loop import LiveRunner, write_outputs
from graph_slam.live.prosthesis import LogReplay, NoProsthesis, UdpStream
from graph_slam.live.result import LiveResult

__all__ = [
    "CameraSetup",
    "ImuMerger",
    "LiveResult",
    "LiveRunner",
    "LogReplay",
    "NoProsthesis",
    "RealsenseSource",
    "UdpStream",
    "write_outputs",
]

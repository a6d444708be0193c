"""The gait-driven simulator: scenes, walking motion, sensor models, the renderer.

``simulate(SimConfig(...), out)`` writes a session folder (docs/session_format.md) with exact
ground truth; ``graph-slam simulate`` is its command. ``export_realsense_recording`` writes the
same walk as a rig records it (a RealSense SDK bag and a prosthesis log; docs/recording.md).
See docs/simulator.md.
"""

from graph_slam.sim.config import SPEEDS_M_S, MotionConfig, SimConfig
from graph_slam.sim.export import ExportResult, RecordingExportConfig, export_realsense_recording
from graph_slam.sim.recording import SimResult, prepare, simulate

__all__ = [
    "SPEEDS_M_S",
    "ExportResult",
    "MotionConfig",
    "RecordingExportConfig",
    "SimConfig",
    "SimResult",
    "export_realsense_recording",
    "prepare",
    "simulate",
]

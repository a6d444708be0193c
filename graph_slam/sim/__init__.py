"""The gait-driven simulator: scenes, walking motion, sensor models, the renderer.

``simulate(SimConfig(...), out)`` writes a session folder (docs/session_format.md) with exact
ground truth; ``graph-slam simulate`` is its command. See docs/simulator.md.
"""

from graph_slam.sim.config import SPEEDS_M_S, MotionConfig, SimConfig
from graph_slam.sim.recording import SimResult, prepare, simulate

__all__ = ["SPEEDS_M_S", "MotionConfig", "SimConfig", "SimResult", "prepare", "simulate"]

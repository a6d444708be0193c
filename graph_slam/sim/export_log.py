"""The exported walk's prosthesis log: the controller's encoders and load cell on its own clock."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from graph_slam.sim.export_config import RecordingExportConfig
from graph_slam.sim.recording import _ENCODERS, _LOAD_CELL, Simulation
from graph_slam.sim.sensors import simulate_encoders


def load_signal(
    t_s: np.ndarray,
    strikes_s: np.ndarray,
    toe_offs_s: np.ndarray,
    export: RecordingExportConfig,
    rng: np.random.Generator,
) -> np.ndarray:
    """The load cell (N): body weight over each stance (strike → next toe-off), linear ramps
    of ``load_ramp_s`` starting at strike and ending at toe-off, plus white noise. A threshold
    of F N is crossed F / weight × ramp after the strike (50 N: 2 ms with the defaults)."""
    load = np.zeros_like(t_s)
    for strike in strikes_s:
        later = toe_offs_s[toe_offs_s > strike]
        toe_off = later[0] if later.size else t_s[-1] + 1.0
        up = np.clip((t_s - strike) / export.load_ramp_s, 0.0, 1.0)
        down = np.clip((toe_off - t_s) / export.load_ramp_s, 0.0, 1.0)
        load = np.maximum(load, export.body_weight_n * up * down)
    return load + export.load_noise_n * rng.standard_normal(t_s.size)


def write_log(path: Path, sim: Simulation, export: RecordingExportConfig) -> None:
    """The controller's CSV: log time = camera time − clock offset, in ms."""
    cfg, motion = sim.cfg, sim.motion
    joints, _ = simulate_encoders(motion, sim.prosthesis,
                                  np.random.default_rng([cfg.seed, _ENCODERS]),
                                  noise_scale=cfg.noise_scale)  # fmt: skip
    load = load_signal(joints.t_s, motion.foot_strikes_s, motion.toe_offs_s, export,
                       np.random.default_rng([cfg.seed, _LOAD_CELL]))  # fmt: skip
    t_log_ms = (joints.t_s + export.camera_epoch_s - export.clock_offset_s) * 1e3
    table = np.column_stack(
        [t_log_ms, np.rad2deg(joints.knee_rad), np.rad2deg(joints.ankle_rad), load]
    )
    np.savetxt(path, table, delimiter=",", fmt=["%.3f", "%.4f", "%.4f", "%.2f"],
               header="time_ms,knee_deg,ankle_deg,load_n", comments="")  # fmt: skip

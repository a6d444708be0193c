"""Quick-look picture of a simulated walk: side and top views of the camera path over the scene,
stride boundaries and the camera's sagittal field of view at a few frames.

Drawn by the caller after :func:`graph_slam.sim.recording.simulate` (``graph-slam simulate``
does when ``SimConfig.quicklook``): ``write_quicklook(result)``."""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np

from graph_slam.errors import SimulationError
from graph_slam.sim.recording import SimResult, Simulation

QUICKLOOK_NAME = "quicklook.png"


def write_quicklook(result: SimResult) -> Path:
    """Draw ``quicklook.png`` into the session folder a simulation wrote; the time it took is
    added to ``result.timings_s["quick-look"]``."""
    if result.simulation is None:
        raise SimulationError(
            "write_quicklook: the SimResult holds no simulation (only simulate() fills it)"
        )
    clock = time.perf_counter()
    path = quicklook(result.simulation, result.path / QUICKLOOK_NAME)
    result.timings_s["quick-look"] = time.perf_counter() - clock
    return path


def quicklook(sim: Simulation, path: Path) -> Path:
    """Side and top views of the walk in ``sim`` (the frames at their true poses)."""
    t_frames = sim.frame_times_s
    world_T_camera = sim.motion.world_T(t_frames, sim.thigh_T_camera)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Polygon, Rectangle

    motion = sim.motion
    t = np.linspace(0.0, motion.duration_s, max(200, int(motion.duration_s * 200)))
    cam = motion.world_T(t, sim.thigh_T_camera)[:, :3, 3]
    hip = motion.world_T_thigh(t)[:, :3, 3]
    x_lo, x_hi = cam[:, 0].min() - 0.5, cam[:, 0].max() + 2.0
    fig, (side, top) = plt.subplots(
        2, 1, figsize=(max(8.0, (x_hi - x_lo) * 1.1), 7.5), height_ratios=[1.3, 1.0]
    )
    truth = sim.scene.truth()
    for obj in truth.objects:
        c = obj.world_T_object[:3, 3]
        dx, dy, dz = obj.size_m
        if c[0] + dx < x_lo or c[0] - dx > x_hi:
            continue
        if obj.kind == "ramp":
            side.add_patch(
                Polygon(
                    [[c[0] - dx / 2, 0], [c[0] + dx / 2, 0], [c[0] + dx / 2, dz]],
                    color="tab:brown",
                    alpha=0.4,
                )
            )
        else:
            side.add_patch(
                Rectangle((c[0] - dx / 2, c[2] - dz / 2), dx, dz, color="tab:brown", alpha=0.4)
            )
        yaw = math.atan2(obj.world_T_object[1, 0], obj.world_T_object[0, 0])
        corners = np.array([[-dx, -dy], [dx, -dy], [dx, dy], [-dx, dy]]) / 2
        rot = np.array([[math.cos(yaw), -math.sin(yaw)], [math.sin(yaw), math.cos(yaw)]])
        top.add_patch(Polygon(corners @ rot.T + c[:2], color="tab:brown", alpha=0.4))
        top.annotate(obj.name, c[:2], fontsize=6, ha="center", va="center")
    side.axhline(0.0, color="k", lw=0.8)
    side.plot(hip[:, 0], hip[:, 2], color="0.6", lw=0.8, label="hip")
    side.plot(cam[:, 0], cam[:, 2], color="tab:blue", lw=1.2, label="camera (truth)")
    side.plot(
        world_T_camera[:, 0, 3], world_T_camera[:, 2, 3], ".", ms=2, color="tab:orange",
        label=f"frames ({t_frames.size}, {t_frames.size / motion.duration_s:.0f} Hz effective)",
    )  # fmt: skip
    strikes = motion.foot_strikes_s
    heel = motion.world_T_heel(strikes)[:, :3, 3]
    for i, x in enumerate(heel[:, 0]):
        for ax in (side, top):
            ax.axvline(x, color="tab:green", lw=0.6, ls="--")
        side.annotate(f"FS{i}", (x, 1.02), fontsize=7, color="tab:green", ha="center")
    side.plot(heel[:, 0], heel[:, 2], "^", color="tab:green", label="heel at foot strike")
    # Sagittal field of view (image x is sagittal in the portrait mount) at a few frames.
    half = math.radians(sim.camera.fov_x_deg) / 2
    portrait = abs(sim.thigh_T_camera[2, 0]) > abs(sim.thigh_T_camera[2, 1])
    if not portrait:
        half = math.radians(sim.camera.fov_y_deg) / 2
    picks = np.linspace(0, t_frames.size - 1, min(6, t_frames.size)).astype(int)
    for i in picks:
        pose = world_T_camera[i]
        o = pose[:3, 3]
        for a in (-half, 0.0, half):
            d_cam = np.array([math.tan(a), 0.0, 1.0]) if portrait else np.array([0, math.tan(a), 1])
            d = pose[:3, :3] @ d_cam
            d /= np.linalg.norm(d)
            s = -o[2] / d[2] if d[2] < -1e-3 else 2.0
            s = min(s, 2.0)
            end = o + s * d
            side.plot([o[0], end[0]], [o[2], end[2]], color="tab:red", lw=0.5 if a else 0.9)
    side.set_xlim(x_lo, x_hi)
    side.set_ylim(-0.05, 1.1)
    side.set_aspect("equal")
    side.set_ylabel("z (m)")
    side.set_title(
        f"{sim.scene.name}: {sim.cfg.strides} strides at {sim.cfg.speed_m_s} m/s "
        f"(seed {sim.cfg.seed}), {sim.camera.name}, mount pitch {sim.cfg.mount_pitch_deg}°"
    )
    side.legend(loc="upper right", fontsize=7, ncol=2)
    top.plot(cam[:, 0], cam[:, 1], color="tab:blue", lw=1.0)
    top.plot(heel[:, 0], heel[:, 1], "^", color="tab:green")
    top.set_xlim(x_lo, x_hi)
    top.set_ylim(-1.3, 1.3)
    top.set_aspect("equal")
    top.set_xlabel("x (m, walking direction)")
    top.set_ylabel("y (m)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path

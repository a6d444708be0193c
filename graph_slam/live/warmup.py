"""Before a live run starts: the leg model, and a throw-away pipeline over made-up frames so
that the first real frames do not pay for imports, compilation and first allocations."""

from __future__ import annotations

import math

import numpy as np

from graph_slam.session.records import RgbdFrame


def leg_model(mount_pitch_deg: float):
    from kinematics.leg_model import LegModel, LegParams

    return LegModel(LegParams(mount_pitch_down_rad=math.radians(mount_pitch_deg)))


#: modules the pipeline imports on a path the made-up frames do not take (the stride's anchor
#: from the nominal heel-strike pitch when the IMU's up is not known yet: 0.16 s; the model data)
_LAZY_IMPORTS: tuple[str, ...] = ("kinematics.gait_curves", "graph_slam_models")


def warm_up(pipe, setup, n: int = 6) -> None:
    """A throw-away pipeline over a few made-up frames (a textured floor 1 m ahead, moving
    1 cm per frame; every third one with colour, as a 30 Hz colour stream beside 90 Hz depth
    gives), IMU and joint samples and a foot strike (the stride's kinematic anchor), and the
    colour registration compiled for this camera pair, so that the first real frames are not
    the ones that load and compile everything; then the terrain features' and the clearance
    prediction's compiled loops (:func:`graph_slam.terrain.features.warm.warm_up`)."""
    import importlib

    for name in _LAZY_IMPORTS:
        importlib.import_module(name)
    k = setup.intrinsics
    v = np.mgrid[0 : k.height_px, 0 : k.width_px][0]
    rng = np.random.default_rng(0)
    texture = rng.integers(0, 255, (k.height_px, k.width_px, 3), dtype=np.uint8)
    register = None
    if setup.color_model is not None:
        from graph_slam.session.adapters.align_compiled import Registration

        register = Registration(setup.depth_model, setup.color_model, setup.color_T_depth)
        c = setup.color_model
        register(np.ones((k.height_px, k.width_px), np.float32),
                 np.zeros((c.height_px, c.width_px, 3), np.uint8))  # fmt: skip
    for i in range(n):
        t = 0.011 * i
        t_imu = t - 0.01 + np.arange(5) * 0.0025
        pipe.add_imu(t_imu, np.zeros((5, 3)), np.tile([0.0, -9.81, 0.0], (5, 1)))
        t_joints = t - 0.01 + np.arange(6) * 0.002  # the leg's kinematics at a foot strike
        pipe.add_joints(t_joints, np.full(6, 0.1), np.zeros(6))
        if i == 1:
            pipe.foot_strike(t - 0.005)
        depth = (1.0 + 0.2 * v / k.height_px + 0.01 * i).astype(np.float32)
        color = np.roll(texture, i, axis=1) if register is not None and i % 3 == 0 else None
        pipe.add_frame(RgbdFrame(t, depth, color, i), True)
    pipe.finish()
    from graph_slam.terrain.features.warm import warm_up as warm_up_features

    warm_up_features()  # a controller reads the features and the clearance every frame

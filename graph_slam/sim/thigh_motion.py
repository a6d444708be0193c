"""What every walking motion derives from its thigh pose: sensor frames, ideal IMU, velocity.

:class:`ThighMotion` is the base of the level walker (:class:`graph_slam.sim.motion.GaitMotion`)
and the terrain walker (:class:`graph_slam.sim.walker.TerrainMotion`): a subclass gives the
thigh's pose over time, and the poses, noise-free IMU readings and velocities of the frames
fixed to the thigh (camera, IMU) follow from it here.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from graph_slam.errors import SimulationError

GRAVITY_M_S2 = 9.81


class ThighMotion:
    """What every walking motion derives from its thigh pose: sensor frames, IMU, velocity.

    A subclass provides ``world_T_thigh(t_s)`` ((n, 4, 4), C2 in time), ``cfg`` (its
    :class:`~graph_slam.sim.config.MotionConfig`) and ``foot_strikes_s`` (the heel contacts).
    """

    def world_T_thigh(self, t_s: np.ndarray) -> np.ndarray:  # pragma: no cover - abstract
        raise NotImplementedError

    def world_T(self, t_s: np.ndarray, thigh_T_frame: np.ndarray) -> np.ndarray:
        """(n, 4, 4) pose of a thigh-fixed frame (camera, IMU) given its ``thigh_T_frame``."""
        return self.world_T_thigh(t_s) @ thigh_T_frame

    def imu_ideal(
        self, t_s: np.ndarray, thigh_T_imu: np.ndarray, h_s: float = 2e-4
    ) -> tuple[np.ndarray, np.ndarray]:
        """Noise-free gyro (rad/s) and specific force (m/s²) in the IMU frame at ``t_s``.

        Central differences of the exact pose (step ``h_s``): the motion is C2, so the error
        is O(h²) (about 1e-6 m/s² here). Plus, at each heel contact, the sensor mount's
        vibration along the thigh (:mod:`graph_slam.sim.heel_shock`, ``heel_shock_m_s2``; it
        integrates to zero velocity and displacement, so it is not in :meth:`world_T`).
        """
        t = np.atleast_1d(np.asarray(t_s, dtype=float))
        stacked = self.world_T(np.concatenate([t - h_s, t, t + h_s]), thigh_T_imu)
        before, mid, after = np.split(stacked, 3)
        rel = np.einsum("nji,njk->nik", before[:, :3, :3], after[:, :3, :3])
        gyro = Rotation.from_matrix(rel).as_rotvec() / (2.0 * h_s)
        # rotvec of R(t-h)ᵀR(t+h) is in the frame at t-h; rotate it to the frame at t.
        mid_R = mid[:, :3, :3]
        gyro = np.einsum("nji,njk,nk->ni", mid_R, before[:, :3, :3], gyro)
        acc_world = (after[:, :3, 3] - 2.0 * mid[:, :3, 3] + before[:, :3, 3]) / h_s**2
        specific = acc_world + np.array([0.0, 0.0, GRAVITY_M_S2])
        accel = np.einsum("nji,nj->ni", mid_R, specific)
        from graph_slam.sim.heel_shock import heel_shock_in_frame

        shock = heel_shock_in_frame(t, self.foot_strikes_s, self.cfg.heel_shock_m_s2, thigh_T_imu)
        return gyro, accel + shock

    def _model_time(self, t_s: np.ndarray) -> np.ndarray:
        """Session time → model time (a subclass sets ``u0`` and ``duration_s``)."""
        t = np.atleast_1d(np.asarray(t_s, dtype=float))
        if t.size and (t.min() < -1.0 or t.max() > self.duration_s + 1.0):
            raise SimulationError(
                f"time {t.min():.3f}..{t.max():.3f} s is outside the simulated walk "
                f"(0..{self.duration_s:.3f} s, ±1 s margin)"
            )
        return t + self.u0

    def velocity_world(self, t_s: np.ndarray, thigh_T_frame: np.ndarray, h_s: float = 2e-4):
        """(n, 3) world velocity of a thigh-fixed frame's origin."""
        t = np.atleast_1d(np.asarray(t_s, dtype=float))
        a = self.world_T(t + h_s, thigh_T_frame)[:, :3, 3]
        b = self.world_T(t - h_s, thigh_T_frame)[:, :3, 3]
        return (a - b) / (2.0 * h_s)

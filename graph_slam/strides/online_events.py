"""Stride events from the thigh IMU alone, causally: the event source ``imu-online``.

For a recording without load-cell events (a thigh IMU, encoders and a camera), the online gait
estimator (:class:`kinematics.gait_phase.OnlineGaitEstimator`) is run over the IMU stream one
sample at a time. Each foot strike and toe-off carries its estimated time (used to cut the
stride and set the foot-loaded state) and the time it became known (the IMU sample at which the
estimator emitted it); the pipelines announce an event only once it is known
(:meth:`graph_slam.strides.streams.StrideEvents.known_at`), so nothing reads the IMU ahead of
the frame being processed. Computing the events over the whole stream first is equivalent to
running the estimator alongside the frames: its output at a sample depends on no later sample
(tested in ``tests/test_gait_phase.py``).
"""

from __future__ import annotations

import logging

import numpy as np

from graph_slam.strides.events import StrideEvents

log = logging.getLogger(__name__)

ONLINE_SOURCE = "imu-online"


def online_stride_events(
    t_s: np.ndarray, gyro_rad_s: np.ndarray, accel_m_s2: np.ndarray, where: str = ""
) -> StrideEvents:
    """The online estimator's events over an IMU stream (camera clock), with known-at times."""
    from kinematics.gait_online import estimate_online
    from kinematics.imu import ImuSeries

    result = estimate_online(ImuSeries(t_s, gyro_rad_s, accel_m_s2, f"{where}/imu.csv"))
    by_kind = {}
    for kind in ("foot_strike", "toe_off"):
        est = result.times(kind)
        known = result.times(kind, detected=True)
        order = np.argsort(est, kind="stable")
        by_kind[kind] = (est[order], np.maximum.accumulate(known[order]) if known.size else known)
    log.info(
        "%s: %s: %d foot strikes, %d toe-offs from the thigh IMU (%s)",
        where,
        ONLINE_SOURCE,
        by_kind["foot_strike"][0].size,
        by_kind["toe_off"][0].size,
        ", ".join(f"{k} {v}" for k, v in result.counts.items()),
    )
    return StrideEvents(
        foot_strikes_s=by_kind["foot_strike"][0],
        toe_offs_s=by_kind["toe_off"][0],
        source=ONLINE_SOURCE,
        foot_strikes_known_s=by_kind["foot_strike"][1],
        toe_offs_known_s=by_kind["toe_off"][1],
    )

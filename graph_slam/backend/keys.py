"""Variable keys of the per-stride graph, made in one place.

``X(k)``: the IMU (body) pose ``stride_T_imu`` of frame ``k`` of the stride (a ``gtsam.Pose3``);
``V(k)``: the IMU's velocity in the stride frame (m/s); ``B(k)``: the IMU bias
(``gtsam.imuBias.ConstantBias``: accelerometer then gyroscope). ``k`` counts the frames of one
stride from 0; every stride has its own graph, so keys restart at each foot strike.
"""

from __future__ import annotations

from gtsam.symbol_shorthand import B, V, X

__all__ = ["B", "V", "X"]

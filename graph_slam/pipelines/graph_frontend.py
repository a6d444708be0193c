"""The graph variants' front end as the back end sees it: the registration method a config
names (:func:`imu_guess_on`: whether it wants the IMU's initial guess) and every registration,
failed or not, as the back end's :class:`IcpMeasurement` (:func:`icp_measurement`,
:func:`failed_icp_measurement`)."""

from __future__ import annotations

import numpy as np

from graph_slam.backend.measurements import IcpMeasurement
from graph_slam.errors import RegistrationError
from graph_slam.frontend import Registration, make_registration
from graph_slam.frontend.result import RegistrationResult
from graph_slam.pipelines.config import PipelineConfig
from graph_slam.pipelines.protocol import sensor_registration, with_camera_floor


def icp_measurement(result: RegistrationResult, source_index: int, target_index: int):
    """The back end's record of a front-end registration.

    The front end (``RegistrationResult``) reports its information in GTSAM's tangent space
    of ``BetweenFactor<Pose3>`` (right perturbation, source frame), as ``IcpMeasurement``
    wants, already zero along the directions the front end's degeneracy test found free;
    ``dof`` carries that test's count of constrained directions to the gate.
    """
    return IcpMeasurement(
        source_index=source_index,
        target_index=target_index,
        target_T_source=result.target_T_source,
        information=result.information,
        fitness=result.fitness,
        inlier_rmse_m=result.inlier_rmse_m,
        correspondences=result.correspondences,
        dof=result.degeneracy.dof,
    )


def failed_icp_measurement(err: RegistrationError, source_index: int, target_index: int):
    """A failed registration: recorded with its reason, never a zero-motion factor."""
    return IcpMeasurement(
        source_index=source_index,
        target_index=target_index,
        target_T_source=np.eye(4),
        information=np.zeros((6, 6)),
        fitness=float("nan") if err.fitness is None else float(err.fitness),
        inlier_rmse_m=float("nan"),
        correspondences=err.correspondences or 0,
        ok=False,
        reason=f"{err.reason.value}: {err.detail}",
    )


def _measured(register_now, source_index: int, target_index: int):
    """Run a registration and make it the back end's record (a failure keeps its reason and is
    never a zero-motion factor); returns ``(IcpMeasurement, fitness)``."""
    try:
        r = register_now()
    except RegistrationError as err:
        icp = failed_icp_measurement(err, source_index, target_index)
        return icp, icp.fitness
    return icp_measurement(r, source_index, target_index), r.fitness


def imu_guess_on(config: PipelineConfig, registration: Registration) -> bool:
    """``graph.imu_guess``; unset (None): on when the method needs a good guess (the
    projective, realtime, preset: one scale and a tight correspondence distance)."""
    if config.graph.imu_guess is not None:
        return config.graph.imu_guess
    return registration.needs_guess


def _graph_registration(config: PipelineConfig, intrinsics, has_color: bool) -> Registration:
    """The graph's registration method for frames with (or without) a colour image."""
    registration = sensor_registration(
        config.graph.registration, has_color, config.graph.depth_only
    )
    return make_registration(
        with_camera_floor(registration, config.graph.real_camera_floor),
        intrinsics,
        config.cloud,
        has_color,
    )

"""The per-stride 2D factor graph (gtsam ``Pose2``), beside the thesis's pipeline.

One graph per stride, re-solved by iSAM2 at every scan (only the new factors and values are
given to each update). Its variables are the sensor poses X(j) of the stride's scans in the
stride frame; its factors:

* a **leg-kinematic prior** on X(0) at foot strike (the reset: the map and odometry start
  again from the stance foot, as the thesis proposes in 3.3);
* an **inertial-like motion prior** between consecutive poses (always present, so the
  estimate bridges scans where registration fails);
* an **ICP factor** between consecutive poses when registration is usable: converged, with
  enough pairs, and consistent with the motion prior (a chi-square gate on the Mahalanobis
  distance). Its information is ICP's own A^T A / sigma^2, so a direction the geometry does
  not constrain (a flat floor along itself) gets no weight instead of a false zero motion.

The front end differs from the thesis's in two ways a real system can afford: max-range
returns are dropped (the scanner flags them) and ICP starts from the motion prior instead of
from zero motion.
"""

from __future__ import annotations

import numpy as np

from graph_slam.planar import se2
from graph_slam.planar.config import PlanarConfig
from graph_slam.planar.features import extract_lines
from graph_slam.planar.icp import IcpResult, register
from graph_slam.planar.measurements import GraphMeasurements
from graph_slam.planar.scanner import Scan
from graph_slam.planar.thesis import PlanarEstimate


def X(j: int) -> int:
    """Key of the j-th pose of a stride."""
    import gtsam

    return gtsam.symbol("x", j)


def icp_information(result: IcpResult, sigma_m: float) -> np.ndarray:
    """ICP's A^T A / sigma^2 moved from its left update to Pose2's right (local) coordinates."""

    adjoint = se2.to_pose2(result.target_T_source).AdjointMap()
    info = adjoint.T @ (result.information / sigma_m**2) @ adjoint
    return info + np.eye(3) * 1e-6  # keep it positive definite where the geometry is degenerate


def gate(
    result: IcpResult, measured_T: np.ndarray, motion_cov: np.ndarray, config: PlanarConfig
) -> str | None:
    """Why this registration must not enter the graph, or None if it may."""

    if result.target_T_source is None:
        return result.failure
    if not result.converged:
        return result.failure
    if result.n_pairs < config.icp.min_pairs:
        return result.failure
    info = icp_information(result, config.graph.icp_sigma_m)
    diff = se2.to_pose2(measured_T).localCoordinates(se2.to_pose2(result.target_T_source))
    chi2 = float(diff @ np.linalg.solve(motion_cov + np.linalg.inv(info), diff))
    if chi2 > config.graph.gate_chi2:
        return f"disagrees with the motion prior: chi2 {chi2:.1f} > {config.graph.gate_chi2}"
    return None


def run_graph(
    scans: list[Scan],
    stride_index: np.ndarray,
    measurements: GraphMeasurements,
    world_T_stride: np.ndarray,
    config: PlanarConfig,
) -> PlanarEstimate:
    """Estimate every scan's pose stride by stride; poses are returned in the world frame
    through the (given) stride frames, so that both methods are scored alike."""
    import gtsam

    cfg = config.graph
    motion_sigmas = np.array([cfg.motion_sigma_m, cfg.motion_sigma_m, cfg.motion_sigma_rad])
    motion_noise = gtsam.noiseModel.Diagonal.Sigmas(motion_sigmas)
    motion_cov = np.diag(motion_sigmas**2)
    motion = measurements.motion
    heading_noise = gtsam.noiseModel.Diagonal.Sigmas(
        np.array([1e3, 1e3, measurements.heading_sigma_rad])
    )  # the heading alone
    poses = np.full((len(scans), 3, 3), np.nan)
    failures: list[str | None] = [None] * len(scans)
    results: list[IcpResult | None] = [None] * len(scans)
    for stride, prior in enumerate(measurements.leg_priors):
        members = np.flatnonzero(stride_index == stride)
        isam = gtsam.ISAM2()
        graph, values = gtsam.NonlinearFactorGraph(), gtsam.Values()
        x0 = se2.to_pose2(prior.stride_T_sensor)
        graph.add(
            gtsam.PriorFactorPose2(X(0), x0, gtsam.noiseModel.Gaussian.Covariance(prior.covariance))
        )
        values.insert(X(0), x0)
        isam.update(graph, values)
        previous = isam.calculateEstimatePose2(X(0))
        poses[members[0]] = world_T_stride[stride] @ previous.matrix()
        keyframe, reference = (
            0,
            extract_lines(scans[members[0]].points_xy_m(cfg.drop_max_range), config.features),
        )
        for j, k in enumerate(members[1:], start=1):
            graph, values = gtsam.NonlinearFactorGraph(), gtsam.Values()
            graph.add(
                gtsam.BetweenFactorPose2(X(j - 1), X(j), se2.to_pose2(motion[k]), motion_noise)
            )
            graph.add(
                gtsam.PriorFactorPose2(
                    X(j), gtsam.Pose2(0.0, 0.0, measurements.heading_rad[k]), heading_noise
                )
            )
            predicted = previous.compose(se2.to_pose2(motion[k]))
            keyframe_T_predicted = isam.calculateEstimatePose2(X(keyframe)).between(predicted)
            lines = extract_lines(scans[k].points_xy_m(cfg.drop_max_range), config.features)
            result = register(
                lines.points_xy_m, reference, config.icp, keyframe_T_predicted.matrix()
            )
            results[k] = result
            failures[k] = gate(
                result, keyframe_T_predicted.matrix(), (j - keyframe) * motion_cov, config
            )
            if failures[k] is None:
                info = icp_information(result, cfg.icp_sigma_m)
                graph.add(
                    gtsam.BetweenFactorPose2(
                        X(keyframe),
                        X(j),
                        se2.to_pose2(result.target_T_source),
                        gtsam.noiseModel.Gaussian.Information(info),
                    )
                )
            values.insert(X(j), predicted)
            isam.update(graph, values)
            previous = isam.calculateEstimatePose2(X(j))
            poses[k] = world_T_stride[stride] @ previous.matrix()
            if failures[k] is not None or result.n_pairs < cfg.keyframe_overlap * len(
                reference.points_xy_m
            ):
                keyframe, reference = j, lines
    return PlanarEstimate("graph", poses, tuple(failures), tuple(results))

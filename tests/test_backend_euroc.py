"""Real IMU known answer: EuRoC V1_01_easy (first 20 s, tests/data/euroc_v101_slice, see
ATTRIBUTION.md). With the bias taken from the static start, GTSAM preintegration through
:class:`ImuBuffer` over 1 s windows started from the ground-truth state ends within ~5 cm and
a fraction of a degree of the ground truth (the data README's answer: ~4 cm, 0.14°)."""

from __future__ import annotations

from pathlib import Path

import gtsam
import numpy as np
import yaml

from graph_slam.backend.config import ImuNoiseConfig
from graph_slam.backend.imu import ImuBuffer

DATA = Path(__file__).parent / "data" / "euroc_v101_slice"


def load():
    imu = np.loadtxt(DATA / "imu0_data.csv", delimiter=",", comments="#")
    gt = np.loadtxt(DATA / "V101_gt.txt", comments="#")
    t0 = imu[0, 0] * 1e-9
    t_imu = imu[:, 0] * 1e-9 - t0
    t_gt = gt[:, 0] - t0
    poses = []
    for row in gt:
        qx, qy, qz, qw = row[4:8]
        poses.append(gtsam.Pose3(gtsam.Rot3.Quaternion(qw, qx, qy, qz), row[1:4]))
    return t_imu, imu[:, 1:4], imu[:, 4:7], t_gt, poses


def window_errors(use_bias: bool = True):
    t_imu, gyro, accel, t_gt, poses = load()
    sensor = yaml.safe_load((DATA / "imu0_sensor.yaml").read_text().replace("%YAML:1.0", ""))
    cfg = ImuNoiseConfig(
        gyro_noise_density_rad_s_sqrt_hz=sensor["gyroscope_noise_density"],
        accel_noise_density_m_s2_sqrt_hz=sensor["accelerometer_noise_density"],
        gyro_random_walk_rad_s2_sqrt_hz=sensor["gyroscope_random_walk"],
        accel_random_walk_m_s3_sqrt_hz=sensor["accelerometer_random_walk"],
    )
    buf = ImuBuffer(cfg)
    check = buf.add(t_imu, gyro, accel)
    assert check.n_rejected == 0
    # Bias from the static start (0-3.5 s): gyro mean; accel mean minus gravity in the body.
    static = t_imu < 3.5
    world_R_body = poses[0].rotation().matrix()
    g_body = world_R_body.T @ np.array([0.0, 0.0, cfg.gravity_m_s2])
    bias = gtsam.imuBias.ConstantBias(
        accel[static].mean(0) - g_body if use_bias else np.zeros(3),
        gyro[static].mean(0) if use_bias else np.zeros(3),
    )
    pos_err, rot_err = [], []
    for start in np.arange(5.0, 18.5, 1.0):
        i = int(np.argmin(np.abs(t_gt - start)))
        j = int(np.argmin(np.abs(t_gt - (t_gt[i] + 1.0))))
        v0 = (poses[i + 1].translation() - poses[i - 1].translation()) / (t_gt[i + 1] - t_gt[i - 1])
        seg = buf.integrate(t_gt[i], t_gt[j], bias)
        assert seg.ok, seg.reason
        pred = seg.pim.predict(gtsam.NavState(poses[i], v0), bias)
        pos_err.append(np.linalg.norm(pred.pose().translation() - poses[j].translation()))
        rot_err.append(
            np.linalg.norm(gtsam.Rot3.Logmap(poses[j].rotation().between(pred.pose().rotation())))
        )
    return np.array(pos_err), np.rad2deg(np.array(rot_err))


def test_preintegration_reproduces_ground_truth_over_1s_windows():
    pos, rot = window_errors()
    assert pos.size == 14
    assert np.mean(pos) < 0.05, pos
    assert np.max(pos) < 0.10, pos
    assert np.mean(rot) < 0.3, rot


def test_without_bias_correction_rotation_drifts():
    """The known answer's other half: the uncorrected gyro drifts degrees per second."""
    _, rot = window_errors(use_bias=False)
    assert np.mean(rot) > 2.0, rot


if __name__ == "__main__":  # prints the measured numbers for docs/backend.md
    for use in (True, False):
        p, r = window_errors(use)
        print(
            f"bias={use}: position mean {1e3 * p.mean():.1f} mm max {1e3 * p.max():.1f} mm; "
            f"rotation mean {r.mean():.3f} deg max {r.max():.3f} deg"
        )

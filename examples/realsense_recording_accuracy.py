"""A simulated walk recorded by librealsense as an SDK .db3, converted and run without ground
truth, then scored against the truth the export kept aside: the smoothed world trajectory's
RMSE after an SE(3) fit, the frames posed, the clock offset recovered.

    python examples/realsense_recording_accuracy.py runs/rs_acc [--strides 3]
        [--resolution 424x240] [--color-rate 30 | --color-rate all] [--share-color]

Colour is 640×480 at ``--color-rate`` Hz beside the depth at 90 Hz (with the D455's bursty
drops), accel 250 Hz and gyro 400 Hz in the IMU's own (rotated, offset) frame. The walk is
fed to the recorder as fast as it renders (its content is what is scored). Prints one line.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

import numpy as np
import yaml

from graph_slam.report.summary import rigid_fit
from graph_slam.sim import SimConfig
from graph_slam.sim.export import RecordingExportConfig, export_realsense_recording


def _tum(path: Path) -> tuple[np.ndarray, np.ndarray]:
    table = np.loadtxt(path, comments="#", ndmin=2)
    return table[:, 0], table[:, 1:4]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--strides", type=int, default=3)
    parser.add_argument("--resolution", default="424x240")
    parser.add_argument("--color-rate", default="30")
    parser.add_argument("--share-color", action="store_true")
    parser.add_argument("--seed", type=int, default=2)
    args = parser.parse_args()

    out: Path = args.out
    rec = out / "rec"
    cfg = SimConfig(strides=args.strides, resolution=args.resolution, motion_blur=False,
                    seed=args.seed, quicklook=False)  # fmt: skip
    rate = None if args.color_rate == "all" else float(args.color_rate)
    export = RecordingExportConfig(record_speed=None, color_rate_hz=rate, color_size_px=(640, 480))
    truth = export_realsense_recording(cfg, rec, export)
    conv = yaml.safe_load((rec / "convert.yaml").read_text())
    # a short walk: as many matched strikes as it has (at least 5 by default)
    conv["prosthesis_log"]["clock"] = {"min_matched_strikes": min(5, args.strides + 1)}
    if args.share_color:
        conv["association"] = {"share_color": True}
    (out / "convert.yaml").write_text(yaml.safe_dump(conv))
    (out / "run.yaml").write_text(yaml.safe_dump({"variants": ["icp+imu+kin"], "rrd": False}))
    exe = [sys.executable, "-m", "graph_slam"]
    subprocess.run([*exe, "convert", str(rec / "recording.db3"), str(out / "session"),
                    "--config", str(out / "convert.yaml")], check=True, capture_output=True)  # fmt: skip
    subprocess.run([*exe, "run", str(out / "session"), "--out", str(out / "run"),
                    "--config", str(out / "run.yaml")], check=True, capture_output=True)  # fmt: skip
    t_est, p_est = _tum(out / "run" / "recording" / "icp_imu_kin" / "smoothed_world.tum")
    t_gt, p_gt = _tum(rec / "ground_truth.tum")
    idx = np.clip(np.searchsorted(t_gt, t_est - 1e-4), 0, t_gt.size - 1)
    rot, t = rigid_fit(p_est, p_gt[idx])
    rmse = float(np.sqrt(np.mean(np.sum((p_est @ rot.T + t - p_gt[idx]) ** 2, axis=1))))
    report = yaml.safe_load((out / "session" / "conversion_report.yaml").read_text())
    offset = report["clock_offset"]["offset_s"]
    print(f"{args.strides} strides {args.resolution}, colour 640x480 at {args.color_rate} Hz"
          f"{' shared' if args.share_color else ''}: {truth.frames} depth frames, {t_est.size} "
          f"posed, smoothed world RMSE {rmse * 1e3:.1f} mm, clock offset {offset:.4f} s "
          f"(true {truth.clock_offset_s} s, error {abs(offset - truth.clock_offset_s) * 1e3:.1f} ms)")  # fmt: skip


if __name__ == "__main__":
    main()

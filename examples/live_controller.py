"""A controller's own process running the pipeline live: a RealSense camera (or a recording
played back in real time), the prosthesis's streams over UDP from the controller (or its log
replayed), and per frame what the controller reads — gait phase, the obstacle ahead, the time
left to toe-off — from :class:`graph_slam.pipelines.controller.ControllerTap`.

    graph-slam simulate --export realsense-sdk-bag --strides 3 --resolution 424x240 --out rec
    python examples/live_controller.py --playback rec/recording.db3 --config rec/convert.yaml \\
        --clock-offset 3.217
    python examples/live_controller.py --serial 123456789012 --udp 5005   # a camera, UDP

The same objects as ``graph-slam live`` (graph_slam.live): the source, the prosthesis stream,
the runner; the tap wraps the pipeline the runner makes. Ctrl-C stops.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from graph_slam.config import load_config
from graph_slam.live import LiveRunner, LogReplay, NoProsthesis, RealsenseSource, UdpStream
from graph_slam.pipelines.config import PipelineConfig, with_preset
from graph_slam.pipelines.controller import ControllerTap
from graph_slam.pipelines.runner import make_pipeline
from graph_slam.session.adapters.config import ConvertConfig


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--serial")
    parser.add_argument("--playback", type=Path)
    parser.add_argument("--config", type=Path, help="prosthesis_log and calibration (YAML)")
    parser.add_argument("--udp", type=int, help="receive the controller's datagrams here")
    parser.add_argument("--clock-offset", type=float, default=0.0)
    parser.add_argument("--mount-pitch", type=float, default=35.0)
    parser.add_argument("--seconds", type=float, default=None)
    args = parser.parse_args()

    conv = load_config(ConvertConfig, args.config)
    camera_T_imu = conv.calibration.camera_T_imu
    source = RealsenseSource(serial=args.serial, playback=args.playback,
                             camera_T_imu=None if camera_T_imu is None else np.asarray(camera_T_imu))  # fmt: skip
    if args.udp is not None:
        prosthesis = UdpStream(args.udp, offset_s=args.clock_offset, load=conv.prosthesis_log.load)
    elif conv.prosthesis_log.path:
        prosthesis = LogReplay(conv.prosthesis_log.path, conv.prosthesis_log, args.clock_offset)
    else:
        prosthesis = NoProsthesis()
    taps: list[ControllerTap] = []

    def tapped(*a):
        taps.append(ControllerTap(make_pipeline(*a)))
        return taps[-1]

    config = PipelineConfig.model_validate(with_preset({"variant": "icp+imu+kin"}, "realtime"))
    runner = LiveRunner(source, prosthesis, config, mount_pitch_deg=args.mount_pitch,
                        status=print, pipeline_factory=tapped)  # fmt: skip
    result = runner.run(max_s=args.seconds)
    for readout in taps[-1].readouts[::10]:  # every 10th frame's readout
        print(readout.line())
    print(f"{result.stop_reason}: {result.n_processed} frames, {result.skipped} skipped")


if __name__ == "__main__":
    main()

"""CPU time of registering a colour image to a depth frame: the numpy reference
(``align_color_to_depth``) against the compiled kernel the live loop uses
(``align_compiled.Registration``), on one thread (``time.thread_time``: independent of what else
the machine runs), with the check that both give the same image.

    python examples/colour_registration_timing.py                 # 424x240 depth, 636x360 colour
    python examples/colour_registration_timing.py --depth 848x480 --color 1280x720 --distortion inverse

The cameras are those of ``graph-slam simulate --export realsense-sdk-bag`` (colour 59 mm beside
the depth camera, 1.5x the depth size); ``--distortion`` gives the colour camera RealSense-like
coefficients (forward: Brown-Conrady; inverse: inverse Brown-Conrady, inverted by iteration).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from graph_slam.session.adapters.align import CameraModel, align_color_to_depth, pixel_rays
from graph_slam.session.adapters.align_compiled import Registration, warm_up

COEFFS = (-0.055, 0.065, -0.0008, 0.0006, -0.021)
MODELS = {"none": "none", "forward": "brown_conrady", "inverse": "inverse_brown_conrady"}


def _size(text: str) -> tuple[int, int]:
    w, h = text.lower().split("x")
    return int(w), int(h)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--depth", type=_size, default=(424, 240))
    ap.add_argument("--color", type=_size, default=(636, 360))
    ap.add_argument("--distortion", choices=sorted(MODELS), default="none")
    ap.add_argument(
        "--valid",
        type=float,
        default=0.5,
        help="fraction of depth pixels with a reading (the 3-stride export: 0.49)",
    )
    ap.add_argument("--repeat", type=int, default=30)
    args = ap.parse_args()
    (w, h), (cw, ch) = args.depth, args.color
    depth_cam = CameraModel(w, h, 0.527 * w, 0.902 * h, (w - 1) / 2, (h - 1) / 2)
    coeffs = COEFFS if args.distortion != "none" else ()
    color_cam = CameraModel(cw, ch, 0.5 * cw, 0.785 * ch, cw / 2 + 0.8, ch / 2 - 1.4,
                            MODELS[args.distortion], coeffs)  # fmt: skip
    pose = np.eye(4)
    pose[:3, 3] = [-0.059, 0.0003, 0.0005]
    rng = np.random.default_rng(0)
    v = np.mgrid[0:h, 0:w][0]
    depth = (0.8 + 1.5 * (1 - v / h) + rng.normal(0, 0.005, (h, w))).astype(np.float32)
    depth[rng.random((h, w)) >= args.valid] = 0.0
    color = rng.integers(0, 256, (ch, cw, 3), np.uint8)
    t0 = time.perf_counter()
    warm_up()
    reg = Registration(depth_cam, color_cam, pose)
    reg(depth, color)
    compile_s = time.perf_counter() - t0
    rays = pixel_rays(depth_cam)
    ref = align_color_to_depth(depth, color, depth_cam, color_cam, pose, rays)
    got = reg(depth, color)
    same = bool(np.array_equal(ref.color_rgb, got.color_rgb)
                and np.array_equal(ref.has_color, got.has_color))  # fmt: skip

    def cpu_ms(fn) -> float:
        c0 = time.thread_time()
        for _ in range(args.repeat):
            fn()
        return 1e3 * (time.thread_time() - c0) / args.repeat

    ref_ms = cpu_ms(lambda: align_color_to_depth(depth, color, depth_cam, color_cam, pose, rays))
    got_ms = cpu_ms(lambda: reg(depth, color))
    print(f"depth {w}x{h} ({args.valid:.0%} with a reading), colour {cw}x{ch}, distortion "
          f"{args.distortion}: reference "
          f"{ref_ms:.2f} ms, compiled {got_ms:.2f} ms CPU a frame (mean of {args.repeat}); "
          f"identical: {same}; compile or cache load {compile_s:.2f} s")  # fmt: skip


if __name__ == "__main__":
    main()

"""Draw the prosthetic leg's frames and the stride frame (docs/figures/leg_frames.png).

Left: leg straight, foot flat, with the camera-mount parameters. Right: the leg at foot
strike (reference-curve angles at 1.2 m/s), in the stride frame built from the IMU's gravity
direction, with the camera's optical axis and sagittal field of view hitting the ground.

    python examples/plot_leg_frames.py [--out docs/figures/leg_frames.png]
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from kinematics.gait_curves import joint_angles, thigh_angle
from kinematics.leg_model import LegModel
from kinematics.leg_params import LegParams
from kinematics.stride_frame import stride_T_camera

FRAMES = ("thigh", "camera_optical", "imu", "shank", "foot", "heel", "toe")
SAGITTAL_FOV_RAD = math.radians(87.0)  # depth HFOV of a D4xx camera; portrait: sagittal
XLIM, YLIM = (-0.45, 1.25), (-0.08, 1.12)


def leg_points(model: LegModel, q: np.ndarray, stride_T_heel: np.ndarray) -> dict[str, np.ndarray]:
    """4x4 poses of the leg frames in the stride frame."""
    heel_T = {f: model.frame_T_frame("heel", f, q, check_limits=False) for f in FRAMES}
    return {f: stride_T_heel @ heel_T[f] for f in FRAMES}


def draw(ax, poses: dict[str, np.ndarray], title: str, params: LegParams, annotate: bool) -> None:
    xz = {f: poses[f][[0, 2], 3] for f in poses}
    chain = ["thigh", "shank", "foot"]
    pts = np.array([xz[f] for f in chain])
    ax.plot(pts[:, 0], pts[:, 1], "-o", color="0.3", lw=6, solid_capstyle="round", zorder=1)
    sole = np.array([xz["heel"], xz["toe"], xz["foot"], xz["heel"]])
    ax.fill(sole[:, 0], sole[:, 1], color="0.75", zorder=0)
    ax.axhline(0.0, color="saddlebrown", lw=1.5)
    scale = 0.09

    def arrows(frame: str, labels: tuple[str, str], colors: tuple[str, str], lateral: str) -> None:
        origin = xz[frame]
        r = poses[frame][:3, :3]
        for axis, label, color in zip((0, 2), labels, colors, strict=True):
            d = r[[0, 2], axis]
            ax.annotate(
                "",
                origin + scale * d,
                origin,
                arrowprops={"arrowstyle": "->", "color": color, "lw": 1.8},
            )
            ax.text(
                *(origin + 1.25 * scale * d),
                label,
                color=color,
                fontsize=8,
                ha="center",
                va="center",
            )
        ax.text(origin[0] + 0.012, origin[1] - 0.025, lateral, fontsize=7, color="0.2")

    for frame, lateral in (("thigh", "y ⊙ (left)"), ("heel", "y ⊙")):
        arrows(frame, ("x", "z"), ("tab:red", "tab:blue"), lateral)
    # camera: optical frame. Portrait: image x in the sagittal plane, image y to the right.
    cam = poses["camera_optical"]
    r_cam = cam[:3, :3]
    origin = xz["camera_optical"]
    for axis, label, color in ((0, "x_img", "tab:red"), (2, "z (optical)", "tab:blue")):
        d = r_cam[[0, 2], axis]
        ax.annotate(
            "",
            origin + scale * d,
            origin,
            arrowprops={"arrowstyle": "->", "color": color, "lw": 1.8},
        )
        ax.text(*(origin + 1.3 * scale * d), label, color=color, fontsize=8)
    ax.text(origin[0] - 0.07, origin[1] + 0.03, "y_img ⊗ (right)", fontsize=7)
    # sagittal field of view down to the ground
    view = r_cam[[0, 2], 2]
    up = r_cam[[0, 2], 0]
    for k, s in enumerate((-0.5, 0.0, 0.5)):
        ang = s * SAGITTAL_FOV_RAD
        d = math.cos(ang) * view + math.sin(ang) * up
        if d[1] < -1e-3:
            lam = -origin[1] / d[1]
            end = origin + lam * d
            if end[0] > XLIM[1]:  # clip long rays at the plot edge
                end = origin + (XLIM[1] - origin[0]) / d[0] * d
            ax.plot(
                [origin[0], end[0]],
                [origin[1], end[1]],
                ls="-" if k == 1 else ":",
                color="tab:green",
                lw=1,
            )
    ax.plot(*xz["imu"], "s", color="tab:purple", ms=6)
    for f, label in (
        ("imu", "IMU"),
        ("toe", "toe"),
        ("heel", "heel = foot frame\n= stride origin"),
        ("thigh", "thigh frame (hip)"),
        ("shank", "knee"),
        ("foot", "ankle"),
    ):
        ax.text(xz[f][0] - 0.03, xz[f][1] - 0.01, label, fontsize=7, ha="right", va="top")
    if annotate:
        knee, cam_p = xz["shank"], xz["camera_optical"]
        ax.annotate(
            "",
            (knee[0] - 0.12, cam_p[1]),
            (knee[0] - 0.12, knee[1]),
            arrowprops={"arrowstyle": "<->", "color": "k"},
        )
        ax.text(
            knee[0] - 0.13,
            0.5 * (knee[1] + cam_p[1]),
            f"mount_height_\nabove_knee_m\n= {params.mount_height_above_knee_m:.2f}",
            fontsize=7,
            ha="right",
            va="center",
        )
        ax.text(
            cam_p[0] + 0.25,
            cam_p[1] - 0.07,
            f"mount_pitch_down\n= {math.degrees(params.mount_pitch_down_rad):.0f}° "
            "below horizontal",
            fontsize=7,
        )
    ax.set_title(title, fontsize=9)
    ax.set_xlim(*XLIM)
    ax.set_ylim(*YLIM)
    ax.set_aspect("equal")
    ax.set_xlabel("stride x (m, forward along the foot)")
    ax.set_ylabel("stride z (m, up)")
    ax.grid(alpha=0.3)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("docs/figures/leg_frames.png"))
    args = parser.parse_args()

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    params = LegParams()
    model = LegModel(params)
    fig, axes = plt.subplots(1, 2, figsize=(13, 6.2))

    q_flat = np.zeros(2)
    flat = stride_T_camera(model, q_flat, up_in_imu=[0.0, 0.0, 9.81], contact="foot_flat")
    draw(
        axes[0],
        leg_points(model, q_flat, flat.stride_T_foot),
        "Leg straight, foot flat (default LegParams)",
        params,
        annotate=True,
    )

    speed = 1.2
    q_ref = joint_angles(0.0, speed)
    q_strike = np.array([float(q_ref["knee"]), float(q_ref["ankle"])])
    thigh = float(thigh_angle(0.0, speed))
    # thigh flexed forward by `thigh` rad: rotation about -y (world x fwd, y left, z up)
    c, s = math.cos(thigh), math.sin(thigh)
    world_R_thigh = np.array([[c, 0.0, -s], [0.0, 1.0, 0.0], [s, 0.0, c]])
    world_R_imu = world_R_thigh @ model.thigh_T_frame("imu")[:3, :3]
    accel_imu = world_R_imu.T @ np.array([0.0, 0.0, 9.81])
    anchor = stride_T_camera(model, q_strike, up_in_imu=accel_imu, contact="heel_strike")
    draw(
        axes[1],
        leg_points(model, q_strike, anchor.stride_T_foot),
        f"Foot strike at {speed} m/s: knee {math.degrees(q_strike[0]):.0f}°, ankle "
        f"{math.degrees(q_strike[1]):.0f}°, thigh {math.degrees(thigh):.0f}° flexed,\nfoot "
        f"pitch {math.degrees(anchor.foot_pitch_rad):.0f}° toe-up (stride frame from IMU gravity)",
        params,
        annotate=False,
    )
    fig.suptitle(
        "graph_slam leg frames: thigh/shank/foot x forward, y left, z up; camera "
        "optical frame (portrait); stride frame at the heel, z against gravity",
        fontsize=10,
    )
    fig.tight_layout()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=110)
    print(f"wrote {args.out}")
    print(
        "stride_T_camera at foot strike:\n" + np.array2string(anchor.stride_T_camera, precision=3)
    )


if __name__ == "__main__":
    main()

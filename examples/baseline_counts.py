"""The thesis baseline's registered-frame counts per stride (thesis Table 4.2), stance / swing.

For every simulated session given: run the baseline (variant ``icp``) and print, per stride,
the frames registered in stance (foot loaded: load-cell strike to toe-off) and in swing, the
longest gap between frames in stance, the stop reason, and how many registered frames are
wrong: the camera's motion since the stride's first frame more than 5 cm from the ground
truth's (the thesis's rule, fitness >= 0.3, counts them as registered).
Numbers for docs/benchmarks.md ("Baseline registered-frame counts").

    graph-slam simulate --scene thesis-boxes --speed fast --strides 1 --seed 1 --drops random \\
        --fast --out /tmp/bl/fast1r
    python examples/baseline_counts.py /tmp/bl/fast1r [more sessions...]
"""

from __future__ import annotations

import argparse

import numpy as np

from graph_slam.pipelines import PipelineConfig, run_session
from graph_slam.session import open_session

WRONG_M = 0.05


def stride_counts(session, results) -> list[dict]:
    """Per stride: stance/swing registered counts, wrong registrations, longest stance gap."""
    gt = session.ground_truth
    t_gt = np.asarray(gt.t_s)
    out = []
    for s in results.strides:
        idx = np.asarray(s.frame_indices)
        t = results.t_s[idx]
        k = np.searchsorted(t_gt, t - 1e-9)
        if not np.allclose(t_gt[np.clip(k, 0, t_gt.size - 1)], t, atol=1e-6):
            raise ValueError(f"{session.path}: ground truth not at the frame times")
        world_T_camera = np.asarray(gt.parent_T_child)[k]
        loaded = np.array([results.frames[i].foot_loaded for i in idx])
        has = np.array([results.frames[i].has_pose for i in idx])
        wrong = np.zeros_like(has)
        if has[0]:
            est = results.online_stride_T_camera[idx]
            moved_est = np.linalg.inv(est[0]) @ est
            moved_true = np.linalg.inv(world_T_camera[0]) @ world_T_camera
            err = np.linalg.norm(moved_est[:, :3, 3] - moved_true[:, :3, 3], axis=1)
            wrong = has & (err > WRONG_M)
        gaps = np.diff(t[loaded]) if loaded.sum() > 1 else np.zeros(1)
        out.append(
            {
                "stride": s.index,
                "frames": int(idx.size),
                "registered": int(has.sum()),
                "stance": (int((has & loaded).sum()), int(loaded.sum())),
                "swing": (int((has & ~loaded).sum()), int((~loaded).sum())),
                "wrong": (int((wrong & loaded).sum()), int((wrong & ~loaded).sum())),
                "max_stance_gap_ms": float(1e3 * gaps.max()),
                "stop": (s.stop_reason or "").split(":")[0],
            }
        )
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("sessions", nargs="+")
    args = parser.parse_args()
    for path in args.sessions:
        session = open_session(path)
        config = PipelineConfig(preset="thesis", variant="icp")  # the cloud from every pixel
        results = run_session(session, config)
        rows = stride_counts(session, results)
        n = sum(r["frames"] for r in rows)
        reg = sum(r["registered"] for r in rows)
        print(f"{path}: {reg}/{n} registered ({100 * reg / max(n, 1):.0f} %)")
        for r in rows:
            print(
                f"  stride {r['stride']}: {r['registered']}/{r['frames']}, "
                f"stance {r['stance'][0]}/{r['stance'][1]}, swing {r['swing'][0]}/{r['swing'][1]}"
                f"; wrong (> 5 cm) {r['wrong'][0]} + {r['wrong'][1]}; longest stance gap "
                f"{r['max_stance_gap_ms']:.0f} ms; stop: {r['stop'] or '-'}"
            )


if __name__ == "__main__":
    main()

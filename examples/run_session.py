"""Run every pipeline variant on a session folder and print what each produced.

graph-slam simulate --scene thesis-boxes --strides 2 --fast --out runs/sim
python examples/run_session.py runs/sim
"""

from __future__ import annotations

import sys

from graph_slam.pipelines import VARIANTS, PipelineConfig, run_session


def main() -> None:
    for variant in VARIANTS:
        results = run_session(sys.argv[1], PipelineConfig(variant=variant))
        t = results.timings_ms()
        print(f"{variant}: {results.counts}; per frame {t['median']:.1f} ms (p95 {t['p95']:.1f})")
        for s in results.strides:
            print(
                f"  stride {s.index} ({s.start}): {s.n_registered}/{len(s.frame_indices)} "
                f"frames registered/ICP-accepted; stop: {s.stop_reason}"
            )


if __name__ == "__main__":
    main()

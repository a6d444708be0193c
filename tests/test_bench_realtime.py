"""``graph-slam bench realtime``: rows and presets, the figures of a replayed row, the
speed-ups against the thesis baseline, the JSON file."""

from __future__ import annotations

import json

import numpy as np
import pytest

from graph_slam.bench import realtime as rt
from graph_slam.errors import ConfigError
from graph_slam.pipelines import PipelineConfig


def test_rows_are_variants_or_variant_colon_preset() -> None:
    assert rt.row_config("icp").variant == "icp"
    base = PipelineConfig(max_frames=7)
    cfg = rt.row_config("icp+imu", base)
    assert cfg.variant == "icp+imu" and cfg.backend.variant == "icp+imu" and cfg.max_frames == 7
    with pytest.raises(ConfigError, match="unknown variant 'slam'"):
        rt.row_config("slam")
    # a preset sets the baseline's cloud too: every pixel (accurate), the 212x120 one (realtime)
    assert rt.row_config("icp:accurate").baseline.pixel_step == 1
    assert rt.row_config("icp:realtime").baseline.pixel_step is None
    assert rt.row_config("icp").preset == "realtime"  # the default
    with pytest.raises(ConfigError, match="row 'icp\\+imu\\+kin:nope': unknown pipeline preset"):
        rt.row_config("icp+imu+kin:nope")
    real = rt.row_config("icp+imu+kin:realtime", base)  # every real-time setting, over base
    assert real.graph.registration.method == "projective" and real.graph.imu_guess
    assert not real.backend.smoothing and not real.terrain.enabled  # iSAM2 smooths
    assert not real.terrain.online.keep_clouds and real.terrain.online.enabled
    assert real.max_frames == 7


def test_stat_in_milliseconds() -> None:
    s = rt.Stat.of(np.array([0.001, 0.002, 0.003, 0.010]))
    assert (s.median_ms, s.max_ms, s.n) == (2.5, 10.0, 4)
    assert rt.Stat.of(np.zeros(0)).n == 0


def _row(name: str, update_ms: float, hz: float) -> rt.RealtimeRow:
    stat = rt.Stat(update_ms, 2 * update_ms, 3 * update_ms, 10)
    return rt.RealtimeRow(
        session="s", row=name, pace="virtual", stages={k: stat for k, _ in rt.STAGES},
        update=stat, latency=stat, delivered=90, processed=int(hz), skipped=90 - int(hz),
        delivered_hz=90.0, achieved_hz=hz, cpu_ms_per_frame=update_ms, finish_ms=1.0,
        rss_start_mb=100.0, peak_rss_mb=200.0, rss_mb=[(0.0, 100.0), (60.0, 150.0), (90.0, 150.0)],
        strides_scored=2, online_rmse_mm=5.0, smoothed_rmse_mm=4.0, frames_without_pose=0,
        wall_s=1.0,
    )  # fmt: skip


def test_speedups_against_the_thesis_baseline(tmp_path) -> None:
    rows = [_row("icp", 400.0, 2.0), _row("icp+imu+kin", 40.0, 20.0)]
    (up,) = rt.speedups(rows)
    assert up["row"] == "icp+imu+kin"
    assert up["update_median"] == pytest.approx(10.0) and up["achieved_rate"] == 10.0
    assert "full update 10x" in rt.headline_lines(rows)[1]
    assert rt.headline_lines(rows[1:]) == ["(no 'icp' row: no speed-ups)"]
    assert any("150 MB at 1 min" in line for line in rt.row_lines(rows[0]))
    data = json.loads(rt.write_json(rows, tmp_path / "rt.json").read_text())
    assert data["rows"][1]["update"]["median_ms"] == 40.0
    assert data["speedups"][0]["update_median"] == pytest.approx(10.0)


@pytest.fixture(scope="module")
def online_session(tmp_path_factory):
    from graph_slam.sim import SimConfig, simulate

    out = tmp_path_factory.mktemp("realtime") / "sim"
    simulate(SimConfig(strides=1, seed=5, resolution="212x120", drops="none", quicklook=False), out)
    return out


def test_a_replayed_row_reports_every_figure(online_session) -> None:
    (r,) = rt.run_realtime_bench(
        [online_session], ["icp+imu+kin"], PipelineConfig(max_frames=40), isolate=False
    )
    assert r.delivered == 40 and r.processed + r.skipped == 40 and r.processed > 0
    assert r.update.n == r.processed and r.latency.median_ms >= r.update.median_ms * 0.5
    assert r.stages["graph"].n == r.processed and r.stages["registration"].n > 0
    assert 0 < r.achieved_hz <= r.delivered_hz
    assert r.peak_rss_mb >= r.rss_start_mb > 0
    assert r.machine["cpus_visible"] >= 1
    lines = rt.row_lines(r)
    assert "graph update" in "\n".join(lines) and "processed" in lines[0]


def test_rows_run_in_their_own_process(online_session) -> None:
    seen = []
    (r,) = rt.run_realtime_bench(
        [online_session],
        ["icp"],
        PipelineConfig(max_frames=5),
        on_start=lambda s, v: seen.append(v),
    )
    assert seen == ["icp"] and r.row == "icp" and r.delivered == 5


def test_markdown_table_carries_its_caption() -> None:
    import datetime
    import os

    rows = [_row("icp:accurate", 400.0, 2.0), _row("icp+imu+kin", 40.0, 20.0)]
    text = rt.markdown_table(rows, "graph-slam bench realtime s --markdown")
    caption, _, header, rule, *body = text.splitlines()
    today = datetime.datetime.now(datetime.UTC).date().isoformat()
    assert caption.startswith(f"({today}, commit ")
    assert (
        f"{len(os.sched_getaffinity(0))} cores: `graph-slam bench realtime s --markdown`" in caption
    )
    assert header.count("|") == rule.count("|") == 10
    assert body == [
        "| s | icp:accurate | 400.0 / 800.0 | 90 | 2 | 88 | 400.0 | 200 | 4.0 |",
        "| s | icp+imu+kin | 40.0 / 80.0 | 90 | 20 | 70 | 40.0 | 200 | 4.0 |",
    ]

"""What a report writes besides its numbers: TUM trajectories, PLY maps, plots, the rerun
recording. Drawing is :mod:`graph_slam.viz`'s; this module decides what to draw and where."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from graph_slam.evaluation.boxes import collect_measurements, truth_boxes_in_stride
from graph_slam.report.keys import MapSource
from graph_slam.report.terrain_trace import log_grids
from graph_slam.terrain.maps.builder import scaled_intrinsics
from graph_slam.viz.rerun_logger import MAP

__all__ = [
    "log_run",
    "make_logger",
    "write_maps_and_views",
    "write_plots",
    "write_report_md",
    "write_trajectories",
]


def make_logger(path: Path | None):
    from graph_slam.viz import make_logger as _make

    return _make(path)


def _write_tum_finite(path: Path, t_s: np.ndarray, poses: np.ndarray) -> Path:
    from graph_slam.session.io import write_tum

    keep = np.isfinite(poses).all(axis=(1, 2))
    path.parent.mkdir(parents=True, exist_ok=True)
    write_tum(path, t_s[keep], poses[keep])
    return path


def write_trajectories(folder: Path, run) -> list[Path]:
    """TUM files of ``stride_T_camera`` (each stride restarts at its foot strike) per variant,
    online and smoothed, and the ground truth in the same per-stride frames."""
    files = []
    for v, res in run.results.items():
        for kind in ("online", "smoothed"):
            path = folder / f"{v.tag}_{kind}.tum"
            files.append(_write_tum_finite(path, res.t_s, res.poses(kind)))
    if run.references:
        t = np.concatenate([r.t_s for r in run.references])
        ref = np.concatenate([r.stride_T_camera for r in run.references])
        files.append(_write_tum_finite(folder / "ground_truth.tum", t, ref))
    return files


def file_cloud(fused, voxel_m: float):
    """The fused map for its PLY file: its voxels averaged (weighted by their point counts)
    on the grid of ``voxel_m`` with the same origin (0 or the map's own voxel: as it is)."""
    import numpy as np

    from graph_slam.errors import ConfigError
    from graph_slam.session.records import Cloud

    ratio = voxel_m / fused.voxel_m if voxel_m > 0 else 1.0
    if ratio <= 1.0 + 1e-9:
        return fused.to_point_cloud()
    step = round(ratio)
    if abs(ratio - step) > 1e-6:
        raise ConfigError(
            f"field 'map_file_voxel_m': {voxel_m} m is not a whole multiple of the maps' "
            f"voxel {fused.voxel_m} m"
        )
    keys = np.floor_divide(np.asarray(fused.voxel_keys), step)
    _, cell, n_cells = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    cell = cell.reshape(-1)
    weight = np.asarray(fused.counts, float)
    total = np.bincount(cell, weight, minlength=n_cells.size)

    def mean(values: np.ndarray) -> np.ndarray:
        return np.stack(
            [
                np.bincount(cell, weight * values[:, i], minlength=total.size) / total
                for i in range(3)
            ],
            axis=1,
        )

    colors = None if fused.colors_rgb is None else mean(np.asarray(fused.colors_rgb, float) / 255.0)
    return Cloud(mean(np.asarray(fused.points_m, float)), colors)


def _map_file(cfg, source: MapSource, main: MapSource) -> bool:
    """Whether the stride map of ``source`` is written (``CompareConfig.map_files``)."""
    which = cfg.map_files
    return which == "all" or (which == "main" and (source == main or source.is_truth))


def write_maps_and_views(out: Path, run, cfg, logger, t0_s: float) -> list[Path]:
    """Per complete stride: the PLY of the maps ``cfg.map_files`` names, the first strides' map plots, the stride's
    trajectory plot and the rerun recording (camera images at the main variant's poses)."""
    from graph_slam.session.adapters.ply import write_ply
    from graph_slam.viz import plots

    files: list[Path] = []
    scene = run.session.scene
    primary = run.results[list(run.results)[-1]]  # the last variant asked for
    main = MapSource(primary.variant)
    for k, ref in enumerate(run.references):
        tag_stride = f"{run.session.name}_s{run.global_index(k):02d}"
        title = f"{run.label} stride {k + 1} ({run.session.name})"
        if cfg.rrd:
            _log_frames(run.session, ref, primary, cfg, logger, t0_s, run.global_index(k))
            trace = run.traces.get(primary.variant)
            if trace is not None:
                log_grids(logger, trace, ref.frame_indices, run.global_index(k), t0_s,
                          ref.world_T_stride)  # fmt: skip
        truth_boxes = truth_boxes_in_stride(scene, ref.world_T_stride) if scene is not None else []
        for source, smap in run.maps[k].items():
            fused = smap.fused
            if len(fused) and _map_file(cfg, source, main):
                ply = out / "maps" / source.tag / f"{tag_stride}.ply"
                ply.parent.mkdir(parents=True, exist_ok=True)
                write_ply(file_cloud(fused, cfg.map_file_voxel_m), ply, dtype="float32")
                files.append(ply)
            if k < cfg.plot_maps_per_session and len(fused) and (source == main or source.is_truth):
                files += _map_plots(out, source, smap, tag_stride, title, truth_boxes)
            if cfg.rrd and source == main:  # the map as its PLY file holds it
                view = file_cloud(fused, cfg.map_file_voxel_m)
                colors = (
                    None if view.colors is None else np.rint(view.colors * 255).astype(np.uint8)
                )
                logger.set_time(run.global_index(k), t0_s + float(ref.t_s[-1]))
                logger.log_stride(ref.world_T_stride)
                logger.log_cloud(view.points_m, colors, entity=MAP)
                if smap.obstacles is not None:
                    logger.log_obstacles(
                        smap.obstacles.obstacles, smap.obstacles.floor.floor_T_stride()
                    )
        if cfg.rrd:
            logger.log_trajectory("ground_truth", ref.stride_T_camera[:, :3, 3])
            for v, res in run.results.items():
                poses = res.smoothed_stride_T_camera[ref.frame_indices]
                logger.log_trajectory(v, poses[:, :3, 3])
        files.append(
            plots.plot_stride_trajectories(
                out / "plots" / f"trajectory_{tag_stride}.png",
                ref.stride_T_camera[:, :3, 3],
                {
                    v: res.online_stride_T_camera[ref.frame_indices][:, :3, 3]
                    for v, res in run.results.items()
                },
                title=f"{title}, online poses",
            )
        )
    return files


def _log_frames(session, stride_, primary, cfg, logger, t0_s: float, stride: int) -> None:
    """Every ``rrd_frame_step``-th frame of ``stride_`` (a reference or a pipeline's stride:
    its ``frame_indices`` and ``world_T_stride``), images at the main variant's smoothed pose."""
    step = cfg.rrd_image_step
    intr = scaled_intrinsics(session.intrinsics, step)
    for i in list(stride_.frame_indices)[:: cfg.rrd_frame_step]:
        frame = session.frame(int(i))
        logger.set_time(stride, t0_s + float(frame.t_s))
        logger.log_stride(stride_.world_T_stride)
        logger.log_camera(
            primary.smoothed_stride_T_camera[i],
            intr,
            frame.depth_m[::step, ::step],
            None if frame.color_rgb is None else frame.color_rgb[::step, ::step],
        )


def log_run(session, results: dict, cfg, logger, t0_s: float, trace=None) -> None:
    """``run``'s recording of one session: per stride of the main (last) variant, its frames'
    images, its live elevation grids (``trace``: the main variant's
    :class:`~graph_slam.report.terrain_trace.TerrainTrace`), its smoothed map and obstacles,
    and every variant's smoothed positions in it."""
    primary = results[list(results)[-1]]
    for s in primary.strides:
        idx = [int(i) for i in s.frame_indices]
        if not idx:
            continue
        _log_frames(session, s, primary, cfg, logger, t0_s, s.index)
        if trace is not None:
            log_grids(logger, trace, idx, s.index, t0_s, s.world_T_stride)
        logger.set_time(s.index, t0_s + float(primary.frames[idx[-1]].t_s))
        logger.log_stride(s.world_T_stride)
        smap = None if s.terrain is None else s.terrain.smoothed or s.terrain.online
        if smap is not None and len(smap.fused):
            logger.log_cloud(smap.fused.points_m, smap.fused.colors_rgb, entity=MAP)
            if smap.obstacles is not None:
                logger.log_obstacles(
                    smap.obstacles.obstacles, smap.obstacles.floor.floor_T_stride()
                )
        for v, res in results.items():
            poses = res.smoothed_stride_T_camera[idx]
            keep = np.isfinite(poses).all(axis=(1, 2))
            if keep.any():
                logger.log_trajectory(v, poses[keep][:, :3, 3])


def _map_plots(out: Path, source: MapSource, smap, tag_stride: str, title: str, truth_boxes):
    from graph_slam.viz import plots

    fused = smap.fused
    # a scatter of every voxel takes seconds to draw: plot at most 40k of them
    sub = slice(None, None, max(1, len(fused) // 40_000))
    colors = None if fused.colors_rgb is None else fused.colors_rgb[sub]
    obstacles = smap.obstacles.obstacles if smap.obstacles is not None else []
    title = f"{source}, {title}"
    return [
        plots.plot_map_top_view(
            out / "plots" / f"map_{source.tag}_{tag_stride}.png",
            fused.points_m[sub],
            colors,
            obstacles,
            title=title,
            truth_boxes=truth_boxes,
        ),
        plots.plot_elevation(
            out / "plots" / f"elevation_{source.tag}_{tag_stride}.png", smap.elevation, title
        ),
    ]


def write_plots(out: Path, study) -> list[Path]:
    """Error over the gait cycle (online poses) and the measured boxes per map source."""
    from graph_slam.viz import plots

    toe = np.asarray(study.toe_pcts, dtype=float)
    toe_pct = float(np.nanmean(toe)) if np.isfinite(toe).any() else None
    curves = {str(v): c for v, c in study.curves.items()}
    files = []
    if any(curves.values()):  # nothing to draw when no session was scored
        files.append(
            plots.plot_error_over_gait_cycle(
                out / "plots" / "error_gait_cycle.png", curves, toe_pct
            )
        )
    files += _deadline_plot(out, study.deadlines)
    for source, strides in study.maps.items():
        measured = collect_measurements([s.obstacles for s in strides])
        if measured:
            files.append(
                plots.plot_obstacle_boxes(
                    out / "plots" / f"obstacles_{source.tag}.png",
                    measured,
                    {k: study.truth_sizes[k] for k in measured},
                )
            )
    return files


def _deadline_plot(out: Path, deadlines: dict) -> list[Path]:
    """``plots/obstacle_known_gait_phase.png``: per speed and variant, the fraction of the
    strides' whole obstacles the online map knew by each % of the gait cycle."""
    from graph_slam.viz import plots

    known: dict[str, dict[str, list[float]]] = {}
    toe: dict[str, list[float]] = {}
    for variant, strides in deadlines.items():
        for s in strides:
            known.setdefault(s.speed, {}).setdefault(str(variant), []).extend(s.known_pct)
            toe.setdefault(s.speed, []).append(s.toe_off_pct)
    if not known:
        return []  # no scored stride
    toe_pct = {
        sp: float(np.nanmean(t)) if np.isfinite(t).any() else float("nan")
        for sp, t in ((sp, np.asarray(v, dtype=float)) for sp, v in toe.items())
    }
    return [
        plots.plot_obstacle_known_vs_phase(
            out / "plots" / "obstacle_known_gait_phase.png", known, toe_pct
        )
    ]


def write_report_md(path: Path, report, cfg) -> Path:
    from graph_slam.report.markdown import report_markdown

    path.write_text(report_markdown(report, cfg), encoding="utf-8")
    return path

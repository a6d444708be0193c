"""``compare``: run the thesis baseline and the factor-graph variants on sessions, write a report.

One call, :func:`compare`, reads as its steps. For every session (one walking speed each):

1. run every variant (``graph_slam.pipelines.run_session``);
2. build the ground-truth reference in each stride's frame (:func:`truth_world_T_stride`) and the
   stance/swing mask and gait-cycle percentage from the load-cell events;
3. score every stride and variant (online poses; graph variants also smoothed) with
   :func:`~graph_slam.evaluation.trajectory.stride_trajectory_metrics`, count frames;
4. fuse a map per stride and variant (smoothed poses; the baseline's are its online poses) and
   with the true poses, extract the boxes, match them to the scene;
5. write TUM trajectories, PLY maps, plots and a rerun recording.

Then ``metrics.json``, ``report.md`` (thesis Tables 4.2 and 4.1) and the resolved config.
The report folder's layout is documented in docs/evaluation.md.
"""

from __future__ import annotations

import dataclasses
import logging
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from pydantic import Field

from graph_slam.config import ConfigModel, write_config
from graph_slam.errors import EvaluationError
from graph_slam.evaluation.boxes import (
    assess_stride,
    collect_measurements,
    obstacle_accuracy,
    truth_boxes_in_stride,
)
from graph_slam.evaluation.counts import FrameCounts
from graph_slam.evaluation.report import (
    MapEvaluation,
    MapStride,
    StrideEvaluation,
    VariantEvaluation,
    metrics_document,
    table_rows,
    write_metrics_json,
)
from graph_slam.evaluation.tables import table_4_1, table_4_2, table_box_counts
from graph_slam.evaluation.timing import timing_stats
from graph_slam.pipelines import VARIANTS, PipelineConfig, PipelineVariant
from graph_slam.terrain.stride_map import MappingConfig

log = logging.getLogger(__name__)

ProgressCallback = Callable[[int, int], None]
TRUTH = "ground truth"
"""Name of the map fused with the true poses (mapping-only accuracy in Table 4.1)."""
SPEED_CLASSES = ((0.95, "Slow"), (1.25, "Normal"), (float("inf"), "Fast"))
"""Walking speed label from the measured speed (m/s): below 0.95 slow, below 1.25 normal."""


class CompareConfig(ConfigModel):
    """What ``compare`` runs and how much it writes."""

    variants: list[PipelineVariant] = Field(
        default_factory=lambda: list(VARIANTS), min_length=1, description="variants to run"
    )
    pipeline: PipelineConfig = PipelineConfig()
    mapping: MappingConfig = MappingConfig()
    map_pixel_step: int = Field(
        2, ge=1, le=16, description="map clouds use every n-th depth pixel in u and v"
    )
    map_max_depth_m: float = Field(
        2.0,
        gt=0,
        description="map clouds leave out depth beyond this (and beyond the pipeline's "
        "max_depth_m): the D455's depth noise grows as z² (1.9 mm at 1 m, 7.6 mm at 2 m, 17 mm "
        "at 3 m) and far readings blur box edges; the thesis measured boxes within ~1 m",
    )
    match_margin_m: float = Field(
        0.05,
        gt=0,
        description="an obstacle belongs to the scene box whose footprint grown by this holds "
        "its centre",
    )
    truth_map: bool = Field(
        True, description="also fuse each stride with the true poses (mapping-only accuracy)"
    )
    rrd: bool = Field(True, description="write recording.rrd (rerun)")
    rrd_frame_step: int = Field(3, ge=1, description="log every n-th frame's images to the .rrd")
    rrd_image_step: int = Field(
        2, ge=1, le=8, description="subsample the .rrd's depth/colour images by this factor"
    )
    plot_maps_per_session: int = Field(
        1,
        ge=0,
        description="map/elevation plots (last variant and true poses) for the first n strides "
        "of each session",
    )


@dataclass(frozen=True)
class SessionSpec:
    """A session folder and, optionally, its walking-speed label (else from the ground truth)."""

    path: Path
    speed: str | None = None


@dataclass
class CompareReport:
    """What :func:`compare` wrote and measured."""

    out: Path
    variants: dict[str, VariantEvaluation]
    table_4_2_online: str
    table_4_2_smoothed: str
    tables_4_1: dict[str, str]
    box_counts: dict[str, str] = field(default_factory=dict)
    """Per map source: boxes measured, skipped (per reason) and missed (markdown)."""
    maps: dict[str, MapEvaluation] = field(default_factory=dict)
    files: list[Path] = field(default_factory=list)
    wall_s: float = 0.0
    sessions: list[str] = field(default_factory=list)


def truth_world_T_stride(world_T_camera: np.ndarray, foot_T_camera: np.ndarray) -> np.ndarray:
    """The true stride frame: heel contact point as origin, z up, x the sole's horizontal x.

    ``world_T_foot = world_T_camera · foot_T_camera(q)⁻¹`` with the true camera pose and the
    encoder angles at the stride's first frame (the pipelines anchor their stride there, from
    the same leg model; the simulated heel is pinned during stance). Definition as in
    ``kinematics.stride_frame``.
    """
    world_T_foot = np.asarray(world_T_camera) @ np.linalg.inv(np.asarray(foot_T_camera))
    x = world_T_foot[:3, 0].copy()
    x[2] = 0.0
    norm = float(np.linalg.norm(x))
    if norm < 0.1:
        raise EvaluationError("truth_world_T_stride: the foot's x axis is near vertical")
    x /= norm
    z = np.array([0.0, 0.0, 1.0])
    out = np.eye(4)
    out[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    out[:3, 3] = world_T_foot[:3, 3]
    return out


def speed_label(speed_m_s: float) -> str:
    for limit, label in SPEED_CLASSES:
        if speed_m_s < limit:
            return label
    return SPEED_CLASSES[-1][1]


def _frame_categories(results) -> list[str]:
    """registered / bridged / other per frame (see docs/evaluation.md, "report folder").

    Baseline: ``registered`` status → registered. Graph: an ICP factor the gate accepted
    (flag ``icp:ok…``) → registered; any other frame with a pose after the stride's first →
    bridged (IMU/kinematics carried it). Stride-start (reset) frames and frames without pose →
    other.
    """
    out = []
    for f in results.frames:
        if not f.has_pose or f.status == "reset":
            out.append("other")
        elif results.variant == "icp":
            out.append("registered" if f.status == "registered" else "other")
        elif any(flag.startswith("icp:ok") for flag in f.flags):
            out.append("registered")
        else:
            out.append("bridged")
    return out


def _counts(categories: Sequence[str]) -> FrameCounts:
    reg = sum(c == "registered" for c in categories)
    bri = sum(c == "bridged" for c in categories)
    return FrameCounts(len(categories), reg, bri, len(categories) - reg - bri)


def _camera_cloud(frame, intrinsics, step: int, min_m: float, max_m: float):
    depth = frame.depth_m[::step, ::step]
    v, u = np.nonzero((depth > min_m) & (depth < max_m))
    z = depth[v, u].astype(np.float64)
    u_px, v_px = u * step, v * step
    pts = np.column_stack(
        [
            (u_px - intrinsics.cx_px) * z / intrinsics.fx_px,
            (v_px - intrinsics.cy_px) * z / intrinsics.fy_px,
            z,
        ]
    )
    colors = None if frame.color_rgb is None else frame.color_rgb[::step, ::step][v, u]
    return pts, colors


def _scaled_intrinsics(intrinsics, step: int):
    if step == 1:
        return intrinsics
    return dataclasses.replace(
        intrinsics,
        width_px=len(range(0, intrinsics.width_px, step)),
        height_px=len(range(0, intrinsics.height_px, step)),
        fx_px=intrinsics.fx_px / step,
        fy_px=intrinsics.fy_px / step,
        cx_px=intrinsics.cx_px / step,
        cy_px=intrinsics.cy_px / step,
    )


def _write_tum_finite(path: Path, t_s: np.ndarray, poses: np.ndarray) -> Path:
    from graph_slam.session.io import write_tum

    keep = np.isfinite(poses).all(axis=(1, 2))
    path.parent.mkdir(parents=True, exist_ok=True)
    write_tum(path, t_s[keep], poses[keep])
    return path


@dataclass
class _StrideTruth:
    global_index: int
    speed: str
    number: int
    frame_indices: np.ndarray
    t_s: np.ndarray
    world_T_stride: np.ndarray
    reference_stride_T_camera: np.ndarray
    in_stance: np.ndarray
    cycle_pct: np.ndarray
    toe_off_pct: float


def _session_truth(session, results, first_global: int, label: str) -> list[_StrideTruth]:
    """Reference poses in each complete stride's true frame, stance mask, gait-cycle %."""
    from graph_slam.evaluation.trajectory import gait_cycle_percent, stance_mask
    from graph_slam.strides.kinematics import leg_model_for

    gt = session.ground_truth
    if gt is None:
        raise EvaluationError(f"{session.path}: compare needs ground truth (groundtruth.txt)")
    joints = session.joints
    if joints is None:
        raise EvaluationError(f"{session.path}: compare needs joints.csv for the stride frame")
    calib = session.calibration
    leg = leg_model_for(calib.thigh_T_camera, None)
    t_joint = np.asarray(joints.t_s) + calib.joints_time_offset_s
    t_gt = np.asarray(gt.t_s)
    world_T_camera = np.asarray(gt.parent_T_child)
    events = session.events
    if events is None or not len(events):
        raise EvaluationError(
            f"{session.path}: compare needs gait events (events.csv) to cut strides"
        )
    kinds = np.asarray(events.kind)
    sources = np.asarray(events.source)
    use = sources == "load_cell" if (sources == "load_cell").any() else np.ones(len(kinds), bool)
    strikes = np.asarray(events.t_s)[use & (kinds == "foot_strike")]
    offs = np.asarray(events.t_s)[use & (kinds == "toe_off")]
    t_all = results.t_s
    out: list[_StrideTruth] = []
    for s in results.strides:
        idx = np.asarray(s.frame_indices, dtype=int)
        if s.start != "foot_strike" or idx.size < 2:
            continue
        t = t_all[idx]
        before = strikes[strikes <= t[0]]
        after = strikes[strikes > t[-1]]
        if before.size == 0 or after.size == 0:
            continue  # not a complete stride (session starts or ends inside it)
        gi = np.searchsorted(t_gt, t)
        gi = np.clip(gi, 0, t_gt.size - 1)
        if not np.allclose(t_gt[gi], t, atol=1e-6):
            raise EvaluationError(f"{session.path}: groundtruth.txt is not at the frame times")
        q0 = np.array(
            [np.interp(t[0], t_joint, joints.knee_rad), np.interp(t[0], t_joint, joints.ankle_rad)]
        )
        w_T_s = truth_world_T_stride(world_T_camera[gi[0]], leg.foot_T_camera(q0))
        ref = np.linalg.inv(w_T_s) @ world_T_camera[gi]
        t_strike, t_next = float(before[-1]), float(after[0])
        toe = offs[(offs > t_strike) & (offs < t_next)]
        toe_off = float(toe[0]) if toe.size else None
        toe_pct = (
            float(gait_cycle_percent(np.array([toe_off]), t_strike, t_next)[0])
            if toe_off is not None
            else float("nan")
        )
        out.append(
            _StrideTruth(
                global_index=first_global + len(out),
                speed=label,
                number=len(out) + 1,
                frame_indices=idx,
                t_s=t,
                world_T_stride=w_T_s,
                reference_stride_T_camera=ref,
                in_stance=stance_mask(t, toe_off),
                cycle_pct=gait_cycle_percent(t, t_strike, t_next),
                toe_off_pct=toe_pct,
            )
        )
    return out


def _measured_speed(session) -> float:
    gt = session.ground_truth
    p = np.asarray(gt.parent_T_child)[:, :2, 3]
    t = np.asarray(gt.t_s)
    return float(np.linalg.norm(p[-1] - p[0]) / max(t[-1] - t[0], 1e-9))


def compare(
    sessions: Sequence[str | Path | SessionSpec],
    out: str | Path,
    config: CompareConfig | None = None,
    progress: ProgressCallback | None = None,
) -> CompareReport:
    """Run every variant on every session and write the report folder ``out``."""
    from graph_slam.session import open_session

    t_start = time.perf_counter()
    cfg = config or CompareConfig()
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    specs = [s if isinstance(s, SessionSpec) else SessionSpec(Path(s)) for s in sessions]
    if not specs:
        raise EvaluationError("compare: no session given")
    opened = [open_session(s.path) for s in specs]
    total = sum(len(cfg.variants) * s.n_frames for s in opened)
    done = 0

    def tick(_: int, __: int) -> None:
        nonlocal done
        done += 1
        if progress is not None:
            progress(done, total)

    files: list[Path] = [write_config(cfg, out / "config.yaml")]
    names = _variant_names(cfg.variants)
    strides_eval: dict[str, list[StrideEvaluation]] = {n: [] for n in names}
    durations: dict[str, list[float]] = {n: [] for n in names}
    matches: dict[str, list] = {n: [] for n in [*cfg.variants, *([TRUTH] if cfg.truth_map else [])]}
    truth_sizes: dict[str, np.ndarray] = {}
    curves: dict[str, list] = {v: [] for v in cfg.variants}
    toe_pcts: list[float] = []
    logger = _make_logger(out / "recording.rrd" if cfg.rrd else None)
    n_global = 0
    t_offset = 0.0
    for spec, session in zip(specs, opened, strict=True):
        label = spec.speed or speed_label(_measured_speed(session))
        results = {}
        for v in cfg.variants:
            pcfg = PipelineConfig.model_validate({**cfg.pipeline.model_dump(), "variant": v})
            results[v] = _run(session, pcfg, tick)
        first = results[cfg.variants[0]]
        truths = _session_truth(session, first, n_global, label)
        _check_same_strides(session, results, truths)
        for v, res in results.items():
            cats = _frame_categories(res)
            for suffix, poses in _poses_of(v, res):
                for st in truths:
                    strides_eval[v + suffix].append(
                        StrideEvaluation(
                            index=st.global_index,
                            speed=st.speed,
                            number=st.number,
                            frames=_counts([cats[i] for i in st.frame_indices]),
                            trajectory=_trajectory(st, poses),
                        )
                    )
                durations[v + suffix] += [f.frontend_s + f.backend_s for f in res.frames]
            for st in truths:
                m = _trajectory(st, res.online_stride_T_camera)
                curves[v].append((st.cycle_pct, m.errors_unaligned_m))
        toe_pcts += [st.toe_off_pct for st in truths]
        files += _write_trajectories(out / "trajectories" / session.name, session, results, truths)
        files += _maps_and_views(
            out, session, label, results, truths, cfg, matches, truth_sizes, logger, t_offset
        )
        n_global += len(truths)
        t_offset += float(session.frame_times_s[-1]) + 1.0 if session.n_frames else 0.0
    logger.close()
    if cfg.rrd:
        files.append(out / "recording.rrd")

    maps = {
        source: MapEvaluation(
            poses=_map_poses(source),
            strides=strides,
            accuracy=obstacle_accuracy(
                collect_measurements([m.obstacles for m in strides]), truth_sizes
            ),
        )
        for source, strides in matches.items()
    }
    variants: dict[str, VariantEvaluation] = {}
    for name in names:
        base = name.split(" ")[0]
        variants[name] = VariantEvaluation(
            strides=strides_eval[name],
            timing=timing_stats(np.asarray(durations[name])) if durations[name] else None,
            obstacles=maps[base].accuracy,
        )
    session_names = [s.name for s in opened]
    files.append(
        write_metrics_json(
            metrics_document(", ".join(session_names), variants, maps), out / "metrics.json"
        )
    )
    files += _plots(out, cfg, variants, curves, toe_pcts, maps, truth_sizes)
    online = {v: variants[v] for v in cfg.variants}
    smoothed = {n: variants[n] for n in names if n.endswith("smoothed")}
    t42_on = table_4_2(table_rows(online), list(online))
    t42_sm = table_4_2(table_rows(smoothed), list(smoothed)) if smoothed else ""
    t41 = {_map_title(source): table_4_1(m.accuracy) for source, m in maps.items()}
    counts = {_map_title(source): table_box_counts(m.counts()) for source, m in maps.items()}
    report = CompareReport(
        out=out,
        variants=variants,
        table_4_2_online=t42_on,
        table_4_2_smoothed=t42_sm,
        tables_4_1=t41,
        box_counts=counts,
        maps=maps,
        files=files,
        sessions=session_names,
    )
    report.wall_s = time.perf_counter() - t_start
    files.append(_write_report_md(out / "report.md", report, cfg))
    return report


def _map_poses(source: str) -> str:
    """Which poses fuse a source's maps: the truth, the baseline's online poses (it has no
    smoother) or a graph variant's smoothed poses."""
    return "ground truth" if source == TRUTH else "online" if source == "icp" else "smoothed"


def _map_title(source: str) -> str:
    return f"{source} poses" if source == TRUTH else f"{source} ({_map_poses(source)} poses)"


def _variant_names(variants: Sequence[str]) -> list[str]:
    names = list(variants)
    names += [f"{v} smoothed" for v in variants if v != "icp"]
    return names


def _poses_of(variant: str, results):
    yield "", results.online_stride_T_camera
    if variant != "icp":
        yield " smoothed", results.smoothed_stride_T_camera


def _run(session, pcfg: PipelineConfig, tick: ProgressCallback):
    from graph_slam.pipelines import run_session

    return run_session(session, pcfg, progress=tick)


def _check_same_strides(session, results, truths) -> None:
    for v, res in results.items():
        by_start = {int(s.frame_indices[0]): s for s in res.strides if s.frame_indices}
        for st in truths:
            s = by_start.get(int(st.frame_indices[0]))
            if s is None or len(s.frame_indices) != st.frame_indices.size:
                raise EvaluationError(
                    f"{session.path}: variant {v!r} cut strides differently from "
                    f"{next(iter(results))!r} (stride starting at frame {st.frame_indices[0]})"
                )


def _trajectory(st: _StrideTruth, poses: np.ndarray):
    from graph_slam.evaluation.trajectory import stride_trajectory_metrics

    return stride_trajectory_metrics(
        st.t_s, poses[st.frame_indices], st.reference_stride_T_camera, st.in_stance
    )


def _write_trajectories(folder: Path, session, results, truths) -> list[Path]:
    """TUM files of ``stride_T_camera`` (each stride restarts at its foot strike) per variant,
    online and smoothed, and the ground truth in the same per-stride frames."""
    files = []
    for v, res in results.items():
        tag = v.replace("+", "_")
        files.append(
            _write_tum_finite(folder / f"{tag}_online.tum", res.t_s, res.online_stride_T_camera)
        )
        files.append(
            _write_tum_finite(folder / f"{tag}_smoothed.tum", res.t_s, res.smoothed_stride_T_camera)
        )
    if truths:
        t = np.concatenate([st.t_s for st in truths])
        ref = np.concatenate([st.reference_stride_T_camera for st in truths])
        files.append(_write_tum_finite(folder / "ground_truth.tum", t, ref))
    return files


def _maps_and_views(out, session, label, results, truths, cfg, matches, truth_sizes, logger, t0):
    """Per stride: fuse the map of every variant (and the truth), match boxes, write PLY, log."""
    from graph_slam.evaluation import plots
    from graph_slam.session.adapters.ply import write_ply
    from graph_slam.terrain.stride_map import build_stride_map

    files: list[Path] = []
    scene = session.scene
    if scene is not None:
        for obj in scene.objects:
            if obj.kind == "box":
                truth_sizes.setdefault(obj.name.split("#", 1)[0], np.asarray(obj.size_m))
    intr = session.intrinsics
    ccfg = cfg.pipeline.cloud
    rrd_intr = _scaled_intrinsics(intr, cfg.rrd_image_step)
    primary = cfg.variants[-1]
    for k, st in enumerate(truths):
        clouds, colors = [], []
        for i in st.frame_indices:
            frame = session.frame(int(i))
            p, c = _camera_cloud(
                frame,
                intr,
                cfg.map_pixel_step,
                ccfg.min_depth_m,
                min(ccfg.max_depth_m, cfg.map_max_depth_m),
            )
            clouds.append(p)
            colors.append(c)
            if cfg.rrd and (i - st.frame_indices[0]) % cfg.rrd_frame_step == 0:
                logger.set_time(st.global_index, t0 + float(frame.t_s))
                logger.log_stride(st.world_T_stride)
                s_img = cfg.rrd_image_step
                pose = results[primary].smoothed_stride_T_camera[i]
                logger.log_camera(
                    pose,
                    rrd_intr,
                    frame.depth_m[::s_img, ::s_img],
                    None if frame.color_rgb is None else frame.color_rgb[::s_img, ::s_img],
                )
        has_colors = all(c is not None for c in colors)
        pose_sets = {
            v: res.smoothed_stride_T_camera[st.frame_indices] for v, res in results.items()
        }
        if cfg.truth_map:
            pose_sets[TRUTH] = st.reference_stride_T_camera
        truth_boxes = truth_boxes_in_stride(scene, st.world_T_stride) if scene is not None else []
        tag_stride = f"{session.name}_s{st.global_index:02d}"
        for v, poses in pose_sets.items():
            smap = build_stride_map(clouds, poses, colors if has_colors else None, cfg.mapping)
            fused = smap.fused
            tag = v.replace("+", "_").replace(" ", "_")
            if len(fused):
                ply = out / "maps" / tag / f"{tag_stride}.ply"
                ply.parent.mkdir(parents=True, exist_ok=True)
                write_ply(fused.to_point_cloud(), ply)
                files.append(ply)
            obstacles = smap.obstacles.obstacles if smap.obstacles is not None else []
            assessed = assess_stride(
                smap.obstacles, truth_boxes, cfg.match_margin_m, smap.obstacle_error
            )
            matches[v].append(MapStride(st.global_index, st.speed, st.number, assessed))
            if k < cfg.plot_maps_per_session and len(fused) and v in (primary, TRUTH):
                # a scatter of every voxel takes seconds to draw: plot at most 40k of them
                sub = slice(None, None, max(1, len(fused) // 40_000))
                colors_sub = None if fused.colors_rgb is None else fused.colors_rgb[sub]
                title = f"{v}, {label} stride {st.number} ({session.name})"
                files.append(
                    plots.plot_map_top_view(
                        out / "plots" / f"map_{tag}_{tag_stride}.png",
                        fused.points_m[sub],
                        colors_sub,
                        obstacles,
                        title=title,
                        truth_boxes=truth_boxes,
                    )
                )
                files.append(
                    plots.plot_elevation(
                        out / "plots" / f"elevation_{tag}_{tag_stride}.png", smap.elevation, title
                    )
                )
            if cfg.rrd and v == primary:
                logger.set_time(st.global_index, t0 + float(st.t_s[-1]))
                logger.log_stride(st.world_T_stride)
                logger.log_cloud(fused.points_m, fused.colors_rgb, entity=_MAP)
                if smap.obstacles is not None:
                    logger.log_obstacles(obstacles, smap.obstacles.floor.floor_T_stride())
        if cfg.rrd:
            logger.log_trajectory("ground_truth", st.reference_stride_T_camera[:, :3, 3])
            for v, res in results.items():
                logger.log_trajectory(v, res.smoothed_stride_T_camera[st.frame_indices][:, :3, 3])
        files.append(
            plots.plot_stride_trajectories(
                out / "plots" / f"trajectory_{tag_stride}.png",
                st.reference_stride_T_camera[:, :3, 3],
                {
                    v: res.online_stride_T_camera[st.frame_indices][:, :3, 3]
                    for v, res in results.items()
                },
                title=f"{label} stride {st.number} ({session.name}), online poses",
            )
        )
    return files


_MAP = "world/stride/map"


def _make_logger(path: Path | None):
    from graph_slam.viz import make_logger

    return make_logger(path)


def _plots(out, cfg, variants, curves, toe_pcts, maps, truth_sizes) -> list[Path]:
    from graph_slam.evaluation import plots

    files = []
    toe = np.asarray(toe_pcts, dtype=float)
    toe_pct = float(np.nanmean(toe)) if np.isfinite(toe).any() else None
    files.append(
        plots.plot_error_over_gait_cycle(out / "plots" / "error_gait_cycle.png", curves, toe_pct)
    )
    for v, m in maps.items():
        measured = collect_measurements([s.obstacles for s in m.strides])
        if measured:
            tag = v.replace("+", "_").replace(" ", "_")
            files.append(
                plots.plot_obstacle_boxes(
                    out / "plots" / f"obstacles_{tag}.png",
                    measured,
                    {k: truth_sizes[k] for k in measured},
                )
            )
    return files


def _phase_table(variants: dict[str, VariantEvaluation]) -> str:
    lines = [
        "| variant | strides | RMSE aligned median (mm) | stance (mm) | swing (mm) | unaligned median (mm) | time median / p95 (ms) |",
        "| :-- | --: | --: | --: | --: | --: | --: |",
    ]

    def med(values):
        a = np.asarray([x for x in values if x is not None], dtype=float)
        a = a[np.isfinite(a)]
        return f"{np.median(a) * 1e3:.1f}" if a.size else "–"

    for name, v in variants.items():
        traj = [s.trajectory for s in v.strides if s.trajectory is not None]
        phase = {
            p: [t.rmse_by_phase_m.get(p, {}).get("aligned") for t in traj]
            for p in ("stance", "swing")
        }
        timing = f"{v.timing.median_s * 1e3:.1f} / {v.timing.p95_s * 1e3:.1f}" if v.timing else "–"
        lines.append(
            f"| {name} | {len(v.strides)} | {med([t.rmse_aligned_m for t in traj])} | "
            f"{med(phase['stance'])} | {med(phase['swing'])} | "
            f"{med([t.rmse_unaligned_m for t in traj])} | {timing} |"
        )
    return "\n".join(lines) + "\n"


def summary_table(report: CompareReport) -> str:
    """Per variant: median RMSE (aligned, stance, swing, unaligned) and per-frame time."""
    return _phase_table(report.variants)


def _write_report_md(path: Path, report: CompareReport, cfg: CompareConfig) -> Path:
    out = report.out
    plots_dir = out / "plots"
    pngs = sorted(p.relative_to(out) for p in plots_dir.glob("*.png")) if plots_dir.exists() else []
    lines = [
        "# graph_slam comparison report",
        "",
        f"Sessions: {', '.join(report.sessions)}. Variants: {', '.join(cfg.variants)}. "
        f"Wall time {report.wall_s:.0f} s. Resolved config: `config.yaml`; every number: "
        "`metrics.json`; layout: docs/evaluation.md.",
        "",
        "RMSE: camera position in the true stride frame after SE(3) alignment (evo), per stride. "
        "Registered: frames whose pose came from an accepted registration; bridged: frames "
        "carried by IMU/kinematics factors over a missing or rejected registration; the "
        "stride's first (reset) frame is in neither.",
        "",
        "## Table 4.2 — online poses",
        "",
        report.table_4_2_online,
    ]
    if report.table_4_2_smoothed:
        lines += [
            "## Table 4.2 — smoothed poses (graph variants, batch per stride)",
            "",
            report.table_4_2_smoothed,
        ]
    lines += ["## Summary", "", summary_table(report)]
    lines += [
        "## Table 4.1 — obstacle dimensions (mm)",
        "",
        "Each stride's map (the baseline's online poses, the graph's smoothed poses, or the "
        "true poses) measures the boxes it saw **whole**: a box is skipped when its outline "
        "comes near the unobserved area beyond the map (edge of map), another obstacle is "
        "within 4 cm (adjacent), its top was seen in part, too little floor was seen around it, "
        "or it came out in pieces (split); missed: inside the mapped area, no obstacle found. "
        "Counts are strides.",
        "",
    ]
    for name, table in report.tables_4_1.items():
        lines += [f"### {name}", "", table]
        if name in report.box_counts:
            lines += [report.box_counts[name]]
    lines += ["## Plots", ""]
    lines += [f"![{p.stem}]({p.as_posix()})" for p in pngs]
    lines += [
        "",
        "## Files",
        "",
        "`trajectories/<session>/<variant>_{online,smoothed}.tum` and `ground_truth.tum` "
        "(stride_T_camera, each stride restarting at its foot strike: `evo_ape tum "
        "ground_truth.tum icp_imu_kin_online.tum`), `maps/<variant>/<session>_sNN.ply`, "
        "`recording.rrd` (`graph-slam view " + out.as_posix() + "`).",
        "",
    ]
    path.write_text("\n".join(lines), encoding="utf-8")
    return path

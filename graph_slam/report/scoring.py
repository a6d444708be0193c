"""One session's run of every variant, and its scores against the per-stride reference.

Scoring is evaluation's (:mod:`graph_slam.evaluation`); this module only hands it what the
pipelines produced — poses by :class:`~graph_slam.report.keys.RunKey`, maps by
:class:`~graph_slam.report.keys.MapSource` — and the reference of each complete stride.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from graph_slam.errors import EvaluationError
from graph_slam.evaluation.boxes import assess_stride, truth_boxes_in_stride
from graph_slam.evaluation.counts import FrameCounts
from graph_slam.evaluation.report import MapStride, StrideEvaluation
from graph_slam.pipelines import PipelineConfig, PipelineResults
from graph_slam.report.keys import Kind, MapSource, RunKey
from graph_slam.strides.reference import StrideReference
from graph_slam.variants import Variant


@dataclass
class SessionRun:
    """Every variant's results on one session and the reference of its complete strides
    (empty without ground truth). ``first_stride``: the global index of its first stride."""

    session: object
    label: str
    results: dict[Variant, PipelineResults]
    references: list[StrideReference]
    first_stride: int
    maps: list[dict] = field(default_factory=list)
    """Per reference stride: ``{MapSource: StrideMap}`` (:func:`stride_maps`)."""
    traces: dict = field(default_factory=dict)
    """Per variant: what its online terrain map knew at every frame
    (:class:`~graph_slam.report.terrain_trace.TerrainTrace`)."""

    @classmethod
    def build(
        cls,
        session,
        label: str,
        results,
        pipeline: PipelineConfig,
        first_stride: int,
        traces: dict | None = None,
    ) -> SessionRun:
        from graph_slam.strides.kinematics import session_leg_model
        from graph_slam.strides.reference import stride_references
        from graph_slam.strides.streams import session_streams

        refs: list[StrideReference] = []
        if session.ground_truth is not None:
            first = next(iter(results.values()))
            streams = session_streams(session, pipeline.event_source)
            leg, _ = session_leg_model(
                session, pipeline.mount_pitch_deg, pipeline.mount_estimate, streams=streams
            )
            refs = stride_references(session, first.t_s, first.strides, streams.events, leg)
        run = cls(session, label, results, refs, first_stride, traces=dict(traces or {}))
        run.check_same_strides()
        return run

    def global_index(self, k: int) -> int:
        return self.first_stride + k

    def stride_of(self, variant: Variant, ref: StrideReference):
        """The variant's stride that ``ref`` scores (by its first frame: variants number their
        strides differently, the graph counts the part before the first foot strike)."""
        first = int(ref.frame_indices[0])
        for s in self.results[variant].strides:
            if s.frame_indices and int(s.frame_indices[0]) == first:
                return s
        return None

    def check_same_strides(self) -> None:
        """Every variant must cut the scored strides at the same frames."""
        first = next(iter(self.results))
        for v in self.results:
            for ref in self.references:
                s = self.stride_of(v, ref)
                if s is None or len(s.frame_indices) != ref.frame_indices.size:
                    raise EvaluationError(
                        f"{self.session.path}: variant {v!r} cut strides differently from "
                        f"{first!r} (stride starting at frame {ref.frame_indices[0]})"
                    )

    def error_curves(self) -> dict[Variant, list[tuple[np.ndarray, np.ndarray]]]:
        """Per variant and stride: (gait-cycle %, unaligned online error) for the plot."""
        return {
            v: [
                (ref.cycle_pct, _trajectory(ref, res.online_stride_T_camera).errors_unaligned_m)
                for ref in self.references
            ]
            for v, res in self.results.items()
        }

    def truth_sizes(self) -> dict[str, np.ndarray]:
        scene = self.session.scene
        if scene is None:
            return {}
        return {
            obj.name.split("#", 1)[0]: np.asarray(obj.size_m)
            for obj in scene.objects
            if obj.kind == "box"
        }


def frame_categories(results: PipelineResults) -> list[str]:
    """registered / partial / bridged / other per frame (see docs/evaluation.md, "report
    folder").

    Baseline: ``registered`` status → registered, ``partial: k DoF`` (a registration the thesis
    took whose degeneracy test held fewer than six directions) → partial. Graph: an ICP factor the gate accepted on all
    six directions (flag ``icp:ok``) → registered; on only some (``icp:partial (k DoF)``, the
    front end's degeneracy test) → partial; any other frame with a pose after the stride's
    first → bridged (IMU/kinematics carried it). Stride-start (reset) frames and frames without
    pose → other.
    """
    out = []
    for f in results.frames:
        if not f.has_pose or f.status == "reset":
            out.append("other")
        elif Variant(results.variant).is_baseline:
            partial = f.status.startswith("partial")
            out.append(
                "registered" if f.status == "registered" else "partial" if partial else "other"
            )
        elif "icp:ok" in f.flags:
            out.append("registered")
        elif any(flag.startswith("icp:partial") for flag in f.flags):
            out.append("partial")
        else:
            out.append("bridged")
    return out


def _counts(categories: Sequence[str]) -> FrameCounts:
    reg = sum(c == "registered" for c in categories)
    bri = sum(c == "bridged" for c in categories)
    par = sum(c == "partial" for c in categories)
    return FrameCounts(len(categories), reg, bri, len(categories) - reg - bri - par, par)


def _trajectory(ref: StrideReference, poses: np.ndarray):
    from graph_slam.evaluation.trajectory import stride_trajectory_metrics

    return stride_trajectory_metrics(
        ref.t_s, poses[ref.frame_indices], ref.stride_T_camera, ref.in_stance
    )


def anchor_of(flags, stride=None) -> dict:
    """The anchor's case, slope and up source from a stride's first frame's flags, and the
    stride's online grid's frames fused / held back (``stride``: its ``StrideOutput``)."""
    from graph_slam.report.summary import anchor_of as _anchor_of
    from graph_slam.report.summary import grid_frames_of

    return {**_anchor_of(flags), **({} if stride is None else grid_frames_of(stride))}


def terrain_labels(run: SessionRun) -> list[str | None]:
    """Per reference stride, the terrain under the stance foot from the session's
    ``strides_truth.csv`` (the simulator's terrain walker writes it; the true stride whose
    strike is within 0.1 s of the reference's), else None."""
    from pathlib import Path

    from graph_slam.sim.terrain_truth import STRIDES_NAME, read_stride_terrain

    path = getattr(run.session, "path", None)
    if path is None or not (Path(path) / STRIDES_NAME).is_file():
        return [None] * len(run.references)
    rows = read_stride_terrain(Path(path))
    out: list[str | None] = []
    for ref in run.references:
        near = [r for r in rows if abs(r.strike_t_s - ref.t_strike_s) < 0.1]
        out.append(near[0].label if near else None)
    return out


def score_session(run: SessionRun) -> dict[RunKey, list[StrideEvaluation]]:
    """Per key (variant and pose kind) and complete stride: frame counts and trajectory."""
    out: dict[RunKey, list[StrideEvaluation]] = {}
    labels = terrain_labels(run)
    for v, res in run.results.items():
        cats = frame_categories(res)
        kinds = [Kind.ONLINE] + ([] if v.is_baseline else [Kind.SMOOTHED])
        for kind in kinds:
            poses = res.poses(kind)
            out[RunKey(v, kind)] = [
                StrideEvaluation(
                    index=run.global_index(k),
                    speed=run.label,
                    number=k + 1,
                    frames=_counts([cats[i] for i in ref.frame_indices]),
                    trajectory=_trajectory(ref, poses),
                    terrain=labels[k],
                    anchor=anchor_of(
                        res.frames[int(ref.frame_indices[0])].flags, run.stride_of(v, ref)
                    )
                    or None,
                )
                for k, ref in enumerate(run.references)
            ]
    return out


def truth_map(run: SessionRun, ref: StrideReference, pipeline: PipelineConfig):
    """The stride's map fused with the true poses (mapping-only accuracy), from the same map
    clouds as the pipelines' maps."""
    from graph_slam.terrain.maps.builder import TerrainBuilder

    terrain = pipeline.terrain.model_copy(update={"enabled": True, "poses": ("online",)})
    builder = TerrainBuilder(
        terrain, run.session.intrinsics, pipeline.cloud.min_depth_m, pipeline.cloud.max_depth_m
    )
    for i in ref.frame_indices:
        builder.add_frame(int(i), run.session.frame(int(i)))
    return builder.close_stride(-1, ref.frame_indices, ref.stride_T_camera, None).online


def stride_maps(run: SessionRun, ref: StrideReference, sources, pipeline: PipelineConfig):
    """Each source's map of the stride: the pipelines' (graph: smoothed poses; baseline:
    online) and, for the truth source, one fused here from the true poses."""
    out = {}
    for source in sources:
        if source.is_truth:
            out[source] = truth_map(run, ref, pipeline)
            continue
        terrain = run.stride_of(source.variant, ref).terrain
        if terrain is not None and tuple(terrain.frame_indices) != tuple(ref.frame_indices):
            raise EvaluationError(
                f"{run.session.path}: the {source} map of the stride at frame "
                f"{ref.frame_indices[0]} was fused from other frames"
            )
        out[source] = None if terrain is None else terrain.by_kind(source.map_kind)
    return out


def score_maps(
    run: SessionRun, sources: Sequence[MapSource], margin_m: float
) -> dict[MapSource, list[MapStride]]:
    """Per map source and complete stride: the boxes measured, skipped or missed."""
    scene = run.session.scene
    out: dict[MapSource, list[MapStride]] = {s: [] for s in sources}
    for k, ref in enumerate(run.references):
        truth_boxes = truth_boxes_in_stride(scene, ref.world_T_stride) if scene is not None else []
        maps = run.maps[k]
        for source in sources:
            smap = maps.get(source)
            if smap is None:
                raise EvaluationError(
                    f"{run.session.path}: no terrain map of the stride at frame "
                    f"{ref.frame_indices[0]} for {source}"
                )
            assessed = assess_stride(smap.obstacles, truth_boxes, margin_m, smap.obstacle_error)
            out[source].append(MapStride(run.global_index(k), run.label, k + 1, assessed))
    return out


def score_deadlines(run: SessionRun) -> dict:
    """Per variant with a trace and complete stride: when its online map knew each obstacle
    of the stride's final map (:func:`graph_slam.report.terrain_trace.stride_deadlines`)."""
    from graph_slam.report.terrain_trace import stride_deadlines

    return {
        v: [
            stride_deadlines(
                trace, run.stride_of(v, ref), ref, run.global_index(k), run.label, k + 1
            )
            for k, ref in enumerate(run.references)
        ]
        for v, trace in run.traces.items()
        if trace.every_frame
    }

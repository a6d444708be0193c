"""Step 3 of ``compare`` for the terrain features: each scored stride's final grid against the
scene's features, the swing's measured clearance against the true one, the stance-time
warnings and the per-feature deadlines (graph_slam.evaluation.features, .clearance), and
their summaries for report.md and metrics.json (``terrain_features``).

``study`` is the comparison's accumulator (:class:`graph_slam.report.compare._Study`): its
``features``, ``clearances``, ``edge_clearances``, ``clearance_flags`` and
``feature_deadlines`` lists per variant.
"""

from __future__ import annotations

from graph_slam.pipelines.config import PipelineConfig
from graph_slam.report.scoring import SessionRun


def score_run_features(run: SessionRun, study, pipeline: PipelineConfig) -> None:
    """Each scored stride's final grid: its features against the scene's, its measured swing
    clearance against the true one."""
    from graph_slam.errors import GraphSlamError
    from graph_slam.strides.kinematics import session_leg_model

    if run.session.scene is None or not run.references:
        return
    try:
        leg = session_leg_model(run.session, pipeline.mount_pitch_deg, pipeline.mount_estimate)[0]
    except GraphSlamError:
        leg = None
    for variant in run.results:
        for ref in run.references:
            _score_stride(run, study, variant, ref, leg)


def _score_stride(run: SessionRun, study, variant, ref, leg) -> None:
    from graph_slam.evaluation.clearance import edge_clearance_pairs, swing_clearance_pair
    from graph_slam.evaluation.features import feature_truth_from_scene, score_features
    from graph_slam.terrain.features.extract import features_of_view

    stride = run.stride_of(variant, ref)
    grid = None if stride is None else stride.smoothed_grid
    if grid is None:
        return
    truth = feature_truth_from_scene(run.session.scene, ref.world_T_stride)
    measured = features_of_view(grid, source="smoothed")
    study.features.setdefault(variant, []).append(score_features(measured, truth))
    pair = swing_clearance_pair(run, ref, stride, leg)
    if pair is not None:
        study.clearances.setdefault(variant, []).append(pair)
    edges, true_edge = edge_clearance_pairs(run, ref, stride, leg)
    study.edge_clearances.setdefault(variant, []).extend(edges)
    trace = run.traces.get(variant)
    if pair is not None and trace is not None and len(trace.predictions) == len(trace.t_s):
        warned = any(
            trace.predictions[int(i)] is not None and trace.predictions[int(i)].warning
            for i in ref.frame_indices
            if ref.toe_off_s is not None and trace.t_s[int(i)] < ref.toe_off_s
        )
        no_edge = true_edge is None  # level floor: no edge to clear
        study.clearance_flags.setdefault(variant, []).append(
            (warned, float("nan") if no_edge else true_edge)
        )
    if trace is not None and trace.every_frame and len(trace.features) == len(trace.t_s):
        _score_deadlines(run, study, variant, ref, stride, leg, trace, measured)


def _score_deadlines(run, study, variant, ref, stride, leg, trace, measured) -> None:
    """When each feature of the stride's final grid was first known, relative to toe-off, and
    whether the swing must clear it."""
    from graph_slam.evaluation.clearance import in_swing, swing_toe_extent
    from graph_slam.evaluation.features import feature_deadlines

    idx = [int(i) for i in ref.frame_indices]
    rows = feature_deadlines(
        [trace.t_s[i] for i in idx], [trace.features[i] for i in idx], measured, ref.toe_off_s
    )
    swing = swing_toe_extent(run, ref, stride, leg)  # the features it must clear
    for r in rows:
        r["in_swing"] = in_swing(r, swing)
    study.feature_deadlines.setdefault(variant, []).extend(rows)


def _warning_summary(rows) -> dict:
    """Swings, those whose true edge clearance (over the edges the swing crossed; none on
    level floor) is under the warning margin (2 cm), how many of them the stance-time
    prediction flagged before toe-off, and the flags raised over swings that cleared it or
    crossed no edge."""
    from graph_slam.terrain.features.clearance import ClearanceConfig

    margin = ClearanceConfig().warn_below_m
    low = [w for w, true in rows if true < margin]
    return {
        "swings": len(rows),
        "true_below_margin": len(low),
        "flagged_below_margin": int(sum(low)),
        "false_warnings": int(sum(w for w, true in rows if not true < margin)),
    }


def feature_summaries(study) -> dict[str, dict]:
    """Per variant: the feature scores, clearances, deadlines and warnings summarised."""
    from graph_slam.evaluation.clearance import summarise_clearances
    from graph_slam.evaluation.features import summarise_feature_deadlines, summarise_scores

    return {
        str(v): {
            "grids": len(scores),
            **summarise_scores(scores),
            "swing_clearance": summarise_clearances(study.clearances.get(v, [])),
            "edge_clearance": summarise_clearances(study.edge_clearances.get(v, [])),
            "deadlines": summarise_feature_deadlines(study.feature_deadlines.get(v, [])),
            "warnings": _warning_summary(study.clearance_flags.get(v, [])),
        }
        for v, scores in study.features.items()
    }

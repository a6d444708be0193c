"""Feature truth from a scene, and the scoring of measured features against it."""

from __future__ import annotations

import math

import numpy as np

from graph_slam.evaluation.features import (
    feature_truth_from_scene,
    score_features,
    summarise_scores,
)
from graph_slam.session.records import SceneObject, SceneTruth
from graph_slam.sim.scene import load_scene
from graph_slam.terrain.features.extract import extract_features
from tests.test_terrain_features import CELL, X0, Y0, grid, stairs_surface


def _stride(x, y):
    t = np.eye(4)
    t[:2, 3] = x, y
    return t


def test_truth_of_the_stairs_and_ramp_scenes():
    stairs = feature_truth_from_scene(load_scene("stairs-up").truth(), _stride(0.5, -0.3))
    flight = stairs.stairs[0]
    assert flight.n_steps == 6 and flight.ascending
    for k, step in enumerate(flight.steps):
        assert math.isclose(step.nosing.x_m, 1.0 + 0.28 * k, abs_tol=1e-9)
        assert math.isclose(step.rise_m, 0.17, abs_tol=1e-9)
        assert np.allclose(step.nosing.y_range_m, (-0.9, 0.1))
    assert math.isclose(flight.steps[0].tread_m, 0.28, abs_tol=1e-9)
    ramp = feature_truth_from_scene(load_scene("ramp").truth(), _stride(0.5, 0.0)).ramps[0]
    assert math.isclose(math.degrees(ramp.slope_rad), 8.0, abs_tol=0.01)
    assert math.isclose(ramp.start.x_m, 1.25 - 0.5, abs_tol=1e-9)
    boxes = feature_truth_from_scene(load_scene("thesis-boxes").truth(), _stride(0.2, 0.0)).boxes
    assert math.isclose(boxes[0].leading.x_m, 1.2 - 0.1016 - 0.2, abs_tol=1e-6)
    assert math.isclose(boxes[0].height_m, 0.1905, abs_tol=1e-9)


def test_scores_of_a_measured_staircase_against_its_scene():
    rise, tread, first = 0.17, 0.28, 0.513
    objects = []
    for k in range(4):
        pose = np.eye(4)
        pose[:3, 3] = first + (k + 0.5) * tread, 0.0, (k + 1) * rise / 2
        objects.append(
            SceneObject(f"S.step{k + 1}", pose, np.array([tread, 2.0, (k + 1) * rise]), "step")
        )
    truth = feature_truth_from_scene(SceneTruth("s", tuple(objects)), np.eye(4))
    measured = extract_features(*grid(stairs_surface(), 0.002, seed=3), (X0, Y0), CELL)
    scores = score_features(measured, truth)
    assert len(scores["steps"]) == 4
    summary = summarise_scores([scores])["steps"]
    assert summary["rise_m"]["rmse"] <= 0.003
    assert summary["nosing_m"]["rmse"] <= 0.008
    assert summary["tread_m"]["n"] == 3 and summary["tread_m"]["rmse"] <= 0.008
    # a truth shifted by 3 cm shows in the nosing errors
    shifted = feature_truth_from_scene(SceneTruth("s", tuple(objects)), _stride(-0.03, 0.0))
    moved = summarise_scores([score_features(measured, shifted)])["steps"]
    assert abs(moved["nosing_m"]["bias"] + 0.03) <= 0.005


def test_feature_deadline_known_answer():
    from graph_slam.evaluation.features import feature_deadlines, summarise_feature_deadlines

    final = extract_features(*grid(stairs_surface(), 0.0), (X0, Y0), CELL)
    rough = extract_features(*grid(stairs_surface(rise=0.19), 0.0), (X0, Y0), CELL)
    partial = extract_features(
        *grid(stairs_surface(), 0.0, unknown=lambda x, y: x > 1.0), (X0, Y0), CELL
    )
    # frames at 0.0 .. 0.4 s: rises 2 cm off first, then the near two steps, then all four
    online = [None, rough, partial, None, final]
    rows = feature_deadlines([0.0, 0.1, 0.2, 0.3, 0.4], online, final, toe_off_s=0.35)
    assert [r["kind"] for r in rows] == ["step"] * 4
    assert [r["known_t_s"] for r in rows] == [0.2, 0.2, 0.4, 0.4]
    summary = summarise_feature_deadlines(rows)
    assert summary["n"] == 4 and summary["n_known"] == 4 and summary["n_before_toe_off"] == 2
    assert math.isclose(summary["lead_s_min"], -0.05, abs_tol=1e-9)
    assert summary["swing"]["n"] == 0  # none marked as the swing's own
    from graph_slam.evaluation.clearance import in_swing

    near = (rows[0]["edge_x_m"] - 0.01, rows[1]["edge_x_m"] + 0.01)
    for r in rows:  # a swing over the two near steps only
        r["in_swing"] = in_swing(r, (*near, 0.0))
    own = summarise_feature_deadlines(rows)["swing"]
    assert own["n"] == 2 and own["n_before_toe_off"] == 2 and own["n_at_least_0_5_s"] == 0
    assert not any(in_swing(r, (-9.0, 9.0, 5.0)) for r in rows)  # a swing beside the flight


def _spec(scene, name):
    return next(o for o in scene.spec.objects if o.name == name)


def _stride_at(x, y, z):
    t = _stride(x, y)
    t[2, 3] = z
    return t


def test_truth_of_the_walked_stairs_from_the_scene_yaml():
    for name, heel in (("stairs-ascent", (0.5, -0.3, 0.0)), ("stairs-descent", (0.0, 0.0, 1.02))):
        scene = load_scene(name)
        spec = _spec(scene, "Stairs")
        tread, width, rise = spec.size_m
        sign = -1.0 if spec.direction == "down" else 1.0
        # the session's SceneTruth gives the same truth as the scene itself
        for source in (scene, scene.truth()):
            flight = feature_truth_from_scene(source, _stride_at(*heel)).stairs[0]
            assert flight.n_steps == spec.steps and flight.ascending == (sign > 0)
            for k, step in enumerate(flight.steps):
                x = spec.center_xy_m[0] + k * tread - heel[0]
                assert math.isclose(step.nosing.x_m, x, abs_tol=1e-9), (name, k)
                assert math.isclose(step.nosing.yaw_rad, 0.0, abs_tol=1e-12)
                assert np.allclose(
                    step.nosing.y_range_m, (-width / 2 - heel[1], width / 2 - heel[1])
                )
                assert math.isclose(step.rise_m, sign * rise, abs_tol=1e-9)
                top = (k + 1) * rise if sign > 0 else (spec.steps - k) * rise
                assert math.isclose(step.upper_height_m, top - heel[2], abs_tol=1e-9)
                assert math.isclose(step.upper_height_m - step.lower_height_m, rise, abs_tol=1e-9)
                if k + 1 < flight.n_steps:
                    assert math.isclose(step.tread_m, tread, abs_tol=1e-9)
                else:
                    assert math.isnan(step.tread_m)
    # the descent's platform edge is the flight's first nosing, not a curb too
    curbs = feature_truth_from_scene(load_scene("stairs-descent"), _stride_at(0, 0, 1.02)).curbs
    assert all(abs(c.edge.x_m - 1.0) > 0.1 for c in curbs)


def test_truth_of_the_walked_ramps_and_curbs_from_the_scene_yaml():
    for name, uphill in (("ramp-up-8", 0.0), ("ramp-down-8", math.pi)):
        scene = load_scene(name)
        length, _, rise = _spec(scene, "Ramp").size_m
        x0 = _spec(scene, "Ramp").center_xy_m[0] - length / 2
        ramps = feature_truth_from_scene(scene.truth(), _stride(0.5, 0.0)).ramps
        assert len(ramps) == 1
        assert math.isclose(ramps[0].slope_rad, math.atan2(rise, length), abs_tol=1e-12)
        assert math.isclose(math.degrees(ramps[0].slope_rad), 8.0, abs_tol=0.01)
        assert math.isclose(abs(ramps[0].uphill_yaw_rad), uphill, abs_tol=1e-9)
        assert math.isclose(ramps[0].start.x_m, x0 - 0.5, abs_tol=1e-9)
        assert np.allclose(ramps[0].x_range_m, (x0 - 0.5, x0 + length - 0.5))
    # the platform at the ramp's top is flush with it: no curb there
    curbs = feature_truth_from_scene(load_scene("ramp-up-8"), _stride(0.5, 0.0)).curbs
    assert all(abs(c.edge.x_m - 3.0) > 0.1 for c in curbs)
    for name, heel, sign in (
        ("curb-up", (0.5, 0.0, 0.0), 1.0),
        ("curb-down", (0.0, 0.0, 0.12), -1.0),
    ):
        scene = load_scene(name)
        spec = _spec(scene, "Curb")
        depth, width, height = spec.size_m
        x_edge = spec.center_xy_m[0] - sign * depth / 2 - heel[0]
        truth = feature_truth_from_scene(scene.truth(), _stride_at(*heel))
        assert not truth.boxes and not truth.stairs
        curb = min(truth.curbs, key=lambda c: abs(c.edge.x_m - x_edge))
        assert math.isclose(curb.edge.x_m, x_edge, abs_tol=1e-9)
        assert math.isclose(curb.height_m, sign * height, abs_tol=1e-9)
        assert math.isclose(curb.near_height_m, 0.0, abs_tol=1e-9)
        assert np.allclose(curb.edge.y_range_m, (-width / 2, width / 2))


def test_truth_of_a_box_stepped_onto_and_a_changed_scene():
    scene = load_scene("step-onto")
    depth, _, height = _spec(scene, "Box").size_m
    (box,) = feature_truth_from_scene(scene.truth(), _stride(0.3, 0.0)).boxes
    assert math.isclose(box.leading.x_m, 1.3 - depth / 2 - 0.3, abs_tol=1e-9)
    assert math.isclose(box.height_m, height, abs_tol=1e-12)
    assert math.isclose(box.depth_m, depth, abs_tol=1e-12)
    # a session whose objects no longer match the scene file keeps the objects' own truth
    moved = scene.truth().objects[0]
    pose = moved.world_T_object.copy()
    pose[0, 3] += 0.1
    changed = SceneTruth("step-onto", (SceneObject(moved.name, pose, moved.size_m, moved.kind),))
    (box,) = feature_truth_from_scene(changed, _stride(0.3, 0.0)).boxes
    assert math.isclose(box.leading.x_m, 1.4 - depth / 2 - 0.3, abs_tol=1e-9)


def test_a_deadline_edge_is_known_where_the_final_one_is_reported():
    """Online, the flight is seen only on y < −0.1 m, so each nosing is reported at y = −0.1 m;
    the final grid reports it at y = 0 (the foot's line). The same edge line is known; one 3 cm
    off along x is not."""
    from graph_slam.evaluation.features import feature_deadlines

    final = extract_features(*grid(stairs_surface(), 0.0), (X0, Y0), CELL)
    side = extract_features(
        *grid(stairs_surface(), 0.0, unknown=lambda x, y: y > -0.1), (X0, Y0), CELL
    )
    off = extract_features(
        *grid(stairs_surface(first=0.543), 0.0, unknown=lambda x, y: y > -0.1), (X0, Y0), CELL
    )
    assert all(abs(s.nosing.y_m + 0.11) < 0.02 for s in side.stairs[0].steps)
    rows = feature_deadlines([0.0, 0.1], [off, side], final, toe_off_s=0.5)
    assert [r["known_t_s"] for r in rows] == [0.1] * 4

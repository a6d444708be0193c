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

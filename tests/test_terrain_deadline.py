"""The deadline bookkeeping on a hand-made sequence of online obstacles."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest

from graph_slam.errors import EvaluationError
from graph_slam.evaluation.terrain_deadline import obstacle_deadlines, summarise_deadlines


@dataclass
class Box:
    leading_edge_x_m: float
    height_m: float
    center_xy_m: tuple[float, float]


FINAL = [Box(1.00, 0.190, (1.10, -0.28)), Box(2.30, 0.076, (2.43, -0.33))]


def test_first_frame_within_both_tolerances_and_lead_before_toe_off():
    t = [0.0, 0.1, 0.2, 0.3, 0.4, 0.5]
    frames = [
        [],  # nothing yet
        [Box(1.05, 0.190, (1.12, -0.28))],  # edge 5 cm off
        [Box(1.015, 0.175, (1.11, -0.28))],  # height 1.5 cm off
        [Box(1.019, 0.181, (1.11, -0.28)), Box(2.2, 0.07, (2.40, -0.33))],  # box 1 known
        [Box(1.0, 0.19, (1.10, -0.28)), Box(2.31, 0.08, (2.70, -0.33))],  # box 2 too far off
        [Box(1.0, 0.19, (1.10, -0.28))],
    ]
    d = obstacle_deadlines(t, frames, FINAL, toe_off_s=0.35, stride_index=4)
    assert [x.known_t_s for x in d[:1]] == [0.3]
    assert d[0].lead_s == pytest.approx(0.05)
    assert d[0].stride_index == 4 and d[0].obstacle_index == 0
    assert not d[1].known and math.isnan(d[1].lead_s)
    s = summarise_deadlines(d)
    assert s["n"] == 2 and s["n_known"] == 1 and s["n_before_toe_off"] == 1
    assert s["fraction_before_toe_off"] == 0.5
    assert s["lead_s_median"] == pytest.approx(0.05)
    # known after toe-off: a negative lead, not counted as before
    late = obstacle_deadlines(t, frames, FINAL[:1], toe_off_s=0.25)
    assert late[0].lead_s == pytest.approx(-0.05)
    assert summarise_deadlines(late)["n_before_toe_off"] == 0
    # tolerances are parameters: with 2 cm on the height, frame 2 already knows box 1
    loose = obstacle_deadlines(t, frames, FINAL[:1], 0.35, height_tol_m=0.02)
    assert loose[0].known_t_s == 0.2


def test_bad_sequences_are_refused_and_empty_is_nan():
    with pytest.raises(EvaluationError, match="increase"):
        obstacle_deadlines([0.0, 0.0], [[], []], FINAL, 1.0)
    with pytest.raises(EvaluationError, match="2 obstacle lists for 3 frames"):
        obstacle_deadlines([0.0, 0.1, 0.2], [[], []], FINAL, 1.0)
    s = summarise_deadlines(obstacle_deadlines([0.0], [[]], [], None))
    assert s["n"] == 0 and np.isnan(s["fraction_before_toe_off"])

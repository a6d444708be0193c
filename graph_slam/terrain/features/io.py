"""One stride's terrain features and toe clearances as JSON (``run``'s ``sNN_features.json``).

The document (``FEATURES_SCHEMA`` 1), stride frame, metres, radians, NaN as null:

- ``stride``: the stride's index; ``frames``: its first and last frame index;
- ``online`` / ``smoothed``: :meth:`TerrainFeatures.to_dict
  <graph_slam.terrain.features.model.TerrainFeatures.to_dict>` of the stride's online grid at its last
  frame and of its final grid (re-fused from the smoothed poses, or the online grid when no
  clouds were kept; null when there is none);
- ``predicted_clearance``: :func:`~graph_slam.terrain.features.prediction.predict_clearance` of the
  final grid from the heel's stride (the toe at ``toe_x_m``): the reference swing's clearance
  over the terrain this stride mapped;
- ``swing_clearance``: the measured swing — the toe path (the camera poses that placed the
  final grid at the stride's unloaded frames and the encoders, through the leg model) against
  the final grid —
  or null with ``swing_clearance_skipped`` saying why (no encoders, no swing frame, ...).

:func:`read_features_json` checks the fields and gives the records back.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from graph_slam.errors import EvaluationError, GraphSlamError
from graph_slam.terrain.features.clearance import Clearance, clearance_along, toe_path
from graph_slam.terrain.features.model import TerrainFeatures
from graph_slam.terrain.features.prediction import predict_clearance

FEATURES_SCHEMA = 1
_FIELDS = ("schema", "stride", "frames", "online", "smoothed", "predicted_clearance",
           "swing_clearance")  # fmt: skip


def swing_toe_path(stride, results, session, leg_model) -> tuple[np.ndarray | None, str]:
    """The toe (N×3, stride frame) over the stride's unloaded frames from the poses that
    placed its final grid (``StrideOutput.grid_stride_T_camera``: the smoothed ones, the online
    ones when the final grid is the online grid) and the encoders; None and why when it
    cannot be had."""
    from graph_slam.strides.joints import interp_q

    joints = session.joints if session is not None else None
    if joints is None or leg_model is None:
        return None, "no encoders or leg model"
    loaded = {f.frame_index: f.foot_loaded for f in results.frames}
    rows = [k for k, i in enumerate(stride.frame_indices) if not loaded.get(int(i), True)]
    placed = getattr(stride, "grid_stride_T_camera", stride.smoothed_stride_T_camera)
    poses = np.asarray(placed)[rows] if rows else np.zeros((0, 4, 4))
    t_joint = np.asarray(joints.t_s) + session.calibration.joints_time_offset_s
    t = session.frame_times_s[[stride.frame_indices[k] for k in rows]]
    q = [interp_q(float(tt), t_joint, joints.q_rad) for tt in t]
    ok = [k for k in range(len(rows)) if q[k] is not None and np.isfinite(poses[k]).all()]
    if len(ok) < 2:
        return None, "fewer than 2 swing frames with a pose and encoders"
    return toe_path(poses[ok], np.array([q[k] for k in ok]), leg_model), ""


def stride_features_document(stride, results, session=None, leg_model=None) -> dict:
    """The document of one stride (see the module docstring)."""
    from graph_slam.terrain.features.extract import features_of_view

    online = None if stride.online_grid is None else features_of_view(stride.online_grid)
    final_grid = stride.smoothed_grid
    smoothed = None if final_grid is None else features_of_view(final_grid, source="smoothed")
    doc = {
        "schema": FEATURES_SCHEMA,
        "stride": int(stride.index),
        "frames": [int(stride.frame_indices[0]), int(stride.frame_indices[-1])],
        "online": None if online is None else online.to_dict(),
        "smoothed": None if smoothed is None else smoothed.to_dict(),
        "predicted_clearance": None,
        "swing_clearance": None,
        "swing_clearance_skipped": "no final grid",
    }
    if final_grid is None:
        return doc
    doc["predicted_clearance"] = predict_clearance(final_grid, smoothed).to_dict()
    try:
        path, why = swing_toe_path(stride, results, session, leg_model)
    except GraphSlamError as err:
        path, why = None, str(err)
    if path is not None:
        swing = clearance_along(final_grid, smoothed, path)
        doc["swing_clearance"] = swing.to_dict()
        why = "" if math.isfinite(swing.min_m) else "the swing passed over no known cell"
    doc["swing_clearance_skipped"] = why or None
    return doc


def write_features_json(path: Path, doc: dict) -> Path:
    path = Path(path)
    path.write_text(json.dumps(doc, indent=1, allow_nan=False), encoding="utf-8")
    return path


def read_features_json(path: Path) -> dict:
    """:func:`write_features_json`'s document with the records rebuilt: ``online`` /
    ``smoothed`` as :class:`TerrainFeatures`, the clearances as :class:`Clearance` (or None)."""
    try:
        doc = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError) as err:
        raise EvaluationError(f"{path}: cannot read the features document ({err})") from None
    for key in _FIELDS:
        if key not in doc:
            raise EvaluationError(f"{path}: field {key!r} is missing")
    if doc["schema"] != FEATURES_SCHEMA:
        raise EvaluationError(f"{path}: field 'schema' is {doc['schema']}, not {FEATURES_SCHEMA}")
    try:
        for key in ("online", "smoothed"):
            doc[key] = None if doc[key] is None else TerrainFeatures.from_dict(doc[key])
        for key in ("predicted_clearance", "swing_clearance"):
            doc[key] = None if doc[key] is None else Clearance.from_dict(doc[key])
    except (KeyError, TypeError, ValueError) as err:
        raise EvaluationError(
            f"{path}: a feature or clearance record is malformed ({err})"
        ) from None
    return doc

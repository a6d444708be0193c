"""A box seen only from 2-3 m, measured on a stride map fused from the true poses.

The fast walk of the demo's course (seed 1) strikes its fifth stride with a copy of Box1 3.2 m
ahead; it never comes within 1.6 m. Fused from every point within 2 m, the map's box top is
dense only along its near edge and smeared along the walk by the range noise, and the box came
out 121 mm short (Table 4.1's depth error). The stride map now measures boxes on the points
within ``obstacle_max_depth_m`` (1.5 m): such a box is not measured, and a box seen close is
measured within the tolerances below.
"""

from __future__ import annotations

import numpy as np
import pytest

from graph_slam.evaluation.boxes import assess_stride, base_name, truth_boxes_in_stride
from graph_slam.terrain.maps.builder import map_cloud
from graph_slam.terrain.maps.stride_map import MappingConfig, build_stride_map

DEPTH_TOL_M = 0.008  # the target on a box's depth
HEIGHT_TOL_M = 0.003


def _rendered_stride(stride: int):
    """Camera-frame clouds, true stride_T_camera and the stride's true boxes."""
    from graph_slam.sim import SPEEDS_M_S, SimConfig
    from graph_slam.sim.recording import prepare
    from graph_slam.sim.render import Renderer, intrinsics_for

    cfg = SimConfig(
        speed_m_s=SPEEDS_M_S["fast"], strides=7, seed=1, resolution="424x240",
        drops="bursty", quicklook=False,
    )  # fmt: skip
    sim = prepare(cfg)
    intrinsics = intrinsics_for(sim.camera, cfg.fast, cfg.resolution)
    renderer = Renderer(sim.scene, intrinsics, sim.camera, motion_blur=False)
    strikes = sim.motion.foot_strikes_s
    t = sim.frame_times_s
    t = t[(t >= strikes[stride]) & (t < strikes[stride + 1])]
    world_T_camera = sim.motion.world_T(t, sim.thigh_T_camera)
    world_T_stride = sim.motion.world_T_heel(np.array([t[0]]))[0]
    # the stride frame: at the heel, gravity-aligned, x along the heading
    heading = np.arctan2(world_T_stride[1, 0], world_T_stride[0, 0])
    c, s = np.cos(heading), np.sin(heading)
    world_T_stride[:3, :3] = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    stride_T_camera = np.linalg.inv(world_T_stride) @ world_T_camera
    rng = np.random.default_rng(11)
    clouds = []
    for pose in world_T_camera:
        depth, _ = renderer.render(pose, rng)
        frame = type("F", (), {"depth_m": depth, "color_rgb": None})
        clouds.append(map_cloud(frame, intrinsics, 2, 0.1, 2.0)[0])
    return clouds, stride_T_camera, truth_boxes_in_stride(sim.scene.truth(), world_T_stride)


@pytest.fixture(scope="module")
def far_stride():
    return _rendered_stride(4)


def _outcomes(clouds, poses, truth, config):
    smap = build_stride_map(clouds, poses, config=config)
    return {
        o.box: o for o in assess_stride(smap.obstacles, truth, 0.05, smap.obstacle_error).outcomes
    }


def test_a_box_seen_only_from_afar_is_not_measured_short(far_stride):
    clouds, poses, truth = far_stride
    far = [b for b in truth if base_name(b.name) == "Box1" and 2.9 < b.center_xy_m[0] < 3.6]
    assert far, "the course must hold a Box1 copy about 3.2 m ahead of this stride's strike"
    box = far[0]
    whole_map = _outcomes(clouds, poses, truth, MappingConfig(obstacle_max_depth_m=None))
    near_map = _outcomes(clouds, poses, truth, MappingConfig())
    # the cause: from 2-3 m the box's top is dense only along its near edge (measured or not,
    # depending on which frames the stride kept, its depth is far off)
    assert whole_map[box.name].obstacle is not None
    assert abs(whole_map[box.name].obstacle.depth_m - box.size_m[0]) > 0.03
    # within 1.5 m the far box is not measured; the boxes measured are within the tolerances
    assert near_map.get(box.name) is None or near_map[box.name].status != "measured"
    measured = {k: o.obstacle for k, o in near_map.items() if o.status == "measured"}
    assert measured, "a box nearer the walk is measured"
    for name, obstacle in measured.items():
        true = next(b for b in truth if b.name == name)
        assert abs(obstacle.depth_m - true.size_m[0]) <= DEPTH_TOL_M, name
        assert abs(obstacle.width_m - true.size_m[1]) <= DEPTH_TOL_M, name
        assert abs(obstacle.height_m - true.size_m[2]) <= HEIGHT_TOL_M, name

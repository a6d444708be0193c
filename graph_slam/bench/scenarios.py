"""``graph-slam bench scenarios``: a fixed list of scenes and conditions as a regression suite.

Each scenario is simulated (short: a few strides, quarter resolution for the D455, native
for the Pico Flexx), then run with the full graph (``icp+imu+kin``) and the thesis baseline
(``icp``). Per scenario: coverage (frames with a smoothed pose), frames registered (6 DoF),
partial (k DoF) and bridged, frames counted registered whose smoothed pose is more than 2 cm
off (must be 0), smoothed and online per-stride RMSE (median, worst) and the baseline's
registered frames and its RMSE after SE(3) alignment (as the reports give it: its poses are
not in the true stride frame) beside them. Figures: docs/benchmarks.md ("Scenarios").
"""

from __future__ import annotations

import tempfile
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

WRONG_POSE_M = 0.02


@dataclass(frozen=True)
class Scenario:
    """One condition: a scene (a name under models/scenes) and the simulator's options."""

    name: str
    scene: str
    camera: str = "d455"
    speed: str = "normal"
    sim: dict = field(default_factory=dict)


SCENARIOS: tuple[Scenario, ...] = (
    Scenario("flat-textureless", "flat-floor-textureless"),
    Scenario("boxes-textureless", "thesis-boxes-textureless"),
    Scenario("boxes-pico-flexx", "thesis-boxes", camera="pico_flexx"),
    Scenario("flat-textured", "flat-floor"),
    Scenario("boxes-textured", "thesis-boxes"),
    Scenario("boxes-fast", "thesis-boxes", speed="fast"),
    # every sensor's noise σ doubled: depth, IMU, encoders and load cell
    Scenario("boxes-noise-x2", "thesis-boxes", sim={"noise_scale": 2.0}),
    Scenario("stairs-up", "stairs-up"),
    # the terrain-following walker: on the stairs, ramps, curbs and boxes (docs/simulator.md)
    Scenario("stairs-ascent", "stairs-ascent"),
    Scenario("stairs-descent", "stairs-descent"),
    *(Scenario(f"ramp-{d}-{a}", f"ramp-{d}-{a}") for d in ("up", "down") for a in (5, 8, 10)),
    Scenario("curb-up", "curb-up"),
    Scenario("curb-down", "curb-down"),
    Scenario("step-over", "step-over"),
    Scenario("step-onto", "step-onto"),
    Scenario("terrain-course", "terrain-course"),
)


@dataclass
class ScenarioScore:
    name: str
    frames: int
    with_pose: int
    registered: int
    partial: int
    bridged: int
    wrong_registered: int
    smoothed_mm: np.ndarray
    online_mm: np.ndarray
    baseline_registered: int
    baseline_mm: np.ndarray

    def line(self) -> str:
        def stat(values: np.ndarray) -> str:
            return "-" if values.size == 0 else f"{np.median(values):.1f}/{values.max():.1f}"

        return (
            f"{self.name:24s} {self.with_pose:4d}/{self.frames:<4d} {self.registered:4d} "
            f"{self.partial:4d} {self.bridged:4d} {self.wrong_registered:4d}   "
            f"{stat(self.smoothed_mm):>11s} {stat(self.online_mm):>11s}   "
            f"{self.baseline_registered:4d} {stat(self.baseline_mm):>13s}"
        )


def pooled(scores: list[ScenarioScore]) -> list[ScenarioScore]:
    """One score per scenario run at several speeds (``<name>@<speed>`` rows): counts summed,
    per-stride RMSE pooled over the speeds, named ``<name>@all`` (the targets are over the three
    speeds)."""
    groups: dict[str, list[ScenarioScore]] = {}
    for sc in scores:
        name, at, _ = sc.name.partition("@")
        if at:
            groups.setdefault(name, []).append(sc)
    out = []
    for name, group in groups.items():
        if len(group) < 2:
            continue
        total = {
            k: sum(getattr(g, k) for g in group)
            for k in ("frames", "with_pose", "registered", "partial", "bridged",
                      "wrong_registered", "baseline_registered")
        }  # fmt: skip
        arrays = {
            k: np.concatenate([getattr(g, k) for g in group])
            for k in ("smoothed_mm", "online_mm", "baseline_mm")
        }
        out.append(ScenarioScore(name=f"{name}@all", **total, **arrays))
    return out


HEADER = (
    f"{'scenario':24s} {'posed':>9s} {'reg':>4s} {'part':>4s} {'brid':>4s} {'wrong':>4s}   "
    f"{'smoothed mm':>11s} {'online mm':>11s}   {'base':>4s} {'baseline mm':>13s}\n"
    f"{'':24s} {'':9s} {'(6)':>4s} {'(k)':>4s} {'(0)':>4s} {'>2cm':>4s}   "
    f"{'med/worst':>11s} {'med/worst':>11s}   {'reg':>4s} {'aligned m/w':>13s}"
)


def markdown_table(scores: list[ScenarioScore], command: str) -> str:
    """The scores as a markdown table with its caption (date, commit, cores, command): what
    docs/benchmarks.md pastes ("Scenarios"). Accuracy and counts only: they repeat bit for
    bit (docs/benchmarks.md, "Determinism")."""
    from graph_slam.bench.caption import caption

    def stat(values: np.ndarray) -> str:
        return "–" if values.size == 0 else f"{np.median(values):.1f} / {values.max():.1f}"

    lines = [
        f"({caption(command)})",
        "",
        "| scenario | posed | registered (6 DoF) | partial | bridged | wrong (> 2 cm) "
        "| smoothed mm median / worst | online mm median / worst | baseline registered "
        "| baseline mm (aligned) median / worst |",
        "| :-- | --: | --: | --: | --: | --: | --: | --: | --: | --: |",
    ]
    for sc in scores:
        lines.append(
            f"| {sc.name} | {sc.with_pose}/{sc.frames} | {sc.registered} | {sc.partial} "
            f"| {sc.bridged} | {sc.wrong_registered} | {stat(sc.smoothed_mm)} "
            f"| {stat(sc.online_mm)} | {sc.baseline_registered} | {stat(sc.baseline_mm)} |"
        )
    return "\n".join(lines)


def simulate_scenario(scenario: Scenario, folder: Path, strides: int, seed: int) -> Path:
    from graph_slam.sim import SPEEDS_M_S, SimConfig, simulate

    native = scenario.camera != "d455"
    cfg = SimConfig(
        scene=scenario.scene,
        speed_m_s=SPEEDS_M_S[scenario.speed],
        strides=strides,
        seed=seed,
        camera=scenario.camera,
        drops="none",
        fast=not native,
        quicklook=False,
        **scenario.sim,
    )
    out = folder / scenario.name
    simulate(cfg, out, overwrite=True)
    return out


def _categories(results) -> list[str]:
    out = []
    for f in results.frames:
        if "icp:ok" in f.flags:
            out.append("registered")
        elif any(flag.startswith("icp:partial") for flag in f.flags):
            out.append("partial")
        elif f.status == "reset":
            out.append("reset")
        else:
            out.append("bridged")
    return out


def scenario_config(variant: str, base=None):
    """``base`` (a :class:`PipelineConfig`, the defaults when None) for ``variant``, without
    terrain maps (this bench scores poses only)."""
    from graph_slam.pipelines import PipelineConfig

    data = (base or PipelineConfig()).model_dump(mode="json")
    data["variant"] = variant
    data["terrain"] = {**data["terrain"], "enabled": False}
    return PipelineConfig.model_validate(data)


def score_scenario(name: str, path: Path, base=None) -> ScenarioScore:
    """The full graph and the baseline on one simulated session (``base``: the pipeline
    configuration both start from, the defaults when None)."""
    from graph_slam.bench.accuracy import score
    from graph_slam.pipelines import run_session
    from graph_slam.session import open_session
    from graph_slam.strides.kinematics import session_leg_model
    from graph_slam.strides.reference import stride_references
    from graph_slam.strides.streams import session_streams

    session = open_session(path)
    leg, _ = session_leg_model(session)
    graph = run_session(session, scenario_config("icp+imu+kin", base))
    baseline = run_session(session, scenario_config("icp", base))
    strides = score(session, graph, leg)
    cats = _categories(graph)
    events = session_streams(session, "load_cell").events
    refs = stride_references(session, graph.t_s, graph.strides, events, leg)
    smoothed = graph.smoothed_stride_T_camera
    wrong = scored = 0
    counts = {"registered": 0, "partial": 0, "bridged": 0}
    with_pose = 0
    for ref in refs:
        for i, truth in zip(ref.frame_indices, ref.stride_T_camera, strict=True):
            scored += 1
            err = np.linalg.norm(smoothed[i, :3, 3] - truth[:3, 3])
            with_pose += bool(np.isfinite(err))
            if cats[i] in counts:
                counts[cats[i]] += 1
            if cats[i] == "registered" and not err <= WRONG_POSE_M:
                wrong += 1
    base_reg = sum(
        baseline.frames[i].status == "registered" for ref in refs for i in ref.frame_indices
    )
    base_mm = np.array([_aligned_rmse_m(ref, baseline.online_stride_T_camera) for ref in refs])
    base_mm *= 1e3
    return ScenarioScore(
        name=name,
        frames=scored,
        with_pose=with_pose,
        registered=counts["registered"],
        partial=counts["partial"],
        bridged=counts["bridged"],
        wrong_registered=wrong,
        smoothed_mm=np.array([s.smoothed_rmse_m for s in strides]) * 1e3,
        online_mm=np.array([s.online_rmse_m for s in strides]) * 1e3,
        baseline_registered=int(base_reg),
        baseline_mm=base_mm[np.isfinite(base_mm)],
    )


def _aligned_rmse_m(ref, poses: np.ndarray) -> float:
    """The stride's RMSE after SE(3) alignment (the reports' figure for the baseline, whose
    poses are not in the true stride frame), on the frames it posed."""
    from graph_slam.evaluation.trajectory import stride_trajectory_metrics

    metrics = stride_trajectory_metrics(
        ref.t_s, poses[ref.frame_indices], ref.stride_T_camera, ref.in_stance
    )
    return float(metrics.rmse_aligned_m)


def at_speeds(scenarios, speeds: tuple[str, ...] | None) -> list[Scenario]:
    """Every scenario at each of ``speeds`` (named ``<name>@<speed>``); None: as listed. A
    scenario that is itself a speed (``boxes-fast``: the textured box course at the fast
    walk) is left out: ``boxes-textured@fast`` is the same run."""
    from graph_slam.errors import ConfigError
    from graph_slam.sim import SPEEDS_M_S

    if speeds is None:
        return list(scenarios)
    if unknown := [v for v in speeds if v not in SPEEDS_M_S]:
        raise ConfigError(f"speeds: unknown {unknown}; choose from {', '.join(SPEEDS_M_S)}")
    return [
        replace(s, name=f"{s.name}@{v}", speed=v)
        for s in scenarios
        if s.speed == "normal"
        for v in speeds
    ]


def run_scenarios(
    names: tuple[str, ...] | None = None,
    strides: int = 2,
    seed: int = 3,
    on_score=None,
    speeds: tuple[str, ...] | None = None,
    base=None,
) -> list[ScenarioScore]:
    """Simulate and score every scenario (or those named), at each of ``speeds`` when given,
    from the pipeline configuration ``base`` (defaults when None); ``on_score`` as each
    finishes."""
    chosen = at_speeds([s for s in SCENARIOS if names is None or s.name in names], speeds)
    scores = []
    with tempfile.TemporaryDirectory() as tmp:
        for scenario in chosen:
            path = simulate_scenario(scenario, Path(tmp), strides, seed)
            sc = score_scenario(scenario.name, path, base)
            scores.append(sc)
            if on_score is not None:
                on_score(sc)
    return scores

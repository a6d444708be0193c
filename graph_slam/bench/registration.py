"""Registration benchmark: per-stage timings and accuracy of frame-to-frame registration.

Datasets: synthetic D455-sized frames (848×480, 87° field of view) of the thesis's box course,
rendered analytically with exact ground truth, and, when present, the 10 real TUM RGB-D frames
(``../shared/data/tum_fr1_xyz_10``), where Open3D's own RGB-D odometry is run for comparison.

Per pair (target = frame k, source = frame k+1), as a frame-to-frame pipeline pays them for each
new frame: ``cloud`` (depth → points), ``voxel`` (the new frame's target pyramid and its
voxelisation on the previous frame's grid), ``normals`` (target pyramid), ``icp`` (Open3D levels
and the optional refinement), ``information`` (information matrix, degeneracy, convergence gate).
Each frame is prepared once (:func:`graph_slam.frontend.make_registration`), on the previous
frame's grid through the guess, and kept as the next pair's target, as the pipeline does. ``realtime``
(:class:`ProjectiveConfig`): ``cloud`` (organised points), ``normals`` (pixel normals and
intensity gradients), ``voxel`` (their voxel means), ``icp`` (projective Gauss-Newton),
``information``. ``realtime-gicp`` (:class:`GicpConfig`): ``cloud`` (decimated), ``voxel``,
``normals`` (covariances, normals, intensity gradients), ``icp`` (GICP and the photometric
stage), ``information``.

Sessions written by ``graph-slam simulate`` can be benchmarked too (:func:`session_dataset`),
at their resolution or decimated (``step`` 2: 848×480 → 424×240, intrinsics scaled).

The datasets are in :mod:`graph_slam.bench.registration_data`, Open3D's RGB-D odometry (the
reference on the TUM frames) in :mod:`graph_slam.bench.registration_open3d`.
"""

from __future__ import annotations

import time
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from graph_slam.bench.registration_data import (
    TUM_DEPTH_UNIT_M,
    TUM_INTRINSICS,
    Dataset,
    default_tum_folder,
    pose_error,
    read_tum_sample,
    relative_truth,
    session_dataset,
    synthetic_dataset,
)
from graph_slam.bench.registration_open3d import odometry_errors, open3d_rgbd_odometry
from graph_slam.errors import RegistrationError
from graph_slam.frontend import (
    CloudConfig,
    RegistrationConfig,
    colored_registration,
    fast_point_to_plane,
    make_registration,
    refined_colored_registration,
    thesis_registration,
)
from graph_slam.frontend.config import (
    GicpConfig,
    ProjectiveConfig,
    gicp_registration,
    realtime_registration,
)

__all__ = [
    "BENCH_CONFIGS",
    "GUESSES",
    "METHODS",
    "STAGES",
    "TUM_DEPTH_UNIT_M",
    "TUM_INTRINSICS",
    "ConfigSummary",
    "Dataset",
    "DatasetReport",
    "default_tum_folder",
    "initial_guess",
    "odometry_errors",
    "open3d_rgbd_odometry",
    "pose_error",
    "read_tum_sample",
    "relative_truth",
    "run_config",
    "run_registration_bench",
    "session_dataset",
    "synthetic_dataset",
]

STAGES = ("cloud", "voxel", "normals", "icp", "information")

#: The configurations compared (name → factory).
BENCH_CONFIGS: dict[str, Callable[[], RegistrationConfig]] = {
    "thesis: colored ICP 4/2/1 cm, no kernel": thesis_registration,
    "colored ICP 4/2/1 cm, Tukey (default)": colored_registration,
    "colored 4/2/1 cm + noise-weighted 5 mm refinement": refined_colored_registration,
    "point-to-plane 4/2/1 cm, Tukey": lambda: RegistrationConfig(method="point_to_plane"),
    "point-to-plane 2 cm (fast)": fast_point_to_plane,
}


def _accurate() -> RegistrationConfig:
    from graph_slam.pipelines.config import REGISTRATION_PRESETS

    return REGISTRATION_PRESETS["accurate"]()


#: Short names (``graph-slam bench registration --methods``): the five above and the graph's
#: presets ``accurate`` and ``realtime``.
METHODS: dict[str, tuple[str, Callable[[], RegistrationConfig | GicpConfig]]] = {
    "thesis": ("thesis: colored ICP 4/2/1 cm, no kernel", thesis_registration),
    "default": ("colored ICP 4/2/1 cm, Tukey (default)", colored_registration),
    "refined": ("colored 4/2/1 cm + noise-weighted 5 mm refinement", refined_colored_registration),
    "p2pl": ("point-to-plane 4/2/1 cm, Tukey", lambda: RegistrationConfig(method="point_to_plane")),
    "fast": ("point-to-plane 2 cm (fast)", fast_point_to_plane),
    "accurate": ("accurate (graph default): colored ICP 4/2 cm, Tukey", _accurate),
    "realtime": (
        "realtime: organised normals, projective colored ICP 2 cm (numpy)",
        realtime_registration,
    ),
    "realtime-gicp": (
        "realtime-gicp: GICP 2 cm (small_gicp) + photometric stage",
        gicp_registration,
    ),
}
GUESSES = ("identity", "constant-velocity")


@dataclass(frozen=True)
class ConfigSummary:
    """Mean stage times and errors of one configuration on one dataset."""

    name: str
    pairs: int
    stage_ms: dict[str, float]
    translation_err_mm: np.ndarray  # per registered pair
    rotation_err_deg: np.ndarray
    statuses: Counter = field(default_factory=Counter)

    @property
    def total_ms(self) -> float:
        return float(sum(self.stage_ms.values()))

    def line(self) -> str:
        stages = ", ".join(f"{s} {self.stage_ms[s]:.1f}" for s in STAGES)
        if self.translation_err_mm.size:
            acc = (
                f"error {self.translation_err_mm.mean():.2f} mm mean / "
                f"{self.translation_err_mm.max():.2f} max, {self.rotation_err_deg.mean():.3f}° "
                f"mean / {self.rotation_err_deg.max():.3f}° max"
            )
        else:
            acc = "no pair registered"
        status = ", ".join(f"{k} {v}" for k, v in sorted(self.statuses.items()))
        return (
            f"  {self.name}\n    per pair (ms): {stages}; total {self.total_ms:.0f} ms "
            f"({1000.0 / max(self.total_ms, 1e-9):.1f} Hz)\n    {acc}; {status}"
        )


@dataclass(frozen=True)
class DatasetReport:
    dataset: str
    points_per_frame: float
    summaries: tuple[ConfigSummary, ...]
    reference: str | None = None

    def lines(self) -> list[str]:
        out = [f"{self.dataset} ({self.points_per_frame:.0f} valid depth pixels per frame)"]
        if self.reference:
            out.append(f"  {self.reference}")
        out += [s.line() for s in self.summaries]
        return out


def initial_guess(data: Dataset, k: int, guess: str) -> np.ndarray:
    """The initial ``camera_k_T_camera_k+1``: identity, or ``constant-velocity`` (the previous
    pair's true motion, as the pipeline's guess from its last two poses; identity for k = 0)."""
    if guess == "identity" or k == 0:
        return np.eye(4)
    if guess == "constant-velocity":
        return relative_truth(data.world_T_camera, k - 1)
    raise ValueError(f"guess must be one of {GUESSES}, got {guess!r}")


def run_config(
    name: str,
    config: RegistrationConfig | GicpConfig | ProjectiveConfig,
    data: Dataset,
    cloud_config: CloudConfig | None = None,
    guess: str = "identity",
) -> ConfigSummary:
    """Register every consecutive pair of ``data`` and time each stage: each frame prepared
    once (:func:`graph_slam.frontend.make_registration`; on the previous frame's grid through
    the guess) and kept as the next pair's target, as the pipeline does."""
    method = make_registration(config, data.intrinsics, cloud_config)
    tally = _Tally.start()
    target = None
    for k, frame in enumerate(data.frames):
        init = None if k == 0 else initial_guess(data, k - 1, guess)
        source = method.prepare(frame, None if k == 0 else target.grid_T_cloud @ init)
        if k > 0:  # the first frame's preparation is not a pair's cost
            for stage, seconds in source.timing_s.items():
                tally.stage_s[stage] += seconds
            tally.pair(lambda s=source, t=target, i=init: method.register(s, t, i), data, k - 1)
        target = source
    return tally.summary(name, len(data.frames) - 1)


@dataclass
class _Tally:
    """Per-stage seconds, errors against the truth and statuses over the pairs of a run."""

    stage_s: dict[str, float]
    t_err: list[float]
    r_err: list[float]
    statuses: Counter

    @classmethod
    def start(cls) -> _Tally:
        return cls(dict.fromkeys(STAGES, 0.0), [], [], Counter())

    def pair(self, register_now, data: Dataset, k: int) -> None:
        """Register pair ``k`` (frame ``k + 1`` onto frame ``k``) and count it."""
        t0 = time.perf_counter()
        try:
            result = register_now()
        except RegistrationError as err:
            self.stage_s["icp"] += time.perf_counter() - t0
            self.statuses[f"failed {err.reason.value}"] += 1
            return
        for stage, seconds in result.timing_s.items():
            self.stage_s[stage] += seconds
        self.statuses[result.status.value] += 1
        t, r = pose_error(result.target_T_source, relative_truth(data.world_T_camera, k))
        self.t_err.append(t * 1e3)
        self.r_err.append(np.degrees(r))

    def summary(self, name: str, pairs: int) -> ConfigSummary:
        return ConfigSummary(
            name=name,
            pairs=pairs,
            stage_ms={s: 1e3 * v / pairs for s, v in self.stage_s.items()},
            translation_err_mm=np.asarray(self.t_err),
            rotation_err_deg=np.asarray(self.r_err),
            statuses=self.statuses,
        )


def run_registration_bench(
    *,
    pairs: int = 10,
    rate_hz: float = 40.0,
    tum_folder: Path | None = None,
    configs: dict[str, Callable[[], RegistrationConfig | GicpConfig]] | None = None,
    progress: Callable[[int, int], None] | None = None,
    sessions: Sequence[Path] = (),
    steps: Sequence[int] = (2, 1),
    guess: str = "identity",
) -> list[DatasetReport]:
    """Run every configuration on the synthetic frames and, when found, the TUM frames; with
    ``sessions``, on each session's first ``pairs + 1`` frames at every decimation ``step``
    instead of the synthetic frames. Open3D on one thread: the same figures every run
    (:mod:`graph_slam.determinism`)."""
    from graph_slam.determinism import apply_threads

    apply_threads(True)
    configs = configs or BENCH_CONFIGS
    if sessions:
        datasets = [session_dataset(p, s, 0, pairs + 1) for p in sessions for s in steps]
    else:
        datasets = [synthetic_dataset(pairs, rate_hz)]
    if tum_folder is not None:  # asked for: it must be there
        datasets.append(read_tum_sample(tum_folder))
    elif not sessions and (default_tum_folder() / "ground_truth.json").is_file():
        datasets.append(read_tum_sample(default_tum_folder()))
    reports, done, total = [], 0, len(datasets) * len(configs)
    warm_up = Dataset(
        "warm-up", datasets[0].intrinsics, datasets[0].frames[:2], datasets[0].world_T_camera[:2]
    )
    for factory in configs.values():  # first calls pay imports and thread start-up
        run_config("warm-up", factory(), warm_up)
    for data in datasets:
        reference = None
        if data.name.startswith("TUM"):
            t0 = time.perf_counter()
            errors = odometry_errors(data, open3d_rgbd_odometry(data))
            ms = 1e3 * (time.perf_counter() - t0) / len(errors)
            reference = (
                f"Open3D RGB-D odometry (reference): error {1e3 * np.nanmean(errors[:, 0]):.2f} mm "
                f"mean / {1e3 * np.nanmax(errors[:, 0]):.2f} max, "
                f"{np.degrees(np.nanmean(errors[:, 1])):.3f}° mean; {ms:.0f} ms per pair"
            )
        summaries = []
        for name, factory in configs.items():
            summaries.append(run_config(name, factory(), data, guess=guess))
            done += 1
            if progress is not None:
                progress(done, total)
        points = np.mean([np.count_nonzero(f.depth_m) for f in data.frames])
        reports.append(DatasetReport(data.name, float(points), tuple(summaries), reference))
    return reports

"""``simulate``: one call from a :class:`SimConfig` to a session folder on disk.

The steps: load the scene and the sensor profiles → build the leg model and the walking
motion → draw which frames survive the drop model → render only those → write IMU, encoders,
events (load cell in ``events.csv``, truth in ``events_truth.csv``), ground truth and scene →
write the resolved config and the quick-look picture next to the session.

Determinism: every random stream has its own generator seeded by ``(seed, stream)``, so the
same config gives the same bytes (the manifest's ``created_utc`` honours
``SOURCE_DATE_EPOCH`` for byte-identical reruns).
"""

from __future__ import annotations

import datetime as _dt
import logging
import math
import os
import time
from collections import deque
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from graph_slam.session.atomic import atomic_folder, check_output
from graph_slam.session.manifest import Provenance
from graph_slam.session.records import Calibration, PoseTrajectory, RgbdFrame
from graph_slam.session.writer import SessionWriter
from graph_slam.sim.config import (
    CameraProfile,
    ImuProfile,
    ProsthesisProfile,
    SimConfig,
    load_profile,
)
from graph_slam.sim.motion import GaitMotion
from graph_slam.sim.render import Renderer, image_size, intrinsics_for
from graph_slam.sim.scene import load_scene
from graph_slam.sim.sensors import (
    frame_schedule,
    load_cell_events,
    simulate_encoders,
    simulate_imu,
    true_events,
)

logger = logging.getLogger(__name__)

CONFIG_NAME = "sim_config.yaml"
EVENTS_TRUTH_NAME = "events_truth.csv"
MOCAP_RATE_HZ = 200.0

# Random streams (one generator each, seeded by (seed, stream)).
_DROPS, _DEPTH, _IMU, _ENCODERS, _LOAD_CELL = 1, 2, 3, 4, 5


@dataclass
class SimResult:
    """What a simulation wrote, with its headline figures."""

    path: Path
    frames: int
    nominal_frames: int
    duration_s: float
    frames_per_stride: np.ndarray
    stride_times_s: np.ndarray
    mean_speed_m_s: float
    timings_s: dict[str, float] = field(default_factory=dict)
    simulation: Simulation | None = field(default=None, repr=False)
    """The run's setup (scene, motion, profiles): what the quick-look draws."""

    @property
    def effective_rate_hz(self) -> float:
        return self.frames / self.duration_s

    def lines(self) -> list[str]:
        fps = self.frames_per_stride
        return [
            f"wrote {self.path}: {self.frames} of {self.nominal_frames} nominal frames over "
            f"{self.duration_s:.2f} s (effective {self.effective_rate_hz:.1f} Hz)",
            f"{fps.size} strides, frames per stride {fps.min()}–{fps.max()} "
            f"(mean {fps.mean():.1f}); stride time {self.stride_times_s.mean():.3f} s; "
            f"walking speed {self.mean_speed_m_s:.2f} m/s",
            "time: " + ", ".join(f"{k} {v:.1f} s" for k, v in self.timings_s.items()),
        ]


@dataclass
class Simulation:
    """Everything of a run but the rendered frames (built by :func:`prepare`)."""

    cfg: SimConfig
    scene: object
    camera: CameraProfile
    imu: ImuProfile
    prosthesis: ProsthesisProfile
    motion: GaitMotion  # or graph_slam.sim.walker.TerrainMotion (same interface)
    thigh_T_camera: np.ndarray
    thigh_T_imu: np.ndarray
    frame_times_s: np.ndarray
    nominal_frames: int

    @property
    def calibration(self) -> Calibration:
        return Calibration(
            thigh_T_camera=self.thigh_T_camera,
            camera_T_imu=np.linalg.inv(self.thigh_T_camera) @ self.thigh_T_imu,
            imu_time_offset_s=self.cfg.imu_time_offset_s,
            joints_time_offset_s=0.0,
        )


def prepare(cfg: SimConfig) -> Simulation:
    """Load scene and profiles, build the motion and the frame schedule (no rendering)."""
    from kinematics.leg_model import LegModel
    from kinematics.leg_params import LegParams

    scene = load_scene(cfg.scene)
    camera = load_profile(CameraProfile, cfg.camera)
    imu = load_profile(ImuProfile, cfg.imu)
    prosthesis = load_profile(ProsthesisProfile, cfg.prosthesis)
    if cfg.drops is not None:
        camera = camera.model_copy(
            update={"drops": camera.drops.model_copy(update={"model": cfg.drops})}
        )
    image_size(camera, cfg.fast, cfg.resolution)  # a wrong size fails before any work
    leg = LegParams(mount_pitch_down_rad=math.radians(cfg.mount_pitch_deg))
    model = LegModel(leg)
    if scene.spec.walk == "terrain":
        from graph_slam.sim.walker import TerrainMotion

        motion = TerrainMotion(
            cfg.speed_m_s, cfg.strides, cfg.seed, scene.surfaces, leg, cfg.motion
        )
    else:
        motion = GaitMotion(cfg.speed_m_s, cfg.strides, cfg.seed, leg, cfg.motion)
    t_frames, _ = frame_schedule(
        motion.duration_s, camera.rate_hz, camera.drops, np.random.default_rng([cfg.seed, _DROPS])
    )
    return Simulation(
        cfg=cfg,
        scene=scene,
        camera=camera,
        imu=imu,
        prosthesis=prosthesis,
        motion=motion,
        thigh_T_camera=model.thigh_T_frame("camera_optical"),
        thigh_T_imu=model.thigh_T_frame("imu"),
        frame_times_s=t_frames,
        nominal_frames=math.floor(motion.duration_s * camera.rate_hz) + 1,
    )


def _created_utc() -> str:
    epoch = os.environ.get("SOURCE_DATE_EPOCH")
    moment = _dt.datetime.fromtimestamp(int(epoch), _dt.UTC) if epoch else _dt.datetime.now(_dt.UTC)
    return moment.replace(microsecond=0).isoformat()


def simulate(
    cfg: SimConfig,
    out: str | Path,
    *,
    overwrite: bool = False,
    progress: Callable[[int, int], None] | None = None,
) -> SimResult:
    """Simulate a walk and write the session (plus its resolved config) to ``out``.

    The quick-look picture is the caller's step:
    :func:`graph_slam.sim.quicklook.write_quicklook` (``graph-slam simulate`` draws it when
    ``cfg.quicklook``).
    """
    check_output(out, overwrite=overwrite, command="simulate")  # before any work
    clock = time.perf_counter()
    timings: dict[str, float] = {}
    sim = prepare(cfg)
    motion, camera = sim.motion, sim.camera
    intrinsics = intrinsics_for(camera, cfg.fast, cfg.resolution)
    renderer = Renderer(
        sim.scene, intrinsics, camera, noise_scale=cfg.noise_scale, motion_blur=cfg.motion_blur
    )
    t_frames = sim.frame_times_s
    world_T_camera = motion.world_T(t_frames, sim.thigh_T_camera)
    gyro_camera, _ = motion.imu_ideal(t_frames, sim.thigh_T_camera)
    timings["setup"] = time.perf_counter() - clock
    imu_rate = cfg.imu_rate_hz or sim.imu.rate_hz
    notes = (
        f"graph_slam.sim: scene {sim.scene.name}, {cfg.strides} strides at {cfg.speed_m_s} m/s, "
        f"camera {camera.name} ({camera.drops.model} drops), mount pitch {cfg.mount_pitch_deg} deg. "
        f"events.csv holds the load-cell events; the true events are in {EVENTS_TRUTH_NAME}; "
        f"the resolved config is {CONFIG_NAME}."
    )
    with atomic_folder(out, overwrite=overwrite, command="simulate", create=False) as tmp:
        writer = SessionWriter(
            tmp,
            name=f"sim-{sim.scene.name}-{cfg.speed_m_s:g}mps-seed{cfg.seed}",
            intrinsics=intrinsics,
            depth_unit_m=camera.depth_unit_m,
            camera_profile=camera.name,
            camera_rate_hz=camera.rate_hz,
            imu_profile=sim.imu.name,
            imu_rate_hz=imu_rate,
            joints_rate_hz=sim.prosthesis.encoder_rate_hz,
            calibration=sim.calibration,
            provenance=Provenance(
                generator="graph_slam.sim",
                source=f"scene:{sim.scene.name}",
                seed=cfg.seed,
                created_utc=_created_utc(),
                notes=notes,
            ),
        )
        clock = time.perf_counter()
        rng_depth = np.random.default_rng([cfg.seed, _DEPTH])
        with writer, ThreadPoolExecutor(max_workers=1) as png_worker:
            # PNG encoding (zlib releases the GIL) overlaps the rendering of the next frame; one
            # worker keeps the frames in order.
            pending: deque[Future] = deque()
            for i, t in enumerate(t_frames):
                depth, color = renderer.render(world_T_camera[i], rng_depth, gyro_camera[i])
                frame = RgbdFrame(float(t), depth, color, index=i)
                pending.append(png_worker.submit(writer.add_frame, frame))
                while len(pending) > 2:
                    pending.popleft().result()
                if progress is not None:
                    progress(i + 1, t_frames.size)
            while pending:
                pending.popleft().result()
            timings["render+write frames"] = time.perf_counter() - clock
            clock = time.perf_counter()
            imu, _ = simulate_imu(
                motion,
                sim.thigh_T_imu,
                sim.imu,
                np.random.default_rng([cfg.seed, _IMU]),
                rate_hz=imu_rate,
                noise_scale=cfg.noise_scale,
                accel_range_g=cfg.accel_range_g,
                time_offset_s=cfg.imu_time_offset_s,
            )
            joints, _ = simulate_encoders(
                motion,
                sim.prosthesis,
                np.random.default_rng([cfg.seed, _ENCODERS]),
                noise_scale=cfg.noise_scale,
            )
            writer.write_imu(imu)
            writer.write_joints(joints)
            # The true events go to their own file; events.csv (written last, so the manifest
            # points at it) holds what a real prosthesis has: the load cell's events.
            writer.write_events(true_events(motion), filename=EVENTS_TRUTH_NAME)
            writer.write_events(
                load_cell_events(
                    motion,
                    sim.prosthesis,
                    np.random.default_rng([cfg.seed, _LOAD_CELL]),
                    noise_scale=cfg.noise_scale,
                )
            )
            writer.write_ground_truth(PoseTrajectory(t_frames, world_T_camera))
            t_hf = np.arange(math.floor(motion.duration_s * MOCAP_RATE_HZ) + 1) / MOCAP_RATE_HZ
            writer.write_ground_truth(
                PoseTrajectory(t_hf, motion.world_T(t_hf, sim.thigh_T_camera)), high_rate=True
            )
            writer.write_scene(sim.scene.truth())
            if sim.scene.spec.walk == "terrain":
                from graph_slam.sim.terrain_truth import write_terrain_truth

                write_terrain_truth(tmp, motion, sim.scene, motion.duration_s)
        path = Path(out)
        strikes = motion.foot_strikes_s
        per_stride = np.histogram(t_frames, bins=strikes)[0]
        result = SimResult(
            path=path,
            frames=int(t_frames.size),
            nominal_frames=sim.nominal_frames,
            duration_s=motion.duration_s,
            frames_per_stride=per_stride,
            stride_times_s=np.diff(strikes),
            mean_speed_m_s=motion.mean_speed_m_s,
            simulation=sim,
        )
        write_resolved_config(sim, tmp / CONFIG_NAME, result)
    timings["streams"] = time.perf_counter() - clock
    result.timings_s = timings
    return result


def write_resolved_config(sim: Simulation, path: Path, result: SimResult) -> Path:
    """The run's settings, the profiles and scene it loaded, and the derived figures."""
    data = {
        "sim": sim.cfg.model_dump(mode="json"),
        "camera_profile": sim.camera.model_dump(mode="json"),
        "imu_profile": sim.imu.model_dump(mode="json"),
        "prosthesis_profile": sim.prosthesis.model_dump(mode="json"),
        "scene": sim.scene.spec.model_dump(mode="json"),
        "leg": {
            k: (list(v) if isinstance(v, tuple) else v) for k, v in sim.motion.leg.to_dict().items()
        },
        "derived": {
            "frames": result.frames,
            "nominal_frames": result.nominal_frames,
            "duration_s": round(result.duration_s, 6),
            "effective_rate_hz": round(result.effective_rate_hz, 3),
            "frames_per_stride": result.frames_per_stride.tolist(),
            "foot_strikes_s": [round(float(t), 6) for t in sim.motion.foot_strikes_s],
            "mean_speed_m_s": round(result.mean_speed_m_s, 4),
        },
    }
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return path

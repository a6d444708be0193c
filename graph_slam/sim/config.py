"""Typed configuration of the simulator and its sensor profiles.

:class:`SimConfig` is what a run needs (scene, speed, strides, seed, profiles, options); the
sensor profiles are YAML files under ``models/sensors/`` loaded into :class:`CameraProfile`,
:class:`ImuProfile` and :class:`ProsthesisProfile`. Every run writes the resolved config (the
run settings and the profiles it loaded) next to the session (``sim_config.yaml``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal, TypeVar

import yaml
from pydantic import Field, model_validator

from graph_slam.config import ConfigModel, config_from_dict, yaml_error_text
from graph_slam.errors import ConfigError, SimulationError

#: Named walking speeds of the thesis's experiments (m/s).
SPEEDS_M_S: dict[str, float] = {"slow": 0.8, "normal": 1.1, "fast": 1.4}

P = TypeVar("P", bound=ConfigModel)


class MotionConfig(ConfigModel):
    """Gait-driven walking motion (graph_slam.sim.motion)."""

    stride_time_cv: float = Field(
        0.02, ge=0, le=0.1, description="stride-to-stride variability of the stride time (CV)"
    )
    lateral_step_sigma_m: float = Field(
        0.01, ge=0, le=0.05, description="σ of the lateral foot placement, per stride"
    )
    swing_roll_deg: float = Field(
        2.0, ge=0, le=10, description="mean frontal-plane thigh roll bump in swing (abduction)"
    )
    swing_yaw_deg: float = Field(
        3.0, ge=0, le=15, description="mean transverse thigh yaw bump in swing (rotation)"
    )
    swing_lateral_m: float = Field(
        0.015, ge=0, le=0.06, description="mean lateral hip excursion in swing (pelvis sway)"
    )
    flat_foot_deg: float = Field(
        1.0, ge=0, le=6, description="foot pitch band |γ| < this is forced flat (foot flat)"
    )
    flat_blend_deg: float = Field(6.0, gt=0, le=10, description="C2 blend width to the band")
    swing_dorsiflexion_deg: float = Field(
        10.0, ge=0, le=25, description="extra ankle dorsiflexion in swing (toe clearance)"
    )
    heel_shock_m_s2: float = Field(
        15.0, ge=0, le=60, description="peak of the thigh IMU's heel-contact burst (0: none)"
    )
    lead_in_s: float = Field(0.25, ge=0, le=0.3, description="recording before the first strike")
    lead_out_s: float = Field(0.1, ge=0, le=2, description="recording after the last strike")
    grid_hz: float = Field(2000.0, ge=500, le=20000, description="event-search grid rate")


class SimConfig(ConfigModel):
    """One simulation run: ``graph-slam simulate`` fills it from its options."""

    scene: str = Field("thesis-boxes", description="models/scenes/<name>.yaml or a YAML path")
    speed_m_s: float = Field(1.1, ge=0.6, le=1.8, description="walking speed (gait curves)")
    strides: int = Field(9, ge=1, le=1000, description="complete strides of the prosthetic leg")
    seed: int = Field(1, ge=0)
    camera: str = Field("d455", description="camera profile models/sensors/<name>.yaml")
    imu: str = Field("thigh_imu", description="IMU profile models/sensors/<name>.yaml")
    prosthesis: str = Field("prosthesis", description="encoders + load cell profile")
    drops: Literal["none", "random", "bursty"] | None = Field(
        None, description="frame-drop model; None = the camera profile's default"
    )
    mount_pitch_deg: float = Field(35.0, ge=30, le=45, description="camera below horizontal")
    noise_scale: float = Field(1.0, ge=0, le=10, description="multiplies every noise σ")
    fast: bool = Field(
        False, description="quarter resolution (tests, previews): the D455's 212x120"
    )
    resolution: str | None = Field(
        None,
        pattern=r"^[1-9][0-9]*x[1-9][0-9]*$",
        description="image size WIDTHxHEIGHT, the profile's size divided by one factor on "
        "both axes (the D455's real-time modes 848x480, 424x240, 212x120); None = the "
        "profile's size (or a quarter of it with fast)",
    )
    imu_rate_hz: float | None = Field(None, gt=0, le=4000, description="override the profile")
    accel_range_g: float | None = Field(
        None, gt=0, le=64, description="accelerometer saturation (±g); None = profile"
    )
    imu_time_offset_s: float = Field(0.0, ge=-0.5, le=0.5, description="IMU clock offset")
    motion_blur: bool = True
    quicklook: bool = Field(True, description="graph-slam simulate draws quicklook.png")
    motion: MotionConfig = MotionConfig()

    @model_validator(mode="after")
    def _one_size(self) -> SimConfig:
        if self.fast and self.resolution is not None:
            raise ValueError("set either fast (a quarter of the profile's size) or resolution")
        return self


class DepthNoise(ConfigModel):
    """Depth noise: σ(z) = sigma_at_1m_m · z^exponent (+ floor); dropouts at edges."""

    sigma_at_1m_m: float = Field(ge=0)
    exponent: float = Field(2.0, ge=0, le=3)
    sigma_floor_m: float = Field(0.0, ge=0)
    edge_threshold_m: float = Field(0.03, gt=0, description="depth jump that marks an edge")
    edge_dropout_prob: float = Field(0.5, ge=0, le=1)
    flying_pixel_prob: float = Field(0.2, ge=0, le=1)
    random_dropout_prob: float = Field(0.002, ge=0, le=1)
    grazing_cos_min: float = Field(0.12, ge=0, lt=1, description="invalid below this cos(inc.)")


class DropModel(ConfigModel):
    """Frame drops (thesis: 90 Hz recorded as 35-40 Hz) and capture-time jitter."""

    model: Literal["none", "random", "bursty"] = "bursty"
    keep_prob: float = Field(0.42, gt=0, le=1, description="random: P(frame kept)")
    good_keep_prob: float = Field(0.95, gt=0, le=1, description="bursty: P(kept) when good")
    bad_keep_prob: float = Field(0.1, ge=0, le=1, description="bursty: P(kept) in a burst")
    p_good_to_bad: float = Field(0.2, ge=0, le=1)
    p_bad_to_good: float = Field(0.125, gt=0, le=1)
    jitter_s: float = Field(0.0004, ge=0, le=0.005, description="σ of the capture-time jitter")


class CameraProfile(ConfigModel):
    """A depth (RGB-D) camera: image, rate, range, noise, drops; see models/sensors/."""

    name: str
    description: str = ""
    width_px: int = Field(gt=0)
    height_px: int = Field(gt=0)
    fov_x_deg: float = Field(gt=10, lt=170, description="along the image x axis")
    fov_y_deg: float = Field(gt=10, lt=170, description="along the image y axis")
    rate_hz: float = Field(gt=0, le=1000)
    color: bool = True
    depth_unit_m: float = Field(1e-4, gt=0, le=0.01)
    min_range_m: float = Field(gt=0)
    max_range_m: float = Field(gt=0)
    exposure_s: float = Field(0.008, ge=0, le=0.05, description="colour exposure (blur)")
    noise: DepthNoise
    drops: DropModel = DropModel()
    sources: tuple[str, ...] = ()

    @model_validator(mode="after")
    def _range(self) -> CameraProfile:
        if self.max_range_m <= self.min_range_m:
            raise ValueError("max_range_m must be larger than min_range_m")
        return self


class ImuProfile(ConfigModel):
    """A MEMS IMU: continuous-time noise densities (Kalibr convention) and ranges."""

    name: str
    description: str = ""
    rate_hz: float = Field(200.0, gt=0, le=4000)
    gyro_noise_density_rad_s_sqrt_hz: float = Field(ge=0)
    gyro_random_walk_rad_s2_sqrt_hz: float = Field(ge=0)
    accel_noise_density_m_s2_sqrt_hz: float = Field(ge=0)
    accel_random_walk_m_s3_sqrt_hz: float = Field(ge=0)
    gyro_bias_sigma_rad_s: float = Field(0.005, ge=0, description="turn-on bias σ")
    accel_bias_sigma_m_s2: float = Field(0.05, ge=0, description="turn-on bias σ")
    accel_range_g: float | None = Field(None, gt=0)
    gyro_range_rad_s: float | None = Field(34.9, gt=0)
    sources: tuple[str, ...] = ()


class ProsthesisProfile(ConfigModel):
    """Knee/ankle encoders and the load cell of the prosthesis."""

    name: str
    description: str = ""
    encoder_rate_hz: float = Field(500.0, gt=0, le=10000)
    encoder_bits: int = Field(14, ge=6, le=24, description="counts per turn = 2^bits")
    encoder_noise_rad: float = Field(0.0005, ge=0)
    load_cell_latency_s: float = Field(0.015, ge=0, le=0.2)
    load_cell_jitter_s: float = Field(0.003, ge=0, le=0.05)
    sources: tuple[str, ...] = ()


def load_model_config(cls: type[P], folder: str, what: str, name_or_path: str) -> tuple[P, Path]:
    """Load ``models/<folder>/<name>.yaml`` (or a YAML file path) into ``cls``.

    Errors are :class:`SimulationError` naming the file (or the known names) and the field.
    """
    from graph_slam_models import model_path

    path = Path(name_or_path)
    if path.suffix not in (".yaml", ".yml"):
        try:
            path = model_path(f"{folder}/{name_or_path}.yaml")
        except (FileNotFoundError, ValueError):
            raise SimulationError(
                f"{what} {name_or_path!r}: no file models/{folder}/{name_or_path}.yaml "
                f"(known: {', '.join(known_names(folder))})"
            ) from None
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
    except OSError as err:
        raise SimulationError(f"{path}: cannot read {what} ({err.strerror})") from None
    except UnicodeDecodeError as err:
        raise SimulationError(f"{path}: {what} is not UTF-8 text (byte {err.start})") from None
    except yaml.YAMLError as err:
        raise SimulationError(f"{path}: {yaml_error_text(err)}") from None
    try:
        return config_from_dict(cls, data, source=str(path)), path
    except ConfigError as err:
        raise SimulationError(str(err)) from None


def load_profile(cls: type[P], name_or_path: str) -> P:
    """Load a profile by name (``models/sensors/<name>.yaml``) or by file path."""
    return load_model_config(cls, "sensors", "sensor profile", name_or_path)[0]


def known_names(folder: str) -> list[str]:
    """Names of the shipped YAML files in ``models/<folder>``."""
    from graph_slam_models import MODELS_DIR

    return sorted(p.stem for p in (MODELS_DIR / folder).glob("*.yaml"))

"""Named settings of a whole pipeline (:data:`PIPELINE_PRESETS`), applied under a config's
explicit fields (``PipelineConfig.preset``) or over them (:func:`with_preset`), and the
``VARIANT[:PRESET]`` rows of the benchmarks (:func:`parse_row`)."""

from __future__ import annotations

from typing import Any, Literal

from graph_slam.config import merge_dicts
from graph_slam.variants import Variant

VARIANT_NAMES = frozenset(v.value for v in Variant)

PresetName = Literal["realtime", "realtime-gicp", "accurate", "thesis"]
"""The names of :data:`PIPELINE_PRESETS`."""
DEFAULT_PRESET = "realtime"
"""The configuration every entry point runs by default (library, ``run``, ``compare``,
``batch``, ``demo``, the examples)."""


#: Named settings of a whole pipeline: ``PipelineConfig.preset`` (under the explicit fields)
#: or ``with_preset`` (over a config: the ``VARIANT:PRESET`` rows of the benchmarks,
#: ``--preset``). Each preset sets every field any preset sets, so one applied over a config
#: built from another leaves nothing of the other behind. ``realtime`` (the default): the
#: real-time registration preset with the IMU's initial guess, iSAM2 as the stride's smoother
#: (``backend.smoothing: false``: a stride's smoothed poses are iSAM2's estimate at its close
#: plus one Gauss-Newton step, no batch LM; measured on the 424×240 sessions,
#: docs/benchmarks.md), that step and the end-state marginals on the frame after the foot
#: strike (``backend.end_state: next_frame``: the strike's frame already carries the floor
#: fit), the online grid without kept clouds (``terrain.online.keep_clouds: false``: no
#: re-fusion at the close; the stride's grid is the online one), no stride maps (fusing a
#: stride's map at its close takes 0.3–1.2 s at 424×240, which the real-time path cannot
#: afford; ``compare`` turns them on to score them) and the thesis baseline on the 212×120
#: cloud (``baseline.pixel_step`` None). ``accurate`` and ``thesis``: colored ICP (4/2 cm with
#: a Tukey kernel; the thesis's 4/2/1 cm without), batch smoothing at the close, stride maps
#: from kept clouds, the baseline on every pixel. The terrain for the controller is the
#: incremental grid updated at every frame (``terrain.online``, docs/terrain.md), on in every
#: preset.
_REALTIME_REST: dict[str, Any] = {
    "backend": {"smoothing": False, "end_state": "next_frame"},
    "terrain": {"enabled": False, "online": {"enabled": True, "keep_clouds": False}},
    "baseline": {"pixel_step": None},
}
_ACCURATE_REST: dict[str, Any] = {
    "backend": {"smoothing": True, "end_state": "at_close"},
    "terrain": {"enabled": True, "online": {"enabled": True, "keep_clouds": True}},
    "baseline": {"pixel_step": 1},
}
PIPELINE_PRESETS: dict[str, dict[str, Any]] = {
    "realtime": {"graph": {"registration": "realtime", "imu_guess": True}, **_REALTIME_REST},
    "realtime-gicp": {
        "graph": {"registration": "realtime-gicp", "imu_guess": True},
        **_REALTIME_REST,
    },
    "accurate": {"graph": {"registration": "accurate", "imu_guess": None}, **_ACCURATE_REST},
    "thesis": {"graph": {"registration": "thesis", "imu_guess": None}, **_ACCURATE_REST},
}


def with_preset(data: dict[str, Any], preset: str) -> dict[str, Any]:
    """``data`` (a ``PipelineConfig`` as a dict) with the named preset's settings merged over
    it and ``preset`` set; a :class:`ConfigError` naming the presets when ``preset`` is
    unknown."""
    from graph_slam.errors import ConfigError

    if preset not in PIPELINE_PRESETS:
        raise ConfigError(
            f"unknown pipeline preset {preset!r}; choose from {', '.join(PIPELINE_PRESETS)}"
        )

    return {**merge_dicts(data, PIPELINE_PRESETS[preset]), "preset": preset}


def parse_row(row: str) -> tuple[Variant, str | None]:
    """``VARIANT[:PRESET]`` (a benchmark row, ``--variants``-style) → the variant and the
    preset (None when the row names none); a :class:`ConfigError` naming the row when either
    is unknown."""
    from graph_slam.errors import ConfigError

    name, _, preset = row.strip().partition(":")
    if name not in VARIANT_NAMES:
        raise ConfigError(
            f"row {row!r}: unknown variant {name!r} (known: {', '.join(v.value for v in Variant)})"
        )
    if preset and preset not in PIPELINE_PRESETS:
        raise ConfigError(
            f"row {row!r}: unknown pipeline preset {preset!r}; choose from "
            f"{', '.join(PIPELINE_PRESETS)}"
        )
    return Variant(name), preset or None

"""The pipeline variants: one type for every layer (configs, pipelines, reports, benchmarks).

``icp`` is the thesis baseline (reset at foot strike, ICP to the stride's map, no graph); the
others are the per-stride factor graph with the named factor families.
"""

from __future__ import annotations

from enum import StrEnum

from graph_slam.errors import ConfigError


class Variant(StrEnum):
    """A pipeline variant; its value is the name used in configs, reports and on the CLI."""

    ICP = "icp"
    ICP_IMU = "icp+imu"
    IMU_KIN = "imu+kin"
    ICP_IMU_KIN = "icp+imu+kin"

    @property
    def is_baseline(self) -> bool:
        """The thesis pipeline (no factor graph, no smoother: its smoothed poses are its
        online ones)."""
        return self is Variant.ICP

    @property
    def factors(self) -> dict[str, bool]:
        """Which factor families the graph uses (``icp``, ``imu``, ``kin``)."""
        if self.is_baseline:
            raise ConfigError("variant 'icp' is the thesis baseline: it has no factor graph")
        return {f: f in self.value.split("+") for f in ("icp", "imu", "kin")}

    @property
    def tag(self) -> str:
        """File-name form (``icp_imu_kin``)."""
        return self.value.replace("+", "_")


VARIANTS: tuple[Variant, ...] = tuple(Variant)
GRAPH_VARIANTS: tuple[Variant, ...] = tuple(v for v in Variant if not v.is_baseline)


def parse_variants(text: str, field: str = "--variants") -> list[Variant]:
    """``"icp,icp+imu+kin"`` → variants, in order; a :class:`ConfigError` naming the unknown
    ones and the choices."""
    names = [n.strip() for n in text.split(",") if n.strip()]
    bad = [n for n in names if n not in VARIANTS]
    if bad or not names:
        raise ConfigError(
            f"{field}: {', '.join(bad) or '(empty)'} not known; choose from {', '.join(VARIANTS)}"
        )
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise ConfigError(f"{field}: {', '.join(twice)} listed more than once; list each once")
    return [Variant(n) for n in names]

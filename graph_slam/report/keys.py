"""Typed keys of a report: a variant and the kind of its poses (online or smoothed).

``str(key)`` is the name the report and ``metrics.json`` use: ``icp+imu+kin`` for the online
poses, ``icp+imu+kin smoothed`` for the smoothed ones. The baseline has no smoother, so it has
only its online key; its maps are fused from those poses.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

from graph_slam.variants import Variant


class Kind(StrEnum):
    ONLINE = "online"
    SMOOTHED = "smoothed"


@dataclass(frozen=True, order=True)
class RunKey:
    variant: Variant
    kind: Kind = Kind.ONLINE

    def __str__(self) -> str:
        return str(self.variant) if self.kind is Kind.ONLINE else f"{self.variant} smoothed"

    @property
    def tag(self) -> str:
        """File-name form (``icp_imu_kin_smoothed``)."""
        return str(self).replace("+", "_").replace(" ", "_")


def run_keys(variants) -> list[RunKey]:
    """Every variant's online key, then the smoothed keys of the graph variants."""
    keys = [RunKey(Variant(v)) for v in variants]
    keys += [RunKey(Variant(v), Kind.SMOOTHED) for v in variants if not Variant(v).is_baseline]
    return keys


@dataclass(frozen=True)
class MapSource:
    """Where a stride's map came from: a variant's poses (its smoothed ones for the graph, the
    online ones for the baseline) or the ground truth (``variant`` None)."""

    variant: Variant | None = None

    @property
    def is_truth(self) -> bool:
        return self.variant is None

    @property
    def poses(self) -> str:
        """What the report calls the poses the map came from."""
        if self.variant is None:
            return "ground truth"
        return Kind.ONLINE if self.variant.is_baseline else Kind.SMOOTHED

    @property
    def map_kind(self) -> Kind:
        """Which of the pipeline's stride maps it is: the smoothed one (for the baseline that
        is the map of its online poses: it has no smoother)."""
        return Kind.SMOOTHED

    def __str__(self) -> str:
        return "ground truth" if self.variant is None else str(self.variant)

    @property
    def title(self) -> str:
        return f"{self} poses" if self.is_truth else f"{self} ({self.poses} poses)"

    @property
    def tag(self) -> str:
        return str(self).replace("+", "_").replace(" ", "_")

"""How the terrain-following walker moves on each terrain (:data:`GAIT`, per stride label).

Values are chosen so the walker's joint angles land near the published means of each
activity (docs/simulator.md has the table): level walking plays the stance knee of the
level curves (Schwartz et al. 2008), a ramp adds knee flexion at the strike (up) or in
mid-stance (down) as in McIntosh et al. 2006, stairs follow Riener et al. 2002. The toe
rocker of level walking and ramps (48-50° of heel rise at toe-off) puts the ankle near the
−20° of push-off (Winter 2009), which leaves it room to dorsiflex in swing; the least swing
lift (5-6 cm) gives the swing knee peaks of Schwartz et al. 2008 from slow to fast walking.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Gait:
    """Per-activity shape of a stride (distances in m; angles in degrees)."""

    time_factor: float
    """Stride time over the level stride time at the speed."""
    heel_rocker_deg: float
    """Toe-up pitch (relative to the surface) at the strike, rolling over the heel."""
    toe_rocker_deg: float
    """Heel-up pitch at toe-off, rolling over the toe."""
    flat_from: float
    """Stance fraction where the heel rocker ends."""
    toe_from: float
    """Stance fraction where the toe rocker starts."""
    lift_m: float
    """Least swing lift amplitude (raised until the edges are cleared)."""
    knee_deg: tuple[tuple[float, float], ...] = ()
    """Stance knee flexion knots (stance fraction, deg); () = the level curve at the speed."""
    knee_extra_deg: tuple[float, float] = (0.0, 0.0)
    """Added to the level curve: at the strike (fading by 60 % of stance), at mid-stance."""
    back_per_stride: float = 0.0
    """> 0: the hip is this fraction of the arriving stride behind the ankle at the strike."""
    hip_back_m: float = 0.0
    """With ``back_per_stride`` 0: the hip's x − the ankle's at the strike (m)."""
    ankle_max_deg: float = 18.0
    """Stance dorsiflexion cap: past it the heel rises (the foot rolls over the toe).
    Below the URDF's 20° limit; level walking stays under ~15° (Winter 2009), stairs and
    ramps reach 20–25° (Riener et al. 2002, Protopapadaki et al. 2007, McIntosh et al. 2006)."""
    ankle_min_deg: float = -22.0
    """Plantarflexion floor: the heel rises no further at toe-off once the ankle reaches it
    (level walking: −20 ± 5° at toe-off, Winter 2009; above the URDF's −30° limit)."""


_LEVEL = dict(heel_rocker_deg=12.0, toe_rocker_deg=50.0, flat_from=0.20, toe_from=0.55)
_STEP = dict(heel_rocker_deg=6.0, toe_rocker_deg=30.0, flat_from=0.15, toe_from=0.55)

GAIT: dict[str, Gait] = {
    "level": Gait(1.0, **_LEVEL, lift_m=0.05, back_per_stride=0.25, ankle_max_deg=13.5),
    "ramp_up": Gait(1.05, 14.0, 48.0, 0.20, 0.55, lift_m=0.06, back_per_stride=0.25,
                    knee_extra_deg=(10.0, 0.0)),
    "ramp_down": Gait(1.05, 10.0, 48.0, 0.20, 0.55, lift_m=0.05, back_per_stride=0.25,
                      knee_extra_deg=(0.0, 12.0)),
    "stairs_up": Gait(1.25, 0.0, 18.0, 0.05, 0.60, lift_m=0.20, hip_back_m=-0.25,
                      knee_deg=((0.0, 58.0), (0.35, 30.0), (0.7, 10.0), (1.0, 22.0))),
    # the toe overhangs the nosing: the foot stays flat and leaves flat
    "stairs_down": Gait(1.15, 0.0, 0.0, 0.05, 0.60, lift_m=0.12, hip_back_m=-0.12,
                        knee_deg=((0.0, 12.0), (0.25, 28.0), (0.6, 55.0), (1.0, 85.0))),
    "curb_up": Gait(1.1, **_STEP, lift_m=0.06, back_per_stride=0.22, knee_extra_deg=(25.0, 0.0)),
    "curb_down": Gait(1.1, **_STEP, lift_m=0.03, back_per_stride=0.22, knee_extra_deg=(0.0, 15.0)),
    "step_over": Gait(1.1, **_LEVEL, lift_m=0.06, back_per_stride=0.25),
    "step_onto": Gait(1.1, **_STEP, lift_m=0.06, back_per_stride=0.22, knee_extra_deg=(25.0, 0.0)),
}  # fmt: skip

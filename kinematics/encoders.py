"""Joint-encoder validation: channel mapping, NaN, joint limits and impossible jumps.

Nothing is repaired: every sample that cannot be used is flagged with its reason and counted,
and the caller gets a mask of the usable samples (a warning is logged when any is flagged).

Rules (per joint, per sample):

* ``nan``: the value is NaN or infinite;
* ``out_of_limits``: outside the URDF joint limits (plus ``limit_tolerance_rad``);
* ``jump``: the change from the last *accepted* sample of that joint is larger than the
  joint's URDF velocity limit times the elapsed time plus ``noise_tolerance_rad``. Comparing
  with the last accepted sample (not the previous one) flags a single spike once, not twice.

A sample (row) is usable only when all its joints are.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from kinematics.errors import EncoderError
from kinematics.leg_model import LegModel

logger = logging.getLogger(__name__)

REASONS: tuple[str, ...] = ("nan", "out_of_limits", "jump")


@dataclass(frozen=True)
class EncoderCheck:
    """Result of :func:`check_encoders`."""

    t_s: np.ndarray
    q_rad: np.ndarray
    """(N, 2) joint angles in the model's joint order (knee, ankle), as measured."""
    joint_names: tuple[str, ...]
    flags: dict[str, np.ndarray] = field(repr=False)
    """reason -> (N, 2) bool; True where that joint's sample breaks that rule."""

    @property
    def usable(self) -> np.ndarray:
        """(N,) bool: rows whose every joint passed every rule."""
        bad = np.zeros(self.q_rad.shape, dtype=bool)
        for mask in self.flags.values():
            bad |= mask
        return ~bad.any(axis=1)

    @property
    def counts(self) -> dict[str, dict[str, int]]:
        """reason -> joint -> number of flagged samples."""
        return {
            reason: {j: int(mask[:, i].sum()) for i, j in enumerate(self.joint_names)}
            for reason, mask in self.flags.items()
        }

    @property
    def n_samples(self) -> int:
        return int(self.q_rad.shape[0])

    @property
    def n_usable(self) -> int:
        return int(self.usable.sum())

    def summary(self) -> str:
        """One line: how many samples were used and why the others were not."""
        parts = [
            f"{reason} {sum(c.values())} ({', '.join(f'{j} {n}' for j, n in c.items())})"
            for reason, c in self.counts.items()
        ]
        return f"encoders: {self.n_usable}/{self.n_samples} samples usable; flagged: " + "; ".join(
            parts
        )


def check_encoders(
    t_s: Sequence[float] | np.ndarray,
    values: np.ndarray,
    channel_names: Sequence[str],
    model: LegModel,
    *,
    noise_tolerance_rad: float = 0.01,
    limit_tolerance_rad: float = 0.0,
    source: str = "<encoders>",
) -> EncoderCheck:
    """Map encoder channels to the model's joints and flag unusable samples.

    ``values`` is (N, C) in the order of ``channel_names``; the channels must be exactly the
    URDF's joints (else :class:`~kinematics.errors.LegModelError` listing both). ``t_s`` must
    be finite and strictly increasing (else :class:`EncoderError`).
    """
    t = np.asarray(t_s, dtype=float)
    v = np.asarray(values, dtype=float)
    if v.ndim != 2 or v.shape[0] != t.shape[0] or t.ndim != 1:
        raise EncoderError(
            f"{source}: need t_s (N,) and values (N, channels); got {t.shape} and {v.shape}"
        )
    if v.shape[1] != len(channel_names):
        raise EncoderError(
            f"{source}: values have {v.shape[1]} columns but {len(channel_names)} channel names"
        )
    if not np.all(np.isfinite(t)):
        raise EncoderError(
            f"{source}: t_s row {int(np.flatnonzero(~np.isfinite(t))[0])} is not finite"
        )
    if t.size > 1 and np.any(np.diff(t) <= 0):
        row = int(np.flatnonzero(np.diff(t) <= 0)[0]) + 1
        raise EncoderError(f"{source}: t_s must increase strictly; row {row} does not")
    order = model.channel_order(channel_names)
    q = v[:, order]
    n, n_joints = q.shape
    lower = model.lower_limits_rad - limit_tolerance_rad
    upper = model.upper_limits_rad + limit_tolerance_rad
    with np.errstate(invalid="ignore"):
        nan = ~np.isfinite(q)
        out = ~nan & ((q < lower) | (q > upper))
    jump = np.zeros_like(nan)
    for j in range(n_joints):
        last_q, last_t = None, None
        vmax = model.velocity_limits_rad_s[j]
        for k in range(n):
            if nan[k, j] or out[k, j]:
                continue
            if (
                last_q is not None
                and abs(q[k, j] - last_q) > vmax * (t[k] - last_t) + noise_tolerance_rad
            ):
                jump[k, j] = True
                continue
            last_q, last_t = q[k, j], t[k]
    check = EncoderCheck(
        t_s=t,
        q_rad=q,
        joint_names=model.joint_names,
        flags={"nan": nan, "out_of_limits": out, "jump": jump},
    )
    if check.n_usable < check.n_samples:
        logger.warning("%s: %s", source, check.summary())
    return check

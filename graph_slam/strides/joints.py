"""Joint encoders on the camera clock: a causal buffer and the one ``q(t)`` interpolation.

:class:`JointBuffer` takes encoder samples as a device delivers them (chunks, in time order)
and answers ``q_at(t_s)`` — the knee and ankle angles at any time inside the buffered span,
linearly interpolated by :func:`interp_q`, None outside it (never extrapolated). Online, a
frame at ``t_s`` is processed once the encoders have delivered a sample at or after ``t_s``
(at 500 Hz, at most 2 ms later): ``q_at`` reads no sample beyond that one, so its answer is
the same whether later samples have arrived or not (docs/pipelines.md, "causal replay"). Samples that
cannot be used are rejected, counted by reason (:attr:`JointBuffer.counts`) and never used:

* ``nonfinite``: NaN or inf in the time or an angle;
* ``non_monotonic``: a time not after the last accepted sample (across chunks too);
* ``out_of_limits`` / ``jump``: with a leg model, :func:`kinematics.encoders.check_encoders`'s
  rules (URDF joint limits; a change from the previous accepted sample faster than the joint's
  velocity limit). Each chunk is checked with the last accepted sample in front of it, so a
  jump at a chunk boundary is caught as well. ``check_encoders`` keeps its "last accepted
  value" per joint; a row is used only when both joints pass.

Without a model only the first two rules apply (nothing else is known about the joints).
"""

from __future__ import annotations

import logging

import numpy as np

log = logging.getLogger(__name__)

JOINT_REJECT_REASONS = ("nonfinite", "non_monotonic", "out_of_limits", "jump")


def interp_q(t_s: float, joints_t_s: np.ndarray, q_rad: np.ndarray) -> np.ndarray | None:
    """``q`` (rad, N×J samples at increasing ``joints_t_s``) linearly interpolated at ``t_s``;
    None outside ``[joints_t_s[0], joints_t_s[-1]]`` or without samples."""
    t = np.asarray(joints_t_s, float)
    if t.size == 0 or not t[0] <= t_s <= t[-1]:
        return None
    q = np.asarray(q_rad, float)
    return np.array([np.interp(t_s, t, q[:, j]) for j in range(q.shape[1])])


class JointBuffer:
    """Accepted ``[knee, ankle]`` samples (rad) in time order; see the module docstring.

    ``model``: a :class:`kinematics.leg_model.LegModel` whose limits validate the samples, or
    None (time and finiteness checks only).
    """

    def __init__(self, model=None):
        self.model = model
        self._t = np.empty(0)
        self._q = np.empty((0, 2))
        self.counts = {"used": 0, **{r: 0 for r in JOINT_REJECT_REASONS}}

    @property
    def t_s(self) -> np.ndarray:
        return self._t

    @property
    def q_rad(self) -> np.ndarray:
        return self._q

    def add(self, t_s, knee_rad, ankle_rad) -> int:
        """Append a chunk of samples; returns how many were accepted."""
        t = np.asarray(t_s, float).reshape(-1)
        q = np.column_stack([np.ravel(knee_rad), np.ravel(ankle_rad)]).astype(float)
        reason = np.full(t.size, "", dtype=object)
        reason[~(np.isfinite(t) & np.isfinite(q).all(axis=1))] = "nonfinite"
        last = self._t[-1] if self._t.size else -np.inf
        for i in np.flatnonzero(reason == ""):
            if t[i] <= last:
                reason[i] = "non_monotonic"
            else:
                last = t[i]
        if self.model is not None:
            self._check_limits(t, q, reason)
        good = reason == ""
        for r in JOINT_REJECT_REASONS:
            self.counts[r] += int(np.count_nonzero(reason == r))
        self.counts["used"] += int(good.sum())
        if (~good).any():
            log.warning(
                "joints: %d of %d samples rejected (%s)",
                int((~good).sum()),
                good.size,
                ", ".join(
                    f"{r} {int(np.count_nonzero(reason == r))}" for r in sorted(set(reason[~good]))
                ),
            )
        self._t = np.concatenate([self._t, t[good]])
        self._q = np.concatenate([self._q, q[good]])
        return int(good.sum())

    def _check_limits(self, t: np.ndarray, q: np.ndarray, reason: np.ndarray) -> None:
        """``check_encoders`` on the rows still usable, after the last accepted sample."""
        from kinematics.encoders import check_encoders

        rows = np.flatnonzero(reason == "")
        if rows.size == 0:
            return
        head = 1 if self._t.size else 0
        t_chk = np.concatenate([self._t[-1:], t[rows]])
        q_chk = np.concatenate([self._q[-1:], q[rows]])
        check = check_encoders(t_chk, q_chk, self.model.joint_names, self.model, source="joints")
        out = check.flags["out_of_limits"][head:].any(axis=1)
        jump = check.flags["jump"][head:].any(axis=1)
        reason[rows[out]] = "out_of_limits"
        reason[rows[~out & jump]] = "jump"

    def q_at(self, t_s: float) -> np.ndarray | None:
        """``[knee, ankle]`` (rad) at ``t_s`` by :func:`interp_q`; None outside the samples."""
        return interp_q(t_s, self._t, self._q)

    def drop_before(self, t_s: float) -> None:
        """Forget samples not needed at or after ``t_s`` (keeps the one before it)."""
        k = max(int(np.searchsorted(self._t, t_s, side="right")) - 1, 0)
        if k:
            self._t, self._q = self._t[k:], self._q[k:]

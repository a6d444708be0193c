"""The streaming API's contract for foot strikes and frames, one place for every pipeline.

A pipeline is fed in time order (:class:`graph_slam.pipelines.protocol.Pipeline`):

- ``foot_strike(t_s)``: ``t_s`` is a finite time on the camera clock, later than the previous
  strike (each strike once, in order), and not later than the next frame given (announce a
  strike once it happened; an online detector may announce it late, so it may lie before
  the last frame). A strike closer than :data:`MIN_STRIKE_INTERVAL_S` to the previous one is
  implausible as a stride: it is used (the stride is cut at the next frame, as asked) and
  counted, ``PipelineResults.counts["foot_strikes_too_close"]``, which ``run`` and
  ``compare`` report as a caveat;
- ``add_frame(frame, ...)``: an ``RgbdFrame`` of the camera's size; frame times are finite
  and increasing.

Anything else is an :class:`~graph_slam.errors.EstimationError` naming the call, the value
and the rule, before the pipeline's state changes.
"""

from __future__ import annotations

import math

from graph_slam.errors import EstimationError
from graph_slam.session.plausibility import MIN_STRIDE_S
from graph_slam.session.records import RgbdFrame

MIN_STRIKE_INTERVAL_S = MIN_STRIDE_S
"""Strikes closer than this (s) are implausible as strides (the plausibility rule)."""
TOO_CLOSE_KEY = "foot_strikes_too_close"
"""The ``PipelineResults.counts`` key of strikes closer than :data:`MIN_STRIKE_INTERVAL_S`."""


class StrikeClock:
    """Checks the order of ``foot_strike`` and ``add_frame`` calls (module docstring)."""

    def __init__(self) -> None:
        self.last_strike_s: float | None = None
        self.pending_s: float | None = None
        self.last_frame_s: float | None = None
        self.too_close = 0

    def strike(self, t_s: float) -> float:
        """Check a ``foot_strike(t_s)`` call; returns ``t_s`` as a float."""
        try:
            t = float(t_s)
        except (TypeError, ValueError):
            raise EstimationError(f"foot_strike: t_s = {t_s!r} is not a number") from None
        if not math.isfinite(t):
            raise EstimationError(
                f"foot_strike: t_s = {t} is not a finite time (seconds on the camera clock)"
            )
        if self.last_strike_s is not None and t <= self.last_strike_s:
            raise EstimationError(
                f"foot_strike: t_s = {t:.6f} s is not after the previous strike at "
                f"{self.last_strike_s:.6f} s; strikes come in time order, each once"
            )
        if self.last_strike_s is not None and t - self.last_strike_s < MIN_STRIKE_INTERVAL_S:
            self.too_close += 1
        self.last_strike_s = self.pending_s = t
        return t

    def frame(self, frame, intrinsics=None) -> None:
        """Check an ``add_frame`` call: an :class:`RgbdFrame` of the camera's size, its time
        against the last frame's and the strike announced before it."""
        if not isinstance(frame, RgbdFrame):
            raise EstimationError(
                f"add_frame: frame is a {type(frame).__name__}, not a graph_slam.session.RgbdFrame"
            )
        size = (intrinsics.height_px, intrinsics.width_px) if intrinsics is not None else None
        if size is not None and frame.depth_m.shape != size:
            raise EstimationError(
                f"add_frame: frame {frame.index} is {frame.depth_m.shape[1]}×"
                f"{frame.depth_m.shape[0]} px but the camera's intrinsics are {size[1]}×{size[0]}"
            )
        t = float(frame.t_s)
        if not math.isfinite(t):
            raise EstimationError(f"add_frame: frame.t_s = {t} is not a finite time")
        if self.last_frame_s is not None and t <= self.last_frame_s:
            raise EstimationError(
                f"add_frame: frame.t_s = {t:.6f} s is not after the previous frame at "
                f"{self.last_frame_s:.6f} s; frames come in time order"
            )
        if self.pending_s is not None and self.pending_s > t:
            raise EstimationError(
                f"foot_strike: t_s = {self.pending_s:.6f} s lies after the next frame "
                f"({t:.6f} s); announce a strike once it happened, before the first frame "
                "after it"
            )
        self.pending_s = None
        self.last_frame_s = t

    def counts(self) -> dict[str, int]:
        return {TOO_CLOSE_KEY: self.too_close}

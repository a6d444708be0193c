"""The chain of stride graphs: how a stride starts (priors), ends (smoothing) and is recorded.

**Start** (:meth:`StrideChain.start`, at a stride's first frame). Why it starts is the pending
reason: ``foot_strike`` (announced), ``missed_foot_strike`` (the open stride ran past
``priors.max_stride_s``: :meth:`StrideChain.close_if_missed`) or ``first_stride`` (nothing
carried yet). The first state gets pose, velocity and bias priors:

* first stride of a session (:func:`first_stride_priors`): the anchor if any, else
  gravity-aligned from the accelerometer mean (roll/pitch σ ``first_roll_pitch_sigma_rad``,
  flag ``no_anchor``); weak velocity and bias priors;
* later strides (:func:`carried_priors`): the previous stride's smoothed end state propagated
  by the IMU (:meth:`~graph_slam.backend.prediction.ImuPredictor.carry`), covariances ×
  ``carry_inflation`` (× ``missed_strike_inflation`` after a missed strike; also ×
  ``first_carry_inflation`` out of a first stride begun with the foot unloaded). With an
  anchor at a foot strike the pose is the anchor, the velocity is rotated by
  ``new_R_old = R_anchor · R_predictedᵀ`` and ``world_T_stride`` chains by the prediction;
  without one (or after a missed strike) the new graph continues in the previous stride
  frame, covariances × ``missed_strike_inflation``.

**Close** (:meth:`StrideChain.close`): LM smoothing, marginals at the end state (carried to
the next stride), the :class:`~graph_slam.backend.results.StrideSummary`.

**Bookkeeping**: per-stride counts (ICP accepted/rejected, kinematic factors, IMU gaps), the
frame estimates (:meth:`StrideChain.estimate`).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Iterator
from dataclasses import dataclass

import gtsam
import numpy as np

from graph_slam.backend import factors
from graph_slam.backend.config import BackendConfig
from graph_slam.backend.first_stride import FirstStrideRefit
from graph_slam.backend.gating import GateDecision
from graph_slam.backend.keys import B, V, X
from graph_slam.backend.measurements import KinematicMeasurement
from graph_slam.backend.prediction import ImuPredictor, Prediction
from graph_slam.backend.priors import StartPriors, carried_priors, first_stride_priors
from graph_slam.backend.results import FrameEstimate, Results, StrideSummary
from graph_slam.backend.stride_graph import NavEstimate, Smoothed, StrideGraph

log = logging.getLogger(__name__)

#: Strides whose foothold is unknown: no stance factors (``kin_unanchored``).
UNANCHORED = ("missed_foot_strike",)


@dataclass
class _StartInputs:
    """What a stride's start was given (its priors are recomputed when the end state they
    came from is settled)."""

    t_s: float
    anchor: KinematicMeasurement | None
    reason: str
    unloaded_first: bool
    world_T_old: np.ndarray
    loose_tilt_before: bool = False
    """The stride carried from had an anchor without a known up σ, this one has one."""
    tilt_known: bool = True
    """This stride's anchor came with its up's σ."""


@dataclass(eq=False)
class _Unsettled:
    """A closed stride whose Gauss-Newton step and end-state marginals wait for the next
    frame (``end_state: next_frame``)."""

    graph: StrideGraph
    work: Iterator[Smoothed | None]
    """:meth:`StrideGraph.settle_in_pieces`: one piece a frame."""
    summary: StrideSummary | None = None
    start: _StartInputs | None = None
    spent_s: float = 0.0


def _prior_factors(p: StartPriors) -> list[tuple[str, object]]:
    return [
        ("prior", factors.pose_prior(0, p.stride_T_imu, p.cov_pose)),
        ("prior", factors.velocity_prior(0, p.velocity_m_s, p.cov_velocity)),
        ("prior", factors.bias_prior(0, p.bias, p.cov_bias)),
    ]


def _chained(world_T_old: np.ndarray, p: StartPriors) -> np.ndarray:
    """``world_T_stride`` of a stride started with ``p``: a new stride frame chains by the
    predicted IMU pose in the old one; otherwise the old frame goes on."""
    if p.old_stride_T_imu is None:
        return world_T_old
    return world_T_old @ p.old_stride_T_imu @ np.linalg.inv(p.stride_T_imu.matrix())


class StrideChain:
    """The open stride's graph and everything carried from one stride to the next."""

    def __init__(self, config: BackendConfig, camera_T_imu: np.ndarray, imu: ImuPredictor):
        self.cfg = config
        self.camera_T_imu = np.asarray(camera_T_imu, float)
        self.imu = imu
        self.results = Results()
        self.graph: StrideGraph | None = None
        self.start_reason = "first_stride"
        self.pending: str | None = None
        self.world_T_stride = np.eye(4)
        self._t0_s = np.nan
        self._frames: list[FrameEstimate] = []
        self._counts = {"icp_ok": 0, "icp_rej": 0, "kin": 0, "gap": 0}
        self._last_nav = None  # (t_s, NavEstimate, cov_pose, cov_vel, cov_bias) at stride end
        self._started_loaded = True  # the open stride's first frame had the foot loaded
        self._tilt_known = True  # the open stride's anchor had a known up σ
        self.deferred: list[tuple[StrideSummary, StrideGraph]] = []
        self._unsettled: _Unsettled | None = None  # end_state: next_frame
        self._retired: _Unsettled | None = None
        self.first = FirstStrideRefit(config.priors, self.camera_T_imu)
        """Closed strides whose batch smoothing waits (``defer_smoothing``)."""

    @property
    def anchored(self) -> bool:
        """False when the open stride's foothold is unknown (:data:`UNANCHORED`)."""
        return self.start_reason not in UNANCHORED

    def foot_strike(self) -> StrideSummary | None:
        """Close the open stride (if any); the next frame starts a new one."""
        summary = self.close() if self.graph is not None else None
        self.pending = "foot_strike"
        return summary

    def close_if_missed(self, t_s: float) -> None:
        """A stride longer than ``priors.max_stride_s``: a missed foot strike, closed here."""
        max_s = self.cfg.priors.max_stride_s
        if self.graph is not None and self.pending is None and t_s - self._t0_s > max_s:
            log.warning("t=%.3f s: stride longer than %.2f s: a missed foot strike", t_s, max_s)
            self.close()
            self.pending = "missed_foot_strike"

    def start(
        self,
        t_s: float,
        anchor: KinematicMeasurement | None,
        foot_loaded: bool,
        tilt_known: bool = True,
    ) -> list[str]:
        """A new stride graph at ``t_s`` with its first state's priors; returns frame flags.
        ``tilt_known``: the anchor's up vector came with its σ."""
        reason = self.pending or "first_stride"
        if self._last_nav is None:
            reason = "first_stride"
        unloaded_first = self.start_reason == "first_stride" and not self._started_loaded
        inputs = _StartInputs(t_s, anchor, reason, unloaded_first, self.world_T_stride.copy())
        # out of a stride anchored without a known up σ into one with: its bias is loosened
        inputs.loose_tilt_before = not self._tilt_known and tilt_known and anchor is not None
        inputs.tilt_known = bool(tilt_known)
        self._tilt_known = bool(tilt_known)
        priors, flags = self._priors(inputs)
        self.first.strike(reason, anchor, self.imu, self._last_nav, t_s)
        self._new_graph(t_s, priors, flags)
        self.world_T_stride = _chained(inputs.world_T_old, priors)
        if self._unsettled is not None:  # started from the provisional end state
            self._unsettled.start = inputs
        self.start_reason = reason
        self.pending = None
        self._started_loaded = bool(foot_loaded)
        return flags

    def _priors(self, s: _StartInputs) -> tuple[StartPriors, list[str]]:
        """The first state's priors for a stride started with ``s``, and its frame flags."""
        flags = [s.reason] if s.reason != "foot_strike" else []
        if self._last_nav is None:  # first stride of the session: gravity-aligned, weak priors
            priors = first_stride_priors(
                self.cfg.priors, self.camera_T_imu, s.anchor, self.imu.gravity(s.t_s)
            )
        else:
            t_last, nav, cov_x, cov_v, cov_b = self._last_nav
            pred, cov_x, cov_v, carry_flags = self.imu.carry(t_last, nav, cov_x, cov_v, s.t_s)
            flags += carry_flags
            priors = carried_priors(
                self.cfg.priors,
                self.camera_T_imu,
                s.reason,
                pred,
                cov_x,
                cov_v,
                nav.bias,
                cov_b,
                s.anchor,
                s.unloaded_first,
                s.loose_tilt_before,
                gravity_m_s2=self.cfg.imu.gravity_m_s2 if s.tilt_known else None,
            )
        return priors, flags + priors.flags

    def _new_graph(self, t_s: float, p: StartPriors, flags: list[str]) -> None:
        cfg = self.cfg
        g = StrideGraph(
            cfg.isam2_relinearize_threshold,
            (cfg.isam2_velocity_relinearize_threshold, cfg.isam2_accel_bias_relinearize_threshold),
        )
        tagged = _prior_factors(p)
        values = gtsam.Values()
        values.insert(X(0), p.stride_T_imu)
        values.insert(V(0), p.velocity_m_s)
        values.insert(B(0), p.bias)
        g.add_state(t_s, tagged, values, None)
        g.flags.update(f for f in flags if f != "first_stride")
        self.graph = g
        self._t0_s = t_s
        self._frames = []
        self._counts = {"icp_ok": 0, "icp_rej": 0, "kin": 0, "gap": 0}

    def count(
        self, pred: Prediction, kept: list[str], gate: GateDecision | None, flags: list[str]
    ) -> list[str]:
        """Count a frame's factors (``kept`` tags) and flags into the stride's summary;
        returns the frame's ICP flag (``icp_rejected``/``icp_dropped``) if any."""
        g, c = self.graph, self._counts
        if not pred.segment.ok:
            c["gap"] += 1
            g.flags.add(pred.segment.reason)
        if any(f.startswith("kin_inconsistent") for f in flags):
            g.flags.add("kin_inconsistent")
        c["kin"] += "kin" in kept
        if "icp" in kept:
            c["icp_ok"] += 1
        elif gate is not None:
            c["icp_rej"] += 1
            return ["icp_rejected" if not gate.accepted else "icp_dropped"]
        return []

    def estimate(self, index, k, t_s, flags, gate, kept, t_start) -> FrameEstimate:
        """The frame's online estimate (state ``k`` of the open stride), recorded."""
        g = self.graph
        stride_T_camera = g.estimate.atPose3(X(k)).matrix() @ np.linalg.inv(self.camera_T_imu)
        cov = None
        if self.cfg.covariances:
            cov = factors.imu_cov_to_camera(g.marginal_covariance(X(k)), self.camera_T_imu)
        est = FrameEstimate(
            frame_index=index,
            stride_index=len(self.results.strides),
            k=k,
            t_s=float(t_s),
            stride_T_camera=stride_T_camera,
            world_T_camera=self.world_T_stride @ stride_T_camera,
            flags=tuple(flags),
            gate=None if gate is None else gate.record(),  # the factor holds the matrices
            kinematic_factor="kin" in kept,
            imu_factor="imu" in kept,
            update_s=time.perf_counter() - t_start,
            covariance=cov,
            stride_start=k == 0,
        )
        self.results.frames.append(est)
        self._frames.append(est)
        return est

    def close(self) -> StrideSummary:
        """Smooth the open stride, keep its end state for the next one, summarise it. With
        ``defer_smoothing`` the end state is iSAM2's and the smoothing is queued
        (:meth:`smooth_deferred`)."""
        self.settle_pending(at_once=True)
        g = self.graph
        defer = self.cfg.smoothing and self.cfg.defer_smoothing
        lm = self.cfg.smoothing and not defer
        t0 = time.perf_counter()
        values = g.batch() if lm else g.estimate
        marginals = "all" if self.cfg.covariances else "end"
        if self.cfg.end_state == "next_frame":  # the live iSAM2's for now: settle_pending
            smoothed = Smoothed(values, 0.0)
            work = g.settle_in_pieces(values, marginals, not lm, self.cfg.end_state_frames)
            self._unsettled = _Unsettled(g, work)
        else:
            smoothed = g.settle(values, marginals, step=not lm)
        smoothed.seconds = time.perf_counter() - t0
        n = g.n_states
        last = g.nav(n - 1, smoothed.values)
        end = smoothed.end
        if end is None:  # online iSAM2's (provisional, or the settled ones failed)
            end = tuple(g.marginal_covariance(key(n - 1)) for key in (X, V, B))
        covs = self._camera_covariances(smoothed, n)
        self._last_nav = (g.t_s[-1], last, *end)
        summary = self._summary(smoothed.values, covs, smoothed.seconds, last)
        self.results.strides.append(summary)
        self.first.keep(summary, g)
        if self._unsettled is not None:
            self._unsettled.summary = summary
        if defer:
            summary.flags = (*summary.flags, "smoothing_deferred")
            self.deferred.append((summary, g))
        self.graph = None
        return summary

    def settle_pending(self, at_once: bool = False) -> None:
        """``end_state: next_frame``: one piece (all with ``at_once``) of the last closed
        stride's settling (its Gauss-Newton step and end-state marginals,
        :meth:`StrideGraph.settle_in_pieces`, ``end_state_frames`` pieces). After the last,
        its summary is updated and the stride started since from the provisional end state
        gets its settled priors (:meth:`StrideGraph.replace_priors`, ``world_T_stride``
        chained again); its graph is freed on the call after. Frames already returned keep
        their provisional online poses."""
        self._retired = None  # the stride settled on the last call: its graph freed now
        u = self._unsettled
        if u is None:
            return
        t0 = time.perf_counter()
        smoothed = next(u.work)
        while smoothed is None and at_once:
            smoothed = next(u.work)
        if smoothed is None:
            u.spent_s += time.perf_counter() - t0
            return
        self._unsettled = None
        self._retired = u  # freeing a stride's graph takes 1–2 ms: on the next call
        g, summary = u.graph, u.summary
        summary.flags = tuple(sorted({*summary.flags, *g.flags}))
        if smoothed.end is not None:
            n = g.n_states
            last = g.nav(n - 1, smoothed.values)
            self._last_nav = (g.t_s[-1], last, *smoothed.end)
            summary.smoothed_stride_T_camera = self._camera_poses(smoothed.values, n)
            summary.smoothed_covariances = self._camera_covariances(smoothed, n)
            summary.velocity_end_m_s = last.velocity_m_s
            summary.bias_end = np.asarray(last.bias.vector())
            if u.start is not None and self.graph is not None:
                priors, _ = self._priors(u.start)
                self.graph.replace_priors(_prior_factors(priors))
                self.world_T_stride = _chained(u.start.world_T_old, priors)
        summary.smoothing_s += u.spent_s + time.perf_counter() - t0

    def smooth_deferred(self, keep: int = 0) -> list[StrideSummary]:
        """Run the queued smoothings, oldest first, until ``keep`` strides wait: each
        summary's smoothed poses (and covariances, when asked for) are replaced by the batch
        solution and its graph is released; returns the strides updated."""
        done = []
        while len(self.deferred) > keep:
            summary, g = self.deferred.pop(0)
            smoothed = g.smooth(True, "all" if self.cfg.covariances else "none")
            summary.smoothed_stride_T_camera = self._camera_poses(smoothed.values, g.n_states)
            if smoothed.isam is not None:
                summary.smoothed_covariances = self._camera_covariances(smoothed, g.n_states)
            summary.smoothing_s = smoothed.seconds
            summary.flags = tuple(sorted({*summary.flags, *g.flags} - {"smoothing_deferred"}))
            done.append(summary)
        if self.first.finished and self.refit_first() and self.results.strides[0] not in done:
            done.append(self.results.strides[0])  # waited for its deferred smoothing
        return done

    def refit_first(self) -> bool:
        """The session's first stride smoothed again with the first strike's up vector
        (:mod:`graph_slam.backend.first_stride`; smoothed poses only). At the end of a run."""
        return self.first.apply(self.results.strides, self.deferred)

    def _camera_poses(self, values: gtsam.Values, n: int) -> np.ndarray:
        """``stride_T_camera`` of states ``0..n-1`` in ``values`` (n×4×4)."""
        inv_ext = np.linalg.inv(self.camera_T_imu)
        return np.array([values.atPose3(X(k)).matrix() @ inv_ext for k in range(n)])

    def _camera_covariances(self, smoothed: Smoothed, n: int) -> np.ndarray | None:
        """Every state's smoothed pose covariance, camera frame (``marginals="all"`` only)."""
        if smoothed.isam is None:
            return None
        return np.array(
            [
                factors.imu_cov_to_camera(
                    np.asarray(smoothed.isam.marginalCovariance(X(k))), self.camera_T_imu
                )
                for k in range(n)
            ]
        )

    def _summary(self, result, covs, smoothing_s: float, last: NavEstimate) -> StrideSummary:
        g, c = self.graph, self._counts
        return StrideSummary(
            index=len(self.results.strides),
            t_start_s=g.t_s[0],
            t_end_s=g.t_s[-1],
            start=self.start_reason,
            world_T_stride=self.world_T_stride.copy(),
            frame_indices=[f.frame_index for f in self._frames],
            t_s=np.array(g.t_s),
            online_stride_T_camera=np.array([f.stride_T_camera for f in self._frames]),
            smoothed_stride_T_camera=self._camera_poses(result, g.n_states),
            smoothed_covariances=covs,
            flags=tuple(sorted(g.flags)),
            n_icp_accepted=c["icp_ok"],
            n_icp_rejected=c["icp_rej"],
            n_kinematic=c["kin"],
            n_imu_gaps=c["gap"],
            dropped_factors=list(g.dropped),
            smoothing_s=smoothing_s,
            velocity_end_m_s=last.velocity_m_s,
            bias_end=np.asarray(last.bias.vector()),
        )


def make_stride_chain(
    config: BackendConfig, camera_T_imu: np.ndarray, imu: ImuPredictor
) -> StrideChain:
    """The stride start/close component of :class:`~graph_slam.backend.estimator.StrideSLAM`."""
    return StrideChain(config, camera_T_imu, imu)

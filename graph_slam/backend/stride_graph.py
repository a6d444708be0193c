"""The graph of one stride: iSAM2 every frame (online), batch Levenberg–Marquardt at the end
(smoothed), with failure handling that never ends the run.

At each frame the estimator hands over the new state's tagged factors (``imu``, ``icp``,
``kin``, ``bridge``, ``prior``) and initial values; only these go to iSAM2 (passing the
whole graph again would duplicate factors). If GTSAM raises (a bare ``RuntimeError``, e.g.
an indeterminant linear system) or the estimate is not finite, the offending factor is
dropped — ICP first, then the kinematic factor, then the IMU factor (replaced by weak
bridge factors) — iSAM2 is rebuilt from the accepted factors, the reason is logged and the
stride is flagged.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import gtsam
import numpy as np

from graph_slam.backend import end_state
from graph_slam.backend.keys import B, V, X
from graph_slam.errors import EstimationError

log = logging.getLogger(__name__)

#: Drop order when an update fails.
DROP_ORDER = ("icp", "kin", "imu")


@dataclass
class NavEstimate:
    """Pose, velocity and bias of one state (IMU body, stride frame)."""

    stride_T_imu: gtsam.Pose3
    velocity_m_s: np.ndarray
    bias: gtsam.imuBias.ConstantBias


def _finite_state(values: gtsam.Values, k: int) -> bool:
    return bool(
        np.all(np.isfinite(values.atPose3(X(k)).matrix()))
        and np.all(np.isfinite(values.atVector(V(k))))
        and np.all(np.isfinite(values.atConstantBias(B(k)).vector()))
    )


@dataclass
class Smoothed:
    """What :meth:`StrideGraph.smooth` gives: the stride's estimate, the last state's
    covariances (pose, velocity, bias; None when not asked for or failed), an iSAM2
    linearised at the estimate for every state's marginals (``marginals="all"`` only) and
    the time taken."""

    values: gtsam.Values
    seconds: float
    end: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
    isam: gtsam.ISAM2 | None = None


class StrideGraph:
    """Factors and estimates of one stride; keys ``X(k)``, ``V(k)``, ``B(k)``, ``k`` from 0."""

    def __init__(
        self,
        relinearize_threshold: float = 0.01,
        per_type: tuple[float, float] | None = None,
        extra_updates: int = 1,
    ):
        """``relinearize_threshold``: iSAM2's, for every variable; with ``per_type``
        (velocity m/s, accelerometer bias m/s²) those two get their own (the pose and the
        gyroscope bias keep ``relinearize_threshold``)."""
        params = gtsam.ISAM2Params()
        if per_type is None:
            params.setRelinearizeThreshold(relinearize_threshold)
        else:  # per variable type; the bias vector is (accelerometer, gyroscope)
            velocity, accel_bias = per_type
            thresholds = gtsam.ISAM2ThresholdMap()
            thresholds.insert(("x", np.full(6, relinearize_threshold)))
            thresholds.insert(("v", np.full(3, velocity)))
            bias = [accel_bias] * 3 + [relinearize_threshold] * 3
            thresholds.insert(("b", np.array(bias)))
            params.setRelinearizeThreshold(thresholds)
        params.relinearizeSkip = 1
        # QR, not Cholesky: the bias random walk between consecutive frames is ~1e10 times
        # more informative than the bias prior, and GTSAM's Cholesky calls that system
        # indeterminant (measured here on the very first CombinedImuFactor).
        params.setFactorization("QR")
        self._isam_params = params
        self.isam = gtsam.ISAM2(params)
        self.graph = gtsam.NonlinearFactorGraph()
        self.factor_tags: list[str] = []
        self.estimate = gtsam.Values()
        self.t_s: list[float] = []
        self.flags: set[str] = set()
        self.dropped: list[str] = []
        self.extra_updates = extra_updates

    @property
    def n_states(self) -> int:
        return len(self.t_s)

    def nav(self, k: int, values: gtsam.Values | None = None) -> NavEstimate:
        values = self.estimate if values is None else values
        return NavEstimate(
            values.atPose3(X(k)), np.asarray(values.atVector(V(k))), values.atConstantBias(B(k))
        )

    def _try(
        self, tagged: list[tuple[str, object]], new_values: gtsam.Values, k: int, rebuild: bool
    ):
        new_graph = gtsam.NonlinearFactorGraph()
        for _, factor in tagged:
            new_graph.add(factor)
        try:
            if rebuild:
                isam = gtsam.ISAM2(self._isam_params)
                full = gtsam.NonlinearFactorGraph(self.graph)
                full.push_back(new_graph)
                init = gtsam.Values(self.estimate)
                init.insert(new_values)
                isam.update(full, init)
            else:
                isam = self.isam
                isam.update(new_graph, new_values)
            for _ in range(self.extra_updates):
                isam.update()
            est = isam.calculateEstimate()
            if not _finite_state(est, k):
                return None, "nonfinite estimate"
            return (isam, est), ""
        except RuntimeError as err:  # GTSAM's exceptions arrive as bare RuntimeError
            lines = [ln.strip() for ln in str(err).splitlines() if ln.strip()]
            return None, " ".join(lines[:2]) if lines else type(err).__name__

    def add_state(
        self,
        t_s: float,
        tagged: list[tuple[str, object]],
        new_values: gtsam.Values,
        make_bridge: Callable[[], list] | None,
    ) -> tuple[list[str], list[str]]:
        """Add state ``k = n_states`` with its factors; return (kept tags, frame flags)."""
        k = self.n_states
        attempt = list(tagged)
        flags: list[str] = []
        rebuild = False
        while True:
            result, why = self._try(attempt, new_values, k, rebuild)
            if result is not None:
                break
            rebuild = True  # iSAM2 may be half-updated after an exception: never reuse it
            tags = [t for t, _ in attempt]
            victim = next((t for t in DROP_ORDER if t in tags), None)
            if victim is None:
                if "bridge" in tags or make_bridge is None:
                    raise EstimationError(
                        f"stride graph: cannot add state {k} even with bridge factors: {why}"
                    )
                attempt = [*attempt, *(("bridge", f) for f in make_bridge())]
                flags.append("bridged")
                continue
            log.warning("state %d: dropping the %s factor (%s)", k, victim, why)
            i = tags.index(victim)
            attempt.pop(i)
            self.dropped.append(f"{victim}@{k}: {why}")
            flags.append(f"factor_dropped:{victim}")
            self.flags.add("factor_dropped")
            if victim == "imu" and make_bridge is not None and "bridge" not in tags:
                attempt.extend(("bridge", f) for f in make_bridge())
        self.isam, self.estimate = result
        for tag, factor in attempt:
            self.graph.add(factor)
            self.factor_tags.append(tag)
        self.t_s.append(float(t_s))
        return [t for t, _ in attempt], flags

    def replace_priors(self, tagged: list[tuple[str, object]]) -> None:
        """Replace the first state's prior factors (the stride's first ``len(tagged)``
        factors) in the graph and in iSAM2 (removed and added in one update). If iSAM2
        fails, the old priors stay (flag ``prior_replace_failed``)."""
        n = len(tagged)
        if self.factor_tags[:n] != ["prior"] * n:
            raise EstimationError(f"replace_priors: the first {n} factors are not priors")
        new = gtsam.NonlinearFactorGraph()
        for _, factor in tagged:
            new.add(factor)
        try:
            self.isam.update(new, gtsam.Values(), list(range(n)))
            est = self.isam.calculateEstimate()
            if not _finite_state(est, self.n_states - 1):
                raise RuntimeError("nonfinite estimate")
        except RuntimeError as err:
            log.warning("stride graph: new priors not taken (%s); keeping the old", err)
            self.flags.add("prior_replace_failed")
            self.isam = gtsam.ISAM2(self._isam_params)
            self.isam.update(self.graph, self.estimate)
            return
        self.estimate = est
        for i, (_, factor) in enumerate(tagged):
            self.graph.replace(i, factor)

    def marginal_covariance(self, key: int) -> np.ndarray:
        return np.asarray(self.isam.marginalCovariance(key))

    def smooth(self, enabled: bool = True, marginals: str = "end") -> Smoothed:
        """:meth:`batch` (when ``enabled``) then :meth:`settle` with the Gauss-Newton step
        when the batch LM did not run."""
        t0 = time.perf_counter()
        values = self.batch() if enabled else self.estimate
        out = self.settle(values, marginals, step=not enabled)
        out.seconds = time.perf_counter() - t0
        return out

    def batch(self) -> gtsam.Values:
        """Batch LM over the stride from the iSAM2 estimate; the iSAM2 estimate (flag
        ``smoothing_failed``) when it fails."""
        try:
            params = gtsam.LevenbergMarquardtParams()
            params.setMaxIterations(50)
            params.setLinearSolverType("MULTIFRONTAL_QR")
            opt = gtsam.LevenbergMarquardtOptimizer(self.graph, self.estimate, params)
            cand = opt.optimize()
            if all(_finite_state(cand, k) for k in range(self.n_states)):
                return cand
            self.flags.add("smoothing_failed")
        except RuntimeError as err:
            log.warning("stride smoothing failed (%s); keeping the iSAM2 estimate", err)
            self.flags.add("smoothing_failed")
        return self.estimate

    def settle(self, values: gtsam.Values, marginals: str = "end", step: bool = False) -> Smoothed:
        """Marginals at ``values`` and, with ``step``, one Gauss-Newton step from it.

        ``marginals``: ``"end"`` (the last state's pose, velocity and bias covariances, what
        the next stride carries: :meth:`end_state`), ``"all"`` (also every state's, from an
        iSAM2 linearised at ``values``: ``marginalCovariance`` by QR; ``gtsam.Marginals``
        uses Cholesky and fails on these graphs) or ``"none"``. The step (without the batch
        LM) relinearises every factor: iSAM2 relinearises lazily (thresholds), the step
        settles what it left (the real-time preset's fast session: smoothed per-stride RMSE
        median 3.3 → 3.0 mm); it comes out of the same elimination as the marginals. A
        failure keeps ``values`` and leaves ``end`` None (flag ``marginals_failed``).
        """
        if marginals not in ("end", "all", "none"):
            raise ValueError(f"marginals must be 'end', 'all' or 'none', got {marginals!r}")
        t0 = time.perf_counter()
        out = Smoothed(values, 0.0)
        n = self.n_states
        try:
            if marginals == "all":
                out.isam = gtsam.ISAM2(self._isam_params)
                out.isam.update(self.graph, values)
                if step:
                    cand = out.isam.calculateEstimate()
                    if all(_finite_state(cand, k) for k in range(n)):
                        out.values = cand
                out.end = tuple(
                    np.asarray(out.isam.marginalCovariance(key(n - 1))) for key in (X, V, B)
                )
            elif marginals == "end" or step:
                return next(self.settle_in_pieces(values, marginals, step, 1))
        except (RuntimeError, np.linalg.LinAlgError) as err:
            out.isam = None
            self._marginals_failed(err)
        out.seconds = time.perf_counter() - t0
        return out

    def settle_in_pieces(
        self, values: gtsam.Values, marginals: str = "end", step: bool = False, pieces: int = 1
    ) -> Iterator[Smoothed | None]:
        """:meth:`settle` spread over ``pieces`` calls of ``next``
        (:func:`graph_slam.backend.end_state.pieces`: slices of the linearisation, then
        ranges of the elimination); yields None until the last piece, which yields the
        result (``seconds``: the pieces' sum). ``"all"``: at once."""
        if marginals == "all" or not (marginals == "end" or step):
            yield self.settle(values, marginals, step)
            return
        out, spent = Smoothed(values, 0.0), 0.0
        work = end_state.pieces(self.graph, values, self.n_states, pieces)
        while True:
            t0 = time.perf_counter()
            try:
                piece = next(work)
            except (RuntimeError, np.linalg.LinAlgError) as err:
                self._marginals_failed(err)
                piece = ()  # failed: ``values`` kept, no covariances
            spent += time.perf_counter() - t0
            if piece is None:
                yield None
                continue
            if piece:
                delta, end = piece
                out.values = values.retract(delta) if step else values
                out.end = end if marginals == "end" else None
            out.seconds = spent
            yield out
            return

    def _marginals_failed(self, err: Exception) -> None:
        log.warning("stride marginals failed (%s)", err)
        self.flags.add("marginals_failed")

    def end_state(
        self, values: gtsam.Values
    ) -> tuple[gtsam.VectorValues, tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """The whole stride's Gauss-Newton step at ``values`` and the last state's marginal
        covariances (pose, velocity, bias) from one elimination
        (:mod:`graph_slam.backend.end_state`). Raises ``RuntimeError`` (GTSAM) or
        ``LinAlgError`` when it fails."""
        return end_state.end_state(self.graph, values, self.n_states)

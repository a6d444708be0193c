"""A closed stride's end state: the Gauss-Newton step of the whole stride and the last
state's marginal covariances, from one elimination, whole or in pieces.

The stride is a chain of states ``X/V/B(k)``. Every factor is linearised at the estimate,
then every state but the last is eliminated in time order (GTSAM's
``eliminatePartialSequential``: no fill-in beyond neighbours). What remains is the last
state's joint marginal information ``Λ`` and ``η``: its covariance is ``Λ⁻¹``, its step
``Λ⁻¹η``, and back-substitution through the eliminated conditionals gives every other state's
step. Equal to an iSAM2 refactorised at the same estimate (``tests/test_end_state.py``) in
40–60 % of its time (10–15 → 4.5–9 ms on the 424×240 normal session's strides).

The work splits at no cost: the linearisation by slices of the factors, the elimination by
ranges of states (each partial elimination hands the next the factors that remain), so that a
real-time caller can spread it over several frames (:func:`pieces`; ``backend.end_state:
next_frame``, docs/pipelines.md). GTSAM's default elimination first (Cholesky where it can);
QR when Cholesky calls the system indeterminant (the bias random walk between frames is ~1e10
times more informative than the bias prior).
"""

from __future__ import annotations

import itertools
from collections.abc import Iterator

import gtsam
import numpy as np

from graph_slam.backend.keys import B, V, X

#: the last state's covariances: pose (rotation first, IMU local), velocity, bias
EndCovariances = tuple[np.ndarray, np.ndarray, np.ndarray]


def _states(lo: int, hi: int) -> gtsam.Ordering:
    ordering = gtsam.Ordering()
    for k in range(lo, hi):
        for key in (B, V, X):
            ordering.push_back(key(k))
    return ordering


def _eliminate(gfg: gtsam.GaussianFactorGraph, ordering: gtsam.Ordering):
    try:
        return gfg.eliminatePartialSequential(ordering)  # Cholesky where it can
    except RuntimeError:
        return gfg.eliminatePartialSequential(ordering, gtsam.EliminateQR)


def pieces(
    graph: gtsam.NonlinearFactorGraph, values: gtsam.Values, n_states: int, n_pieces: int = 1
) -> Iterator[tuple[gtsam.VectorValues, EndCovariances] | None]:
    """The end state in ``n_pieces`` calls of ``next``: the first half of them linearise
    slices of the factors, the rest eliminate ranges of states; None until the last, which
    yields ``(step, covariances)``. Raises ``RuntimeError`` (GTSAM) or ``LinAlgError`` (a
    non-finite result) from the piece that fails."""
    n_lin = max(1, n_pieces // 2)
    n_elim = max(1, n_pieces - n_lin)
    m = graph.size()
    gfg = gtsam.GaussianFactorGraph()
    for i in range(n_lin):
        part = gtsam.NonlinearFactorGraph()
        for j in range(m * i // n_lin, m * (i + 1) // n_lin):
            part.add(graph.at(j))
        gfg.push_back(part.linearize(values))
        if n_pieces > 1:
            yield None
    n = n_states
    nets, rest = [], gfg
    bounds = sorted({(n - 1) * i // n_elim for i in range(n_elim + 1)})
    for i, (lo, hi) in enumerate(itertools.pairwise(bounds)):
        net, rest = _eliminate(rest, _states(lo, hi))
        nets.append(net)
        if i < len(bounds) - 2:
            yield None
    last = gtsam.Ordering()
    for key in (X, V, B):
        last.push_back(key(n - 1))
    h = np.asarray(rest.augmentedHessian(last))
    cov = np.linalg.inv(h[:-1, :-1])
    d = cov @ h[:-1, -1]
    if not (np.isfinite(cov).all() and np.isfinite(d).all()):
        raise np.linalg.LinAlgError("non-finite end-state marginal")
    step = gtsam.VectorValues()
    step.insert(X(n - 1), d[:6])
    step.insert(V(n - 1), d[6:9])
    step.insert(B(n - 1), d[9:])
    for net in reversed(nets):  # back-substitution, latest states first
        step = net.optimize(step)
    if not np.isfinite(step.vector()).all():
        raise np.linalg.LinAlgError("non-finite Gauss-Newton step")
    yield step, (cov[:6, :6], cov[6:9, 6:9], cov[9:, 9:])


def end_state(
    graph: gtsam.NonlinearFactorGraph, values: gtsam.Values, n_states: int
) -> tuple[gtsam.VectorValues, EndCovariances]:
    """The whole stride's Gauss-Newton step at ``values`` and the last state's covariances,
    at once (see the module docstring)."""
    return next(iter(pieces(graph, values, n_states, 1)))

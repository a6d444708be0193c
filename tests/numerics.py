"""Numerical derivatives shared by the tests that check analytic ones."""

from __future__ import annotations

import numpy as np


def numerical_hessian(cost, step: float, dim: int = 6) -> np.ndarray:
    """Central-difference Hessian of ``cost`` (a function of a ``dim``-vector) at zero."""
    hess = np.zeros((dim, dim))
    for i in range(dim):
        for j in range(dim):
            ei, ej = np.eye(dim)[i] * step, np.eye(dim)[j] * step
            hess[i, j] = (cost(ei + ej) - cost(ei - ej) - cost(ej - ei) + cost(-ei - ej)) / (
                4 * step**2
            )
    return hess

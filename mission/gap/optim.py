"""Multi-start minimisation for the physics fits: a coarse grid finds the basin, Nelder-Mead polishes it."""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from scipy.optimize import minimize


def minimize_from_grid(fun: Callable[[np.ndarray], float], grid: np.ndarray, steps: Sequence[float],
                       max_evals: int, n_starts: int = 1, xatol: float = 1e-3, fatol: float = 1e-6,
                       coarse: Callable[[np.ndarray], float] | None = None) -> tuple[np.ndarray, float]:
    """Evaluate ``fun`` on the start ``grid`` (G, P), then run Nelder-Mead (``max_evals`` x P evaluations, first
    simplex edge ``steps[j]`` along parameter j) from the ``n_starts`` best starts; returns the best (x, value).

    Why: the physics fits (a gap candidate's parameters, a calibration preset's free parameters) have multimodal,
    non-smooth robust losses (headings, floors); a coarse grid finds the basin and the simplex polishes it.  The
    caller clips or wraps x into its bounds (``fun`` should do the same).  ``coarse``: a cheaper version of
    ``fun`` (fewer samples) that ranks the grid, so that a dense grid costs little; the starts are then
    scored with ``fun``.
    """
    grid = np.asarray(grid, dtype=float).reshape(len(grid), -1)
    if coarse is not None and len(grid) > n_starts:
        cv = np.array([coarse(g) for g in grid])
        grid = grid[np.argsort(cv, kind="stable")[: max(n_starts, 3)]]
    vals = np.array([fun(g) for g in grid])
    best = None
    for k in np.argsort(vals, kind="stable")[:n_starts]:
        x0 = grid[k]
        simplex = np.vstack([x0] + [x0 + np.eye(len(x0))[j] * steps[j] for j in range(len(x0))])
        res = minimize(fun, x0, method="Nelder-Mead",
                       options={"maxfev": max_evals * len(x0), "initial_simplex": simplex, "xatol": xatol,
                                "fatol": fatol})
        if best is None or res.fun < best.fun:
            best = res
    assert best is not None
    return np.asarray(best.x, dtype=float), float(min(best.fun, vals.min()))

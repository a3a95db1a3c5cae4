"""Multi-start minimisation for the physics fits: a coarse grid finds the basin, Nelder-Mead
polishes it."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from scipy.optimize import minimize


def minimize_from_grid(
    fun: Callable[[np.ndarray], float],
    grid: np.ndarray,
    steps: Sequence[float],
    max_evals: int,
    n_starts: int = 1,
    xatol: float = 1e-3,
    fatol: float = 1e-6,
    coarse: Callable[[np.ndarray], float] | None = None,
    coarse_tol: tuple[float, float] = (5e-2, 1e-3),
) -> tuple[np.ndarray, float]:
    """Evaluate ``fun`` on the start ``grid`` (G, P), then run Nelder-Mead (``max_evals`` x P
    evaluations, first simplex edge ``steps[j]`` along parameter j) from the ``n_starts`` best
    starts; returns the best (x, value).

    Why: the physics fits (a gap candidate's parameters, a calibration preset's free parameters)
    have multimodal, non-smooth robust losses (headings, floors); a coarse grid finds the basin and
    the simplex polishes it.  The caller clips or wraps x into its bounds (``fun`` should do the
    same).  ``coarse``: a cheaper version of ``fun`` (fewer samples): it ranks the grid and polishes
    the ``n_starts`` best points, and only the best of those is polished on ``fun`` (several starts
    for about the price of one).  ``coarse_tol``: (xatol, fatol) of those coarse polishes: they
    only choose the basin, and the polish on ``fun`` starts a fresh simplex of edges ``steps``
    there, so polishing the thinned loss to ``xatol`` would be work thrown away (a quarter of a
    diagnosis's objective calls).
    """
    grid = np.asarray(grid, dtype=float).reshape(len(grid), -1)

    def nm(
        f: Callable[[np.ndarray], float], x0: np.ndarray, tol: tuple[float, float] = (xatol, fatol)
    ) -> Any:
        simplex = np.vstack([x0] + [x0 + np.eye(len(x0))[j] * steps[j] for j in range(len(x0))])
        return minimize(
            f,
            x0,
            method="Nelder-Mead",
            options={
                "maxfev": max_evals * len(x0),
                "initial_simplex": simplex,
                "xatol": tol[0],
                "fatol": tol[1],
            },
        )

    if coarse is not None and len(grid) > 1:
        # the n_starts best grid points polished on the cheap objective, the best of them polished
        # on ``fun``
        cv = np.array([coarse(g) for g in grid])
        polished = [
            nm(coarse, grid[k], coarse_tol) for k in np.argsort(cv, kind="stable")[:n_starts]
        ]
        x0 = np.asarray(min(polished, key=lambda r: r.fun).x, dtype=float)
        v0 = fun(x0)
        res = nm(fun, x0)
        return (
            (np.asarray(res.x, dtype=float), float(res.fun)) if res.fun <= v0 else (x0, float(v0))
        )
    vals = np.array([fun(g) for g in grid])
    best = None
    for k in np.argsort(vals, kind="stable")[:n_starts]:
        res = nm(fun, grid[k])
        if best is None or res.fun < best.fun:
            best = res
    assert best is not None
    return np.asarray(best.x, dtype=float), float(min(best.fun, vals.min()))

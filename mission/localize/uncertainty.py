"""Uncertainty regions of a transmitter estimate: highest-posterior-density (HPD) sets on the search
grid.

Why HPD sets and not only an ellipse: with a partial flight the posterior is often banana-shaped or
split (the transmitter may lie on either side of a leg); the HPD set follows that shape.  Each
region is also summarised as the ellipse of the same mass under a Gaussian fit to the region's
posterior (centre, semi-axes, orientation), which is what a user compares first.

Each region is a ``mission.localize.region.Region``; its JSON layout (``localize --json``, key
``regions``, ``Region.to_dict``): a list, one entry per level::

    {"level": 0.9,               # nominal probability that the transmitter lies inside
     "hpd_mass": 0.93,           # posterior mass of the set (the level recalibrated on the
                                 # benchmark)
     "area_m2": 5400.0,          # area of the HPD set
     "density": 1.2e-4,          # posterior density threshold of the set (per m^2)
     "ellipse": {"x_m": .., "y_m": .., "a_m": .., "b_m": .., "angle_deg": ..},
                                 # a: semi-major, angle from east
     "polygons": [[[x, y], ...], ...]}   # closed outlines of the set (local ENU metres)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import logsumexp

from mission.localize.region import Ellipse, Polygon, Region


@dataclass
class Posterior:
    """A posterior over candidate positions on a regular grid: ``prob`` (ny, nx) sums to 1; ``grid``
    (ny, nx, 2)."""

    prob: np.ndarray
    grid: np.ndarray

    @property
    def cell_area_m2(self) -> float:
        g = self.grid
        dx = float(g[0, 1, 0] - g[0, 0, 0]) if g.shape[1] > 1 else 1.0
        dy = float(g[1, 0, 1] - g[0, 0, 1]) if g.shape[0] > 1 else 1.0
        return abs(dx * dy)

    def mass_threshold(self, level: float) -> float:
        """The probability per cell above which the cells hold ``level`` of the mass (HPD
        threshold)."""
        p = np.sort(self.prob.ravel())[::-1]
        c = np.cumsum(p)
        i = int(np.searchsorted(c, level * c[-1]))
        return float(p[min(i, p.size - 1)])

    def _cell(self, x: float, y: float) -> tuple[int, int] | None:
        """(row, column) of the grid cell nearest (x, y); None for a point off the grid."""
        g = self.grid
        x0, y0 = g[0, 0]
        dx = g[0, 1, 0] - x0 if g.shape[1] > 1 else 1.0
        dy = g[1, 0, 1] - y0 if g.shape[0] > 1 else 1.0
        j, i = int(round((x - x0) / dx)), int(round((y - y0) / dy))
        return (i, j) if 0 <= i < g.shape[0] and 0 <= j < g.shape[1] else None

    def hpd_level(self, x: float, y: float) -> float:
        """The smallest HPD mass whose set holds (x, y): the mass of the cells more probable than
        its cell (1 for a point off the grid).  Over a benchmark its percentiles are the masses that
        cover the truth at the nominal rates (``benchmarks/calibrate_regions.py``)."""
        c = self._cell(x, y)
        if c is None:
            return 1.0
        p = self.prob
        return float(p[p > p[c]].sum() / p.sum())

    def covers(self, x: float, y: float, level: float) -> bool:
        """True when (x, y) lies in the HPD set of mass ``level`` (a point off the grid is not
        covered)."""
        return self.hpd_level(x, y) < level


def grid_posterior(logp: np.ndarray, shape: tuple[int, int]) -> Posterior:
    """Normalised posterior on the grid from log-likelihoods (H, ny * nx) of H nuisance hypotheses
    (marginalised with equal prior weights; -inf marks cells outside the search area)."""
    lp = logsumexp(logp, axis=0) if logp.ndim == 2 else logp
    lp = lp - np.max(lp)
    p = np.exp(lp)
    p /= p.sum()
    return Posterior(p.reshape(shape), None)  # type: ignore[arg-type]


def _ellipse(pts: np.ndarray, w: np.ndarray, level: float) -> Ellipse:
    """Ellipse of probability ``level`` for a Gaussian with the weighted mean and covariance of
    ``pts``."""
    w = w / w.sum()
    mu = (w[:, None] * pts).sum(axis=0)
    d = pts - mu
    cov = (w[:, None, None] * d[:, :, None] * d[:, None, :]).sum(axis=0)
    vals, vecs = np.linalg.eigh(cov)
    # scipy.stats stays lazy (noqa): 0.5-0.8 s to import, and only the routes with regions get here
    from scipy.stats import chi2  # noqa: PLC0415

    k = float(np.sqrt(chi2.ppf(level, 2)))
    a, b = k * np.sqrt(np.maximum(vals[::-1], 0.0))
    ang = float(np.degrees(np.arctan2(vecs[1, 1], vecs[0, 1])))
    return Ellipse(float(mu[0]), float(mu[1]), float(a), float(b), ang)


def hpd_regions(
    post: Posterior,
    grid: np.ndarray,
    levels: tuple[float, ...] = (0.5, 0.9),
    masses: dict[float, float] | None = None,
) -> tuple[Region, ...]:
    """The HPD regions of ``post`` at each nominal level (``Region``; JSON: the module docstring
    layout); also attaches ``grid`` to it.

    ``masses`` maps a nominal level to the HPD mass that covers the truth at that rate on a
    benchmark (a recalibration of the posterior's credible levels); without it the HPD mass is the
    nominal level.
    """
    # contourpy stays lazy (noqa): only the routes with regions draw them (localize --method grid
    # starts without it)
    import contourpy  # noqa: PLC0415

    post.grid = grid
    pts = grid.reshape(-1, 2)
    p = post.prob.ravel()
    out = []
    gen = (
        contourpy.contour_generator(grid[..., 0], grid[..., 1], post.prob)
        if min(post.prob.shape) > 1
        else None
    )
    for lev in levels:
        mass = float((masses or {}).get(lev, lev))
        thr = post.mass_threshold(mass)
        inside = p >= thr
        polys: list[Polygon] = []
        if gen is not None and inside.sum() >= 1:
            for line in gen.lines(thr * (1 - 1e-9)):
                arr = np.asarray(line)
                if arr.ndim == 2 and len(arr) >= 3:
                    polys.append(tuple(map(tuple, np.round(arr, 1).tolist())))
        out.append(
            Region(
                level=float(lev),
                mass=mass,
                area_m2=float(inside.sum() * post.cell_area_m2),
                density=float(thr / post.cell_area_m2),
                ellipse=_ellipse(pts[inside], p[inside], mass)
                if inside.sum() > 2
                else _ellipse(pts, p, mass),
                polygons=tuple(polys),
            )
        )
    return tuple(out)


def region_covers(est, x: float, y: float, level: float) -> bool | None:
    """Whether ``est``'s region of nominal ``level`` holds (x, y); None when the estimate has no
    posterior."""
    post = getattr(est, "posterior", None)
    if post is None or post.grid is None:
        return None
    reg = est.region(level)
    return post.covers(x, y, level if reg is None else reg.mass)

"""Candidates: the positions a flight's estimators propose, each a hypothesis the flight's own RSS
can weigh.

Why: on every real flight one of the methods is close to the truth, a different one each time; a
ghost mode of a posterior is a position like any other.  So every estimator hands over its point,
and a method with a posterior also each separate mode of it with the mode's mass
(``posterior_modes``); a network facing a track or attitude outside its training still proposes its
point, marked ``in_domain=False``, and is weighed rather than trusted or dropped.
``mission.localize.stacking`` scores them.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.ndimage import maximum_filter


@dataclass(frozen=True)
class Candidate:
    """A proposed transmitter position in the log's ENU frame (metres) and where it came from.

    ``mass``: the posterior mass of the mode it stands for (None for a point estimate without a
    posterior); ``evidence``: the flight's held-out log predictive density of it relative to the
    best candidate (nats, 0 for the best; set by the stacking stage); ``weight``: its stacking
    weight.
    """

    x_m: float
    y_m: float
    source: str
    mass: float | None = None
    in_domain: bool = True
    evidence: float | None = None
    weight: float | None = None

    @property
    def xy(self) -> np.ndarray:
        return np.array([self.x_m, self.y_m])

    def scored(self, evidence: float, weight: float) -> Candidate:
        """The same candidate with its evidence and weight."""
        return replace(self, evidence=float(evidence), weight=float(weight))

    def line(self) -> str:
        """The candidate in one line of ``localize``'s table: weight, source, point, evidence (a
        candidate no held-out RSS scored, such as the adaptive answer's survey network, says so)."""
        dom = "" if self.in_domain else ", outside training"
        ev = "not scored" if self.evidence is None else f"{self.evidence:+.1f} nats"
        return (
            f"{self.weight or 0.0:.2f} {self.source}: {self.x_m:.0f}, {self.y_m:.0f} m ({ev}{dom})"
        )

    def to_dict(self) -> dict:
        d = {"source": self.source, "x_m": round(self.x_m, 2), "y_m": round(self.y_m, 2)}
        if self.mass is not None:
            d["mode_mass"] = round(self.mass, 4)
        d["in_domain"] = self.in_domain
        if self.evidence is not None:
            d["evidence_nats"] = round(self.evidence, 3)
        if self.weight is not None:
            d["weight"] = round(self.weight, 4)
        return d


def posterior_modes(
    prob: np.ndarray,
    grid: np.ndarray,
    min_mass: float = 0.05,
    sep_m: float = 30.0,
    max_modes: int = 3,
) -> list[tuple[float, float, float]]:
    """The separate modes of a grid posterior as (x, y, mass), most massive first.

    A mode is a local maximum over a window of ``sep_m``; every grid cell belongs to the nearest
    mode (its basin), and a mode's mass is its basin's.  Modes lighter than ``min_mass`` are dropped
    (their mass is not redistributed: the masses kept may sum to less than 1).
    """
    p = np.asarray(prob, float)
    step = float(np.hypot(*(grid[0, 1] - grid[0, 0]))) if p.shape[1] > 1 else 1.0
    size = max(3, int(round(sep_m / max(step, 1e-9))) | 1)
    peak = (p == maximum_filter(p, size=size, mode="constant", cval=-1.0)) & (p > 0)
    iy, ix = np.nonzero(peak)
    if iy.size == 0:
        return []
    # a plateau can make many ties: the highest few
    order = np.argsort(p[iy, ix])[::-1][: 4 * max_modes]
    pk = grid[iy[order], ix[order]]  # (P, 2)
    pts = grid.reshape(-1, 2)
    basin = np.argmin(((pts[:, None, :] - pk[None, :, :]) ** 2).sum(-1), axis=1)
    mass = np.bincount(basin, weights=p.ravel(), minlength=len(pk)) / max(p.sum(), 1e-300)
    keep = [i for i in np.argsort(mass)[::-1] if mass[i] >= min_mass][:max_modes]
    return [(float(pk[i, 0]), float(pk[i, 1]), float(mass[i])) for i in keep]


def dedupe(cands: list[Candidate], tol_m: float = 2.0) -> list[Candidate]:
    """Candidates with the near-duplicates (within ``tol_m`` of an earlier one) left out, order
    kept."""
    out: list[Candidate] = []
    for c in cands:
        if all(np.hypot(c.x_m - o.x_m, c.y_m - o.y_m) > tol_m for o in out):
            out.append(c)
    return out

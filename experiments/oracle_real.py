"""What do the real flights allow?  The self-calibrating model with its nuisance fitted *at the
truth*.

Why: issue 10 asks for under 15 m mean held out by team on the six shared flights.  Before chasing
that figure, measure what the search's own model class reaches when it is handed what no estimator
has: for each flight the UAV-antenna hypothesis and RSS offset (rung "h+c"), or those and a free
path-loss exponent (rung "h+c+n"), least-squares fitted to that flight's cells *with the transmitter
at its labelled position* (in-sample, a leak by design).  Only the position is then searched (2 m
grid over the rover area).  Its error is a floor for every estimator of that model class on that
flight: what is left is shadowing and multipath the model cannot express.  The profiled search
(selfcal, the default's component) on the same grid is printed beside.

    python experiments/oracle_real.py --mat ../shared/data/afar2023/mat          # ~10 s
"""

from __future__ import annotations

import argparse
import tempfile

import numpy as np

from mission.flightlog import read_flight_log
from mission.localize.api import search_area
from mission.localize.classical import as_flight
from mission.localize.preprocess import select_samples
from mission.localize.selfcal import (
    SelfCalibratingGrid,
    _geometry,
    antenna_hypotheses,
    cell_average,
    hypothesis_residuals,
    hypothesis_ssr,
)
from mission.workshop.evaluate import import_afar

# 288 location 3 (suspect label, models/README.md): reported as the mean of the other five too
SUSPECT = 2
STEP_M = 2.0


def _minus_gain(geom: tuple[np.ndarray, ...], hyp) -> np.ndarray:
    """-G_h (K, M) dB: the hypothesis' gain toward each candidate, as ``hypothesis_residuals``
    subtracts it."""
    pg, el, az, el_uav = geom
    return next(hypothesis_residuals(np.zeros_like(pg), el, az, [hyp], el_uav=el_uav))


def fit_at_truth(
    y: np.ndarray, geom_t: tuple[np.ndarray, ...], hyps, free_n: bool
) -> tuple[int, np.ndarray]:
    """The hypothesis index and coefficients (offset c, and the exponent term 10 n when ``free_n``)
    that fit the cells ``y`` (M,) best with the transmitter at the truth (least squares; ``geom_t``
    from ``_geometry`` of one candidate).  Model: y = c + G_h + (10 n / 20) pg, pg = -20 log10 d (n
    = 2 when not free)."""
    best = (np.inf, 0, np.zeros(2))
    for h, hyp in enumerate(hyps):
        t = y + _minus_gain(geom_t, hyp)[0]
        x = np.column_stack([np.ones_like(y), geom_t[0][0] / 20.0])
        coef = (
            np.linalg.lstsq(x, t, rcond=None)[0]
            if free_n
            else np.array([np.mean(t - geom_t[0][0]), 20.0])
        )
        ss = float(((t - x @ coef) ** 2).sum())
        if ss < best[0]:
            best = (ss, h, coef)
    return best[1], best[2]


def search_setup(log, f) -> tuple:
    """(the search, its antenna hypotheses, its 2 m grid inside the rover area, the label) for the
    flight samples ``f`` of ``log``."""
    sc = SelfCalibratingGrid(area=search_area(log), step_m=STEP_M)
    hyps = antenna_hypotheses(sc.hypotheses, sc.heading_step_deg)
    grid, _, poly = sc._candidates(f)
    grid = grid.reshape(-1, 2)
    if poly is not None:
        grid = grid[poly.contains(grid)]
    return sc, hyps, grid, np.asarray(log.truth_enu[:2])


def oracle_error(cells, grid, truth, hyps, tx_height_m: float, free_n: bool) -> tuple[float, str]:
    """(error m, the fit in words) of the oracle: the nuisance fitted on ``cells`` at the truth
    (``fit_at_truth``), then the position searched on ``grid``."""
    y = cells.rss_dbm.astype(float)
    geom_t, geom = (
        _geometry(truth[None, :], cells, tx_height_m),
        _geometry(grid, cells, tx_height_m),
    )
    h, (c, k) = fit_at_truth(y, geom_t, hyps, free_n)
    pred = c + k * geom[0] / 20.0 - _minus_gain(geom, hyps[h])
    j = int(np.argmin(((y[None, :] - pred) ** 2).sum(axis=1)))
    return float(np.hypot(*(grid[j] - truth))), f"{hyps[h][0]}, n {k / 10:.1f}"


def one_flight(path) -> dict:
    """Errors (m) of the two oracles and of the profiled search on one imported real log, same 2 m
    grid."""
    log = read_flight_log(path)
    part, _ = select_samples(log)
    f = as_flight(part)
    # the search's own cells, area and tx height
    sc, hyps, grid, truth = search_setup(log, f)
    cells = cell_average(f, sc.cell_m, sc.altitude_gap_m)
    out = {"flight": path.stem}
    for rung, free_n in (("h+c", False), ("h+c+n", True)):
        out[rung], out[rung + " fit"] = oracle_error(
            cells, grid, truth, hyps, sc.tx_height_m, free_n
        )
    ssr, _ = hypothesis_ssr(grid, cells, hyps, sc.tx_height_m)
    out["selfcal"] = float(np.hypot(*(grid[int(np.argmin(ssr.min(axis=0)))] - truth)))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=(__doc__ or "").split("\n")[0])
    ap.add_argument("--mat", required=True, help="folder of the AFAR 2023 .mat files")
    args = ap.parse_args()

    with tempfile.TemporaryDirectory() as tmp:
        rows = [one_flight(p) for p in import_afar(args.mat, tmp)]
    for r in rows:
        print(
            f"{r['flight']}: h+c {r['h+c']:6.1f} m ({r['h+c fit']})   h+c+n {r['h+c+n']:6.1f} m "
            f"({r['h+c+n fit']})   selfcal {r['selfcal']:6.1f} m"
        )
    for k in ("h+c", "h+c+n", "selfcal"):
        e = np.array([r[k] for r in rows])
        print(
            f"{k:8s} mean of {len(e)} {e.mean():5.1f} m, of the five trusted "
            f"{np.delete(e, SUSPECT).mean():5.1f} m"
        )


if __name__ == "__main__":
    main()

"""The evidence stage: every member's candidates, weighed by the flight's own held-out RSS, one
answer.

A meta-estimator in the shape of scikit-learn's ``StackingRegressor``: the members (the
self-calibrating search with each separate mode of its posterior, the calibrated-physics grid, the
spiral networks, the fusion of selfcal and ``rfsl_spiral_e2r``) each propose candidates
(``mission.localize.candidates``); the flight's blocked cross-validated predictive density scores
each and stacking gives their weights (``mission.localize.stacking``).  The answer is the
candidates' geometric median (``answer``: chosen by a rule written before scoring); the regions are
the HPD sets of the candidates' mixture weighted by the evidence, so two surviving candidates far
apart give two islands.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from mission.cells import cell_average
from mission.defaults import DEFAULT_TX_HEIGHT_M
from mission.localize import Estimate
from mission.localize.api import DEFAULT_PHYSICS_PRESET, run_member
from mission.localize.candidates import Candidate, dedupe, posterior_modes
from mission.localize.selfcal import SelfCalibratingGrid, antenna_hypotheses
from mission.localize.stacking import (
    blocked_scores,
    geometric_median,
    mixture_posterior,
    spread_m,
    stacking_weights,
)
from mission.localize.training_domain import altitude_note, flight_altitudes, flown_domain
from mission.localize.uncertainty import hpd_regions
from mission.shipped import shipped_model

MEMBER_NETWORKS = ("rfsl_spiral_e2r.onnx", "rfsl_spiral_e2r_ens5.onnx")
# each candidate's spread in the mixture regions (chosen of 20, 35, 50 m on the development split)
SIGMA_M = 35.0
# The mixture's background (``stacking.mixture_posterior``): a share of the mass spread over the
# search grid for the hypothesis that every candidate is wrong, growing with the candidates'
# disagreement (``background_share``), and the HPD masses that then cover the truth at the nominal
# rates. Chosen and calibrated by the rule of ``benchmarks/score_evidence.py regions-cv`` on all
# 200 benchmark flights: cross-fitted 49.5 % / 89.0 %; the six real flights 5 / 6 and 6 / 6
# (models/README.md, "The evidence stage", "Regions cross-fitted")
BACKGROUND_GAIN = 0.1  # share per 100 m of the candidates' spread
BACKGROUND_MAX = 0.8
CALIBRATED_MASS: dict[float, float] = {0.5: 0.758, 0.9: 0.988}


def background_share(cand_xy: np.ndarray, gain: float = BACKGROUND_GAIN) -> float:
    """The mixture's background share for candidates (K, 2): ``gain`` per 100 m of their spread
    (``stacking.spread_m``), at most ``BACKGROUND_MAX``."""
    return min(BACKGROUND_MAX, gain * spread_m(cand_xy) / 100.0)


def _network_candidates(
    part, origin, tx_height_m: float
) -> tuple[list[Candidate], dict[str, Estimate]]:
    """Each shipped spiral network's point, marked out of its training domain when the track's
    altitude or attitude is (``training_domain``): weighed, never dropped."""
    cands, ests = [], {}
    for name in MEMBER_NETWORKS:
        path = shipped_model(name)
        if path is None:
            continue
        net, est = run_member("onnx", part, origin, model_path=path, tx_height_m=tx_height_m)
        dom = net.card.domain
        off = (
            altitude_note(net.model_name, dom.altitude_m, flight_altitudes(part.enu()[:, 2]))
            or flown_domain(part, dom.attitude_deg, net.model_name)["attitude_note"]
        )
        label = Path(name).stem
        cands.append(Candidate(est.x_m, est.y_m, label, in_domain=off is None))
        ests[label] = est
    return cands, ests


def member_candidates(
    part, origin, area, tx_height_m: float = DEFAULT_TX_HEIGHT_M, physics_preset: str | None = None
) -> tuple[list[Candidate], dict[str, Estimate]]:
    """Every member's candidates (near-duplicates merged) and the members' estimates by name; the
    self-calibrating estimate comes first in both (its posterior grid carries the mixture
    regions)."""
    _, a = run_member("selfcal", part, origin, tx_height_m=tx_height_m, area=area)
    cands = [Candidate(a.x_m, a.y_m, "selfcal")]
    if a.posterior is not None:
        modes = posterior_modes(a.posterior.prob, a.posterior.grid)
        cands += [
            Candidate(x, y, f"selfcal mode {i + 1}", mass=m) for i, (x, y, m) in enumerate(modes)
        ]
    preset = physics_preset or DEFAULT_PHYSICS_PRESET
    _, g = run_member(
        "grid", part, origin, tx_height_m=tx_height_m, area=area, physics_preset=preset
    )
    cands.append(Candidate(g.x_m, g.y_m, f"grid {preset}"))
    nets, net_ests = _network_candidates(part, origin, tx_height_m)
    cands += nets
    # today's default, a candidate like the rest
    if nets and nets[0].source == Path(MEMBER_NETWORKS[0]).stem:
        cands.append(Candidate(0.5 * (a.x_m + nets[0].x_m), 0.5 * (a.y_m + nets[0].y_m), "fusion"))
    return dedupe(cands), {"selfcal": a, f"grid {preset}": g, **net_ests}


def selfcal_scores(cells, xy: np.ndarray, tx_height_m: float, block=None):
    """Blocked held-out scores (``stacking.blocked_scores``) of the points ``xy`` on ``cells``,
    under the self-calibrating search's antenna hypotheses and temperature (its independent cells
    per cell); ``block``: the caller's blocks, else squares."""
    sc = SelfCalibratingGrid(tx_height_m=tx_height_m)
    n_eff = max(cells.area_m2 / (np.pi * sc.corr_m**2), 2.0)
    return blocked_scores(
        cells,
        xy,
        antenna_hypotheses(sc.hypotheses, sc.heading_step_deg),
        tx_height_m,
        tau=min(n_eff / len(cells), 1.0),
        block=block,
    )


def selfcal_cells(part, tx_height_m: float = DEFAULT_TX_HEIGHT_M):
    """``part``'s rows (a log's selection or its samples) averaged into the self-calibrating
    search's cells: what the held-out scores are computed on."""
    sc = SelfCalibratingGrid(tx_height_m=tx_height_m)
    samples = part.samples() if hasattr(part, "samples") else part
    return cell_average(samples, sc.cell_m, sc.altitude_gap_m)


def score_candidates(part, cands: list[Candidate], tx_height_m: float = DEFAULT_TX_HEIGHT_M):
    """The flight's blocked held-out scores of the candidates (``stacking.BlockedScores``), on the
    self-calibrating search's cells (``selfcal_cells``, ``selfcal_scores``)."""
    cells = selfcal_cells(part, tx_height_m)
    return selfcal_scores(cells, np.array([[c.x_m, c.y_m] for c in cands]), tx_height_m)


def answer(cands: list[Candidate]) -> tuple[float, float]:
    """The stage's point: the geometric median of the candidates (``stacking.geometric_median``).

    Chosen by the rule in ``benchmarks/score_evidence.py`` on the benchmark's development split
    (flights 0-59), where every scheme that let the flight's held-out RSS pick or weight the point
    erred more than the default (the evidence favours the candidate fitted on the same physics: see
    models/README.md, "The evidence stage"), and the unweighted median erred less.  The evidence
    weighs the regions.
    """
    x, y = geometric_median(np.array([c.xy for c in cands]))
    return float(x), float(y)


def evidence_stage(
    part,
    origin,
    area,
    tx_height_m: float = DEFAULT_TX_HEIGHT_M,
    physics_preset: str | None = None,
    **_,
) -> Estimate:
    """Localize ``part`` (the selected samples of a log) with the evidence stage (module docstring);
    the estimate's ``candidates`` hold every candidate with its evidence and weight, most weight
    first."""
    cands, members = member_candidates(part, origin, area, tx_height_m, physics_preset)
    scores = score_candidates(part, cands, tx_height_m)
    w = stacking_weights(scores.block_lpd)
    x, y = answer(cands)
    cands = [c.scored(e, wi) for c, e, wi in zip(cands, scores.evidence, w, strict=True)]
    cands = [cands[i] for i in np.argsort(-w, kind="stable")]
    lat, lon, _ = origin.to_geodetic(np.array([x, y, 0.0]))
    est = Estimate(x, y, "evidence", f"median of {len(cands)} candidates", float(lat), float(lon))
    sc = members["selfcal"]
    if sc.posterior is not None and sc.posterior.grid is not None:
        grid = sc.posterior.grid
        xy = np.array([c.xy for c in cands])
        post = mixture_posterior(
            xy, np.array([c.weight for c in cands]), grid, SIGMA_M, background_share(xy)
        )
        est.regions = hpd_regions(post, grid, (0.5, 0.9), CALIBRATED_MASS)
        est.posterior = post
    est.extras["candidates"] = [c.to_dict() for c in cands]
    est.extras["evidence_blocks"] = int(scores.block.max()) + 1
    est.extras["evidence_tau"] = scores.tau
    est.candidates = cands
    est.set_components(members)
    return est

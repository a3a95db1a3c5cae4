"""The answer of an adaptive flight: the candidates its survey proposes, weighed by its rounds.

Why (issue 33 item 1): the live method (``methods.ADAPTIVE_METHOD``) plans the rounds, but on its
own it lands on ghosts; the network that answers a fixed spiral sees only the survey part of an
adaptive flight.  Both propose a position, and the rounds (flown after, low, around the estimate)
are data neither used to propose it: with the transmitter fixed at each candidate, the per-flight
nuisance (offset, path-gain slope, antenna) is fitted on the survey's cells and the rounds' cells
are scored (``stacking.blocked_scores`` with the survey and the rounds as its two blocks).  The
answer is the candidate the rounds support best, unless the network's physics holds on this
flight (``physics_spread_db``): then the network trained on this survey answers
(docs/adaptive.md, "A network that answers only where its physics holds").  The regions are the
live method's.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from mission.cells import cell_average, concat_cells
from mission.defaults import DEFAULT_TX_HEIGHT_M
from mission.errors import InputError
from mission.flightlog import ADAPTIVE
from mission.localize import Estimate
from mission.localize.api import choose_method, default_model_path, run_member
from mission.localize.candidates import Candidate
from mission.localize.evidence_stage import selfcal_scores
from mission.localize.methods import ADAPTIVE_METHOD, composer, method_entry
from mission.localize.selfcal import SelfCalibratingGrid
from mission.localize.sim_default import SPIRAL_NETWORKS, SPIRAL_SOURCE_MODEL
from mission.localize.training_domain import altitude_note, flight_altitudes
from mission.physics import make_model
from mission.shipped import resolve_shipped, shipped_model
from mission.spec import load_mission

SURVEY, ROUNDS = 0, 1  # the two blocks
# the network trained on the surveys of an adaptive spiral (rfsl dataset of the adaptive mission:
# planner.flown_ahead); it answers a survey of the length it was trained on, where a spiral network
# would see only part of the path it learned
SURVEY_NETWORK = "rfsl_survey_e2r.onnx"
SURVEY_S_TOLERANCE = 0.05  # relative: a survey this much shorter or longer is another kind of path
# the gate: the survey's RSS departs from the networks' training physics at their answer by at most
# this robust spread (dB): the 95th percentile on 40 surveys flown under the mission's own physics
# (calibration seed 5000: bench_adaptive.py --json, physics_spread_db; docs/adaptive.md)
PHYSICS_SPREAD_DB = 5.21


def survey_and_rounds(part) -> tuple[object, np.ndarray] | None:
    """(the survey's rows, the rounds mask) of an adaptive flight's selected samples (the mask may
    hold no round yet); None when the log has no phase column or too little survey."""
    phase = part.columns.get("phase")
    if phase is None:
        return None
    rounds = np.asarray(phase).astype(str) == ADAPTIVE
    if (~rounds).sum() < 2:
        return None
    return part.select(~rounds), rounds


def survey_domain(model_path) -> tuple[float, tuple[float, float]] | None:
    """(survey length s, cruise altitude span m) a network was trained on: its training datasets'
    adaptive mission's ``survey_s`` when every dataset flew one and the same, and its card's
    altitude span; None when either is unknown (no claim is better than a wrong one)."""
    from mission.localize.onnx_model import OnnxLocalizer  # noqa: PLC0415  (onnxruntime, lazy)

    card = OnnxLocalizer(model_path, threads=1).card
    datasets = (card.meta.get("training_data") or {}).get("datasets") or []
    seen = set()
    for d in datasets:
        try:
            a = load_mission(resolve_shipped(d.get("mission") or "", "missions", ".yaml")).adaptive
        except InputError:  # a missing or foreign mission file: no claim
            return None
        if a is None or not a.enabled:
            return None
        seen.add(float(a.survey_s))
    if len(seen) != 1 or card.domain.altitude_m is None:
        return None
    return seen.pop(), card.domain.altitude_m


def survey_network(meta: dict, heights_m: np.ndarray, model) -> object:
    """``SURVEY_NETWORK`` in place of ``model`` when ``model`` is a spiral network (the survey is
    that kind of flight), the adaptive record's ``survey_s`` is the one the survey network was
    trained on and the survey flew at its altitudes (``heights_m``); else ``model``."""
    path = shipped_model(SURVEY_NETWORK)
    if path is None or model is None or Path(model).name not in SPIRAL_NETWORKS:
        return model
    record = (meta.get("trajectory") or {}).get("adaptive")
    flown = record.get("survey_s") if isinstance(record, dict) else None
    trained = survey_domain(path)
    if flown is None or trained is None:
        return model
    survey_s, altitude_m = trained
    same_path = abs(float(flown) - survey_s) <= SURVEY_S_TOLERANCE * survey_s
    at_height = altitude_note(SURVEY_NETWORK, altitude_m, flight_altitudes(heights_m)) is None
    return path if same_path and at_height else model


def fixed_choice(part) -> tuple[str, object]:
    """(method, model path) ``localize`` would take for the survey part as if it were a fixed
    flight of this kind (``api.choose_method`` on the sidecar without its adaptive record)."""
    meta = dict(part.meta)
    meta["trajectory"] = {
        k: v for k, v in (meta.get("trajectory") or {}).items() if k != "adaptive"
    }
    method, model, _ = choose_method(meta, part.enu()[:, 2], None, default_model_path())
    return method, model


def fixed_default(part, origin, area, tx_height_m: float, method=None, model=None) -> Estimate:
    """What ``localize`` answers for the survey part as if it were a fixed flight of this kind
    (``fixed_choice``), or with the given ``method`` and ``model``."""
    if method is None:
        method, model = fixed_choice(part)
    entry = method_entry(method)
    kw = {"model_path": model, "tx_height_m": tx_height_m}
    if entry.compose is not None:
        return composer(entry)(part, origin, area, **kw)
    return run_member(method, part, origin, area=area if entry.bounded else None, **kw)[1]


def rounds_scores(survey, rounds, xy: np.ndarray, tx_height_m: float) -> np.ndarray:
    """(K,) the held-out log predictive density (tempered nats) of each candidate at the rounds'
    rows ``rounds``, the nuisance fitted on the survey's rows ``survey`` only."""
    sc = SelfCalibratingGrid(tx_height_m=tx_height_m)
    parts = [cell_average(p.samples(), sc.cell_m, sc.altitude_gap_m) for p in (survey, rounds)]
    block = np.repeat([SURVEY, ROUNDS], [len(c) for c in parts])
    return selfcal_scores(concat_cells(parts), xy, tx_height_m, block).block_lpd[:, ROUNDS]


def physics_spread_db(survey, xy, tx_height_m: float) -> float:
    """Robust spread (1.4826 x MAD, dB) of the survey's RSS minus the spiral networks' training
    physics (e2r, dipoles, the log's attitude) with the transmitter at ``xy``, median removed: a few
    dB where that physics holds, the shadowing's spread where it does not."""
    s = survey.samples()
    tx = np.array([xy[0], xy[1], tx_height_m], dtype=float)
    pred = make_model(SPIRAL_SOURCE_MODEL).rss_dbm(tx, s.enu_m, s.attitude_rad)
    r = np.asarray(s.rss_dbm, dtype=float) - np.asarray(pred, dtype=float)
    return float(1.4826 * np.median(np.abs(r - np.median(r))))


def rounds_answer(part, origin, area, tx_height_m: float = DEFAULT_TX_HEIGHT_M, **_) -> Estimate:
    """The network's survey answer where its physics holds on this survey (``physics_spread_db``);
    else the live method on the whole flight or the fixed flight's default on the survey, the
    candidate the rounds support best (module docstring); the live method's answer alone when no
    round was flown."""

    live = run_member(ADAPTIVE_METHOD, part, origin, area=area, tx_height_m=tx_height_m)[1]
    split = survey_and_rounds(part)
    if split is None:
        live.add_note("no survey phase among the selected samples: the live method answers")
        return live
    survey, rounds = split
    if rounds.sum() < 2:  # nothing held out yet (the survey in flight): the live method answers
        live.add_note("no adaptive round among the selected samples: the live method answers")
        return live
    method, model = fixed_choice(survey)
    fixed = fixed_default(survey, origin, area, tx_height_m, method, model)
    cands = [
        Candidate(live.x_m, live.y_m, f"{ADAPTIVE_METHOD}, whole flight"),
        Candidate(fixed.x_m, fixed.y_m, f"{fixed.method}, survey"),
    ]
    lpd = rounds_scores(survey, part.select(rounds), np.array([c.xy for c in cands]), tx_height_m)
    w = np.exp(lpd - lpd.max())
    cands = [c.scored(e, wk) for c, e, wk in zip(cands, lpd - lpd.max(), w / w.sum(), strict=True)]
    best = cands[int(np.argmax(lpd))]
    members = {ADAPTIVE_METHOD: live, f"{fixed.method} (survey)": fixed}
    spread = None
    if method == "onnx":  # a network answers the survey: the one trained on it where shipped
        net = fixed
        swapped = survey_network(part.meta, survey.enu()[:, 2], model)
        if swapped != model:
            net = fixed_default(survey, origin, area, tx_height_m, method, swapped)
            members[f"{Path(swapped).stem} (survey)"] = net
        spread = physics_spread_db(survey, (net.x_m, net.y_m), tx_height_m)
        if spread <= PHYSICS_SPREAD_DB:
            best = Candidate(net.x_m, net.y_m, f"{net.method}, survey, in its physics")
            cands.append(best)
    lat, lon, _ = origin.to_geodetic(np.array([best.x_m, best.y_m, 0.0]))
    est = Estimate(best.x_m, best.y_m, "rounds", best.source, float(lat), float(lon))
    est.regions = live.regions  # the live method's: the stage picks a point, it fits no posterior
    est.posterior = live.posterior
    if spread is not None:
        est.extras["physics_spread_db"] = round(spread, 2)
    est.extras["candidates"] = [c.to_dict() for c in cands]
    est.candidates = sorted(cands, key=lambda c: (c is not best, -(c.weight or 0.0)))
    est.set_components(members)
    if best.weight is None:
        est.add_note(
            f"the survey departs from the network's physics by {spread:.1f} dB (at most "
            f"{PHYSICS_SPREAD_DB:.1f} dB): the network answers; the regions are the live method's"
        )
    elif best is not cands[0]:
        est.add_note(
            f"the rounds support {best.source} over the live method by "
            f"{best.evidence - cands[0].evidence:.1f} nats; the regions are the live method's"
        )
    return est

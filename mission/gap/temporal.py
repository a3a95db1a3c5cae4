"""Effects that live in time: a gain that drifts or steps over a flight, as a candidate and a power
statement.

Why: a receiver or transmitter whose gain is not constant over the flight (warming up, an AGC step,
a cable moved at a waypoint) leaves a residual that follows the flight's *time*, not its geometry.
No geometric candidate can draw it, so it was blamed on shadowing or a path-gain slope.
``time_drift`` is a free-form basis over each flight's own time, fitted per flight (the offset is
per flight, so is its drift):

| part | columns (per flight) | ridge weight |
| --- | --- | --- |
| smooth drift | Legendre P_1..P_4 of the flight's time scaled to [-1, 1] | 1 + p^2 |
| steps at events | H(t - t_e) per ``flight_events`` event (phase change, turn) | ``STEP_WEIGHT`` |

Events: a change of the log's phase column, or a turn (the heading changes by at least ``TURN_DEG``
within ``TURN_WINDOW_S``), at least ``MIN_EVENT_GAP_S`` apart, at most ``MAX_EVENTS`` per flight.

Ridge lambda by inner two-fold CV over alternate 30 s stretches of flight (``freeform.ridge_cv``, as
every free-form map).  A per-flight term predicts held-out *chunks* of a flight it was trained on;
it cannot say anything about a flight held out whole (it has no coefficients for it), so with
``split="flights"`` it is not tried, and the power statement says so.  ``time_power_statement`` runs
the ranking's own test on the flights at hand with a drift of known size injected: the smallest
drift the diagnosis could show.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from mission.gap.candidate import TIER_FREEFORM, Candidate
from mission.gap.fit import compare, decimate
from mission.gap.freeform import _legendre_all, ridge_cv
from mission.gap.pipeline import Pipeline, memo
from mission.robust import offset_residual
from mission.samples import FlightSamples

DRIFT_ORDER = 4
STEP_WEIGHT = 4.0
TURN_DEG, TURN_WINDOW_S = 60.0, 10.0
MIN_EVENT_GAP_S = 20.0
MAX_EVENTS = 16
LAMBDAS = tuple(np.geomspace(1e-4, 1e2, 13))
NAME = "time_drift"


def flight_events(flight: FlightSamples) -> np.ndarray:
    """Times (s) at which a gain might step: changes of the phase column and the sharpest turns
    (heading change over ``TURN_WINDOW_S`` of at least ``TURN_DEG``), at least
    ``MIN_EVENT_GAP_S`` apart, at most ``MAX_EVENTS`` (the strongest turns first), never within
    the first or last 10 s."""
    t = np.asarray(flight.t_s, dtype=float)
    if len(t) < 5:
        return np.zeros(0)
    cand: list[tuple[float, float]] = []  # (strength, time)
    if flight.phase is not None:
        ph = np.asarray(flight.phase)
        ch = np.nonzero(ph[1:] != ph[:-1])[0] + 1
        cand += [(1e9, float(t[i])) for i in ch]
    if flight.attitude_rad is not None:
        yaw = np.unwrap(np.asarray(flight.attitude_rad[:, 2], dtype=float))
        half = TURN_WINDOW_S / 2
        change = np.abs(np.interp(t + half, t, yaw) - np.interp(t - half, t, yaw))
        deg = np.rad2deg(change)
        peak = (deg >= TURN_DEG) & (deg >= np.r_[deg[1:], -1.0]) & (deg > np.r_[-1.0, deg[:-1]])
        rate = np.abs(np.diff(yaw))  # the turn itself: the fastest heading change near the peak
        for i in np.nonzero(peak)[0]:
            w = np.nonzero(np.abs(t[:-1] - t[i]) <= TURN_WINDOW_S)[0]
            j = int(w[np.argmax(rate[w])]) if len(w) else i
            cand.append((float(deg[i]), float(t[min(j + 1, len(t) - 1)])))
    lo, hi = t[0] + 10.0, t[-1] - 10.0
    chosen: list[float] = []
    for _, te in sorted(cand, key=lambda c: (-c[0], c[1])):
        if lo <= te <= hi and all(abs(te - c) >= MIN_EVENT_GAP_S for c in chosen):
            chosen.append(te)
        if len(chosen) >= MAX_EVENTS:
            break
    return np.sort(np.array(chosen, dtype=float))


def time_columns(
    t: np.ndarray, t0: float, t1: float, events: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Design (N, K) of one flight's time basis and its ridge weights (module table)."""
    u = np.clip(2.0 * (np.asarray(t, dtype=float) - t0) / max(t1 - t0, 1e-9) - 1.0, -1.0, 1.0)
    cols = _legendre_all(u, DRIFT_ORDER)[1:] + [(t >= e).astype(float) for e in events]
    pen = [1.0 + p * p for p in range(1, DRIFT_ORDER + 1)] + [STEP_WEIGHT] * len(events)
    return np.column_stack(cols), np.array(pen)


@dataclass(frozen=True, eq=False)
class TimeTerm:
    """A fitted gain over each flight's time (dB), by flight name: (t0, t1, events,
    coefficients)."""

    per_flight: dict[str, tuple[float, float, np.ndarray, np.ndarray]]
    name: str = NAME

    def field_db(self, flight: FlightSamples, t: np.ndarray) -> np.ndarray:
        part = self.per_flight.get(flight.name)
        if part is None:
            return np.zeros(len(t))
        t0, t1, ev, coef = part
        return memo(
            self,
            (np.asarray(t, dtype=float),),
            lambda: time_columns(t, t0, t1, ev)[0] @ coef,
            extra=flight.name,
        )

    def shape(self, flight: FlightSamples, n: int = 60) -> dict[str, list[float]]:
        """The term on a regular grid of the flight's time (for JSON and plots)."""
        part = self.per_flight.get(flight.name)
        if part is None:
            return {}
        tt = np.linspace(part[0], part[1], n)
        return {
            "t_s": tt.tolist(),
            "gain_db": self.field_db(flight, tt).tolist(),
            "events_s": part[2].tolist(),
        }


def fit_time_term(
    flights: Sequence[FlightSamples],
    idx: Sequence[np.ndarray],
    resid: Sequence[np.ndarray],
    loss: str = "l2",
    f_scale_db: float = 6.0,
    period_s: float = 30.0,
) -> tuple[TimeTerm, dict[str, Any]]:
    """Per flight a ridge fit of the offset-free training residuals on ``time_columns`` (block
    design: every flight's own columns), one lambda for all by inner two-fold CV over alternate
    ``period_s`` stretches."""
    use = [k for k, i in enumerate(idx) if len(i) >= 10 and flights[k].t_s is not None]
    blocks = []
    for k in use:
        f = flights[k]
        ev = flight_events(f)
        X, pen = time_columns(f.t_s[idx[k]], float(f.t_s[0]), float(f.t_s[-1]), ev)
        blocks.append((f, ev, X, pen))
    K = sum(X.shape[1] for _, _, X, _ in blocks)
    Xs, rs, ws, halves, pens, start = [], [], [], [], [], 0
    for (f, _, X, pen), k in zip(blocks, use, strict=True):
        full = np.zeros((len(X), K))
        full[:, start : start + X.shape[1]] = X
        start += X.shape[1]
        r = np.asarray(resid[k], dtype=float)
        Xs.append(full)
        rs.append(r)
        ws.append(np.ones(len(r)) if loss == "l2" else 1.0 / np.sqrt(1.0 + (r / f_scale_db) ** 2))
        halves.append(np.floor(f.t_s[idx[k]] / period_s).astype(int) % 2)
        pens.append(pen)
    if not blocks:
        return TimeTerm({}), {"lambda": 0.0, "size_db": 0.0, "events": {}}
    errs, fit_all = ridge_cv(Xs, rs, ws, halves, np.concatenate(pens), LAMBDAS)
    lam = float(LAMBDAS[int(np.argmin(errs))])
    coef = fit_all(lam)
    per, start, sizes, events = {}, 0, [], {}
    for f, ev, X, _ in blocks:
        c = coef[start : start + X.shape[1]]
        start += X.shape[1]
        per[f.name] = (float(f.t_s[0]), float(f.t_s[-1]), ev, c)
        v = X @ c
        sizes.append(float(np.quantile(v, 0.95) - np.quantile(v, 0.05)))
        events[f.name] = len(ev)
    term = TimeTerm(per)
    return term, {
        "lambda": lam,
        "size_db": float(np.mean(sizes)),
        "events": events,
        "drift_order": DRIFT_ORDER,
        "time_shapes": {f.name: term.shape(f) for f, _, _, _ in blocks},
    }


def time_candidate() -> Candidate:
    """``time_drift`` (module docstring): fills the pipeline's ``temporal`` slot; free-form tier."""

    # only via direct_fit
    def build(p: Pipeline, th: dict[str, float], ch: dict[str, Any]) -> Pipeline:
        return p

    def withhold(p: Pipeline) -> Pipeline:
        return p.replace(temporal=None)

    def direct_fit(
        p: Pipeline,
        flights: Sequence[FlightSamples],
        idx: Sequence[np.ndarray],
        resid: Sequence[np.ndarray],
        rng: np.random.Generator,
        cfg: Any = None,
    ) -> tuple[Pipeline, dict[str, Any]]:
        term, params = fit_time_term(
            flights, idx, resid, getattr(cfg, "loss", "l2"), getattr(cfg, "f_scale_db", 6.0)
        )
        return p.replace(temporal=term), params

    return Candidate(
        NAME,
        "a gain drifting or stepping over each flight's time (smooth drift + steps at turns "
        "and phase changes)",
        (),
        build,
        lambda p: p.temporal is None,
        withhold,
        direct_fit=direct_fit,
        tier=TIER_FREEFORM,
    )


def usable_in(split: str, flights: Sequence[FlightSamples]) -> bool:
    """A per-flight time term can be scored held out only on chunks of flights it was trained on."""
    return split != "flights" and all(f.t_s is not None for f in flights)


DRIFTS_DB = (0.25, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0, 12.0)


def time_power_statement(
    flights: Sequence[FlightSamples],
    resid: Sequence[np.ndarray],
    folds: Sequence[Any],
    cfg: Any,
    m: int,
    split: str,
    seed: int = 0,
) -> dict[str, Any]:
    """The smallest drift (dB from the flight's start to its end, linear) the ranking's held-out
    test would call significant on these flights: the drift is injected into the residuals,
    ``time_drift`` fitted on each fold's training samples (decimated as every fit is) and scored
    with ``fit.compare`` (``power.injected_test``'s method); ``detectable_db`` = the smallest drift
    on ``DRIFTS_DB`` from which on every larger one is significant (inf: not even the largest; with
    whole flights held out, inf by construction)."""
    if not usable_in(split, flights):
        return {
            "detectable_db": math.inf,
            "statement": "A gain drifting over a flight cannot be shown with whole "
            "flights held out (a per-flight term says nothing about another flight); --split "
            "blocks can.",
        }
    ramps = [
        2.0 * (f.t_s - f.t_s[0]) / max(float(f.t_s[-1] - f.t_s[0]), 1e-9) - 1.0 for f in flights
    ]

    def significant(D: float) -> bool:
        a = [np.asarray(r, float) - 0.5 * D * u for r, u in zip(resid, ramps, strict=True)]
        base = [np.full(len(x), np.nan) for x in a]
        new = [np.full(len(x), np.nan) for x in a]
        for fold in folds:
            n_used = max(1, sum(len(i) > 0 for i in fold.train))
            tr = [
                decimate(i, min(cfg.fit_max_samples, max(200, cfg.fit_max_total // n_used)))
                for i in fold.train
            ]
            ok = [i[np.isfinite(x[i])] for x, i in zip(a, tr, strict=True)]
            term, _ = fit_time_term(
                flights, ok, [x[i] for x, i in zip(a, ok, strict=True)], cfg.loss, cfg.f_scale_db
            )
            for k, i in enumerate(fold.test):
                if len(i):
                    x = a[k][i]
                    base[k][i] = offset_residual(
                        x, np.zeros(len(i)), False, cfg.loss, cfg.f_scale_db
                    )
                    new[k][i] = offset_residual(
                        x,
                        term.field_db(flights[k], flights[k].t_s[i]),
                        False,
                        cfg.loss,
                        cfg.f_scale_db,
                    )
        _, _, _, sig, _ = compare(base, new, cfg, m, np.random.default_rng(seed))
        return sig

    threshold = math.inf
    for D in DRIFTS_DB[::-1]:
        if not significant(D):
            break
        threshold = D
    seen = (
        f"a drift smaller than {threshold:.2g} dB over a flight cannot be shown held out"
        if math.isfinite(threshold)
        else f"a drift of any size up to {DRIFTS_DB[-1]:.0f} dB over a flight cannot be shown "
        "held out"
    )
    return {
        "detectable_db": threshold,
        "drifts_db": list(DRIFTS_DB),
        "method": "injected held-out test",
        "statement": f"Along time (a gain drifting over each flight, held out by chunks): {seen}.",
    }

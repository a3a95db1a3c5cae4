"""Free-form candidates: let the data draw the missing effect as a smooth map, then say what it
resembles.

Why: a library of named effects can only name what it contains; an antenna ripple, a notch or a
rover antenna's azimuth pattern outside the list would otherwise be blamed on shadowing.  Three
smooth additive terms (dB), each linear in its coefficients, so a fit is one regularised
least-squares solve:

| name | variables (from the LOS geometry the physics model already computes) | basis |
| --- | --- | --- |
| ``rx_gain_map`` | UAV body azimuth az_b x sin(body depression) | Fourier(M=6) x Legendre(P=3) |
| ``tx_gain_map`` | UAV compass azimuth from rover x sin(elevation) | Fourier(M=4) x Legendre(P=2) |
| ``excess_loss`` | log10(d_los / 100 m) and UAV height | Legendre(P=3) + Legendre(P=2) |

The constant is left out (the free per-flight offset absorbs it).  Coefficients are shrunk by a
ridge penalty lambda (1 + m^2 + p^2) (higher orders cost more: smooth maps), lambda chosen by an
inner two-fold split of the training samples (alternate 30 s stretches of flight, never random
samples); with a robust loss the solve is weighted by soft-L1 IRLS weights.  Each fit reports its
shape on a grid (``params["shape"]``, for the plot), its size (5-95 % range over the flown samples,
dB), where it acts (the geometry of its strongest departure) and which named effect it resembles
(largest |correlation| with that effect's own term on the same samples). The terms are
``mission.physics`` effects (``rss_term_db``), so a fitted map also serves localization.
``rx_gain_map`` is a body-frame map: on a model without the attitude effect it adds the logged
(roll, pitch, yaw) attitude together with the map (``params["adds_attitude"]``).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from types import SimpleNamespace
from typing import Any

import numpy as np
from numpy.polynomial import legendre

from mission.gap.candidate import TIER_FREEFORM, Candidate
from mission.gap.pipeline import Pipeline, memo, offset_residuals
from mission.physics import Attitude
from mission.physics.geometry import (
    bearing,
    body_azimuth,
    body_vectors,
    enu_to_ned,
    link_delta,
    sin_depression,
    sin_elevation,
    slant_distance,
)
from mission.samples import FlightSamples

# kind -> (first variable, second variable, orders); see the module table
KINDS: dict[str, tuple[int, int]] = {
    "rx_gain_map": (6, 3),
    "tx_gain_map": (4, 2),
    "excess_loss": (3, 2),
}
LAMBDAS = tuple(np.geomspace(1e-3, 1e3, 13))


def map_variables(kind: str, link: Any) -> tuple[np.ndarray, np.ndarray]:
    """The two variables of ``kind`` from a ``mission.physics.propagation.Link`` (or the same
    fields)."""
    dx, dy, dz = link.delta
    d = link.d_los
    if kind == "rx_gain_map":  # az_b, sin dep_b
        ubx, uby, ubz = link.u_b
        return body_azimuth(ubx, uby, signed=True), sin_depression(ubz, d)
    # compass bearing and sin elevation of the UAV seen from the transmitter
    if kind == "tx_gain_map":
        return bearing(-dx, -dy, signed=True), sin_elevation(-dz, d)
    if kind == "excess_loss":
        return np.clip(np.log10(d / 100.0), -1.0, 1.0), np.clip((link.z_r - 35.0) / 25.0, -1.0, 1.0)
    raise ValueError(f"unknown free-form kind {kind!r}")


def basis_orders(kind: str) -> list[tuple[str, int, int]]:
    """(function, order m, order p) per coefficient: ``c``/``s`` = cos/sin(m a) P_p(b); ``a``/``b``
    = P_m(a) or P_p(b) alone (the additive excess-loss basis)."""
    M, P = KINDS[kind]
    if kind == "excess_loss":
        return [("a", m, 0) for m in range(1, M + 1)] + [("b", 0, p) for p in range(1, P + 1)]
    return fourier_legendre_orders(M, P)


def fourier_legendre_orders(M: int, P: int) -> list[tuple[str, int, int]]:
    """(``c``/``s``, m, p) of every column of ``fourier_legendre_columns``, in its order."""
    out = [("c", 0, p) for p in range(1, P + 1)]
    for m in range(1, M + 1):
        out += [(t, m, p) for t in ("c", "s") for p in range(P + 1)]
    return out


def ridge_penalty(orders: Sequence[tuple[str, int, int]]) -> np.ndarray:
    """Ridge weights 1 + m^2 + p^2 per basis column (rougher terms shrink more)."""
    return np.array([1.0 + m * m + p * p for _, m, p in orders])


def _leg(x: np.ndarray, p: int) -> np.ndarray:
    c = np.zeros(p + 1)
    c[p] = 1.0
    return legendre.legval(x, c)


def basis_column(fn: str, m: int, p: int, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    if fn == "a":
        return _leg(a, m)
    if fn == "b":
        return _leg(b, p)
    return (np.cos(m * a) if fn == "c" else np.sin(m * a)) * _leg(b, p)


def _legendre_all(x: np.ndarray, n: int) -> list[np.ndarray]:
    """P_0..P_n at x by Bonnet's recurrence (k+1) P_{k+1} = (2k+1) x P_k - k P_{k-1}."""
    out = [np.ones_like(x), x]
    for k in range(1, n):
        out.append(((2 * k + 1) * x * out[k] - k * out[k - 1]) / (k + 1))
    return out[: n + 1]


def fourier_legendre_columns(a: np.ndarray, b: np.ndarray, M: int, P: int) -> list[np.ndarray]:
    """cos/sin(m a) P_p(b) for m <= M, p <= P without the constant, in the order of
    ``basis_orders``: the smooth map over an angle ``a`` (rad) and a variable ``b`` in [-1, 1] that
    the gain maps and the site map share."""
    lb = _legendre_all(b, P)
    cols = lb[1:]
    for m in range(1, M + 1):
        c, s_ = np.cos(m * a), np.sin(m * a)
        cols += [c * q for q in lb] + [s_ * q for q in lb]
    return cols


def _columns(kind: str, a: np.ndarray, b: np.ndarray) -> list[np.ndarray]:
    """Every basis column of ``kind`` (the order of ``basis_orders``), sharing the Legendre and
    Fourier terms."""
    M, P = KINDS[kind]
    if kind == "excess_loss":
        return _legendre_all(a, M)[1:] + _legendre_all(b, P)[1:]
    return fourier_legendre_columns(a, b, M, P)


def design(kind: str, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Design matrix (N, K) of ``kind`` at the variables ``a``, ``b`` (1-D)."""
    return np.column_stack(_columns(kind, a, b))


@dataclass(frozen=True, eq=False)
class FreeFormTerm:
    """A fitted smooth map (dB) added to the RSS: sum_k coef_k basis_k(variables of ``kind``)."""

    name: str
    coef: tuple[float, ...]

    def rss_term_db(self, link: Any) -> np.ndarray:
        a, b = map_variables(self.name, link)
        dtype = np.asarray(link.d_los).dtype

        def compute() -> np.ndarray:
            out = np.zeros(np.shape(a))
            for c, col in zip(self.coef, _columns(self.name, a, b), strict=True):
                out += c * col
            return out.astype(dtype, copy=False)

        # the same samples are evaluated again and again while other effects are fitted on top
        return memo(self, (np.asarray(a), np.asarray(b)), compute, extra=dtype.str)

    def on_grid(self, n: int = 37) -> dict[str, Any]:
        """The shape on a regular grid of the two variables (for plots and JSON)."""
        if self.name == "excess_loss":
            la = np.linspace(-1.0, 1.0, n)
            d_m = 100.0 * 10**la
            h = 35.0 + 25.0 * np.linspace(-1.0, 1.0, n)
            ca = [
                c
                for c, (fn, _, _) in zip(self.coef, basis_orders(self.name), strict=True)
                if fn == "a"
            ]
            cb = [
                c
                for c, (fn, _, _) in zip(self.coef, basis_orders(self.name), strict=True)
                if fn == "b"
            ]
            return {
                "distance_m": d_m.tolist(),
                "loss_vs_distance_db": legendre.legval(la, [0.0, *ca]).tolist(),
                "height_m": h.tolist(),
                "loss_vs_height_db": legendre.legval(np.linspace(-1, 1, n), [0.0, *cb]).tolist(),
            }
        az = np.deg2rad(np.linspace(0.0, 360.0, 2 * n - 1))
        s = np.sin(np.deg2rad(np.linspace(-30.0, 90.0, n)))
        A, B = np.meshgrid(az, s)
        Z = design(self.name, A.ravel(), B.ravel()) @ np.asarray(self.coef)
        return {
            "azimuth_deg": np.rad2deg(az).tolist(),
            "elevation_deg": np.rad2deg(np.arcsin(s)).tolist(),
            "gain_db": Z.reshape(A.shape).tolist(),
        }


def link_of(pipe: Pipeline, flight: FlightSamples, idx: np.ndarray) -> Any:
    """The model's per-sample LOS geometry (``Link`` fields) for the samples ``idx`` (time offset
    applied)."""
    rx, att = pipe.geometry(flight, idx)
    tx = np.asarray(flight.tx_enu_m, dtype=float)
    dx, dy, dz = link_delta(tx, rx)
    d_los = np.maximum(slant_distance(dx, dy, dz), 1e-3)
    if pipe.model.has("attitude"):
        ub = body_vectors(
            enu_to_ned(np.stack([dx, dy, dz], axis=-1)), pipe.model.effect("attitude").apply(att)
        )
        u_b = (ub[:, 0], ub[:, 1], ub[:, 2])
    else:
        u_b = (dy, dx, -dz)
    return SimpleNamespace(
        delta=(dx, dy, dz), z_t=np.full(len(rx), tx[2]), z_r=rx[:, 2], d_los=d_los, u_b=u_b
    )


def _centered(blocks: Sequence[np.ndarray], ws: Sequence[np.ndarray]) -> np.ndarray:
    """Weighted per-flight centring (the free offset is per flight)."""
    out = []
    for B, w in zip(blocks, ws, strict=True):
        wm = np.sum(B * w.reshape(-1, *([1] * (B.ndim - 1))), axis=0) / max(float(np.sum(w)), 1e-12)
        out.append(B - wm)
    return np.concatenate(out) if out else np.zeros(0)


def resemblance(
    kind: str,
    term: Sequence[np.ndarray],
    pipe: Pipeline,
    flights: Sequence[FlightSamples],
    idx: Sequence[np.ndarray],
    named: Mapping[str, Candidate] | None = None,
) -> tuple[str, float, dict[str, float]]:
    """Which named effect's own term (relative to ``pipe``) correlates best with the fitted ``term``
    (``named``: the named candidates by name, passed in by ``candidates.library``; none: nothing to
    compare)."""
    lib = named or {}
    refs: dict[str, dict[str, Any]] = {
        "rx_gain_map": {
            "leg_shadowing": ({"beta": 1.0, "half_width_deg": 8.0, "legs_rotation_deg": 0.0}, {}),
            "rx_pattern measured": ({}, {"pattern": "measured", "flipped": False}),
            "rx_pattern measured flipped": ({}, {"pattern": "measured", "flipped": True}),
        },
        "tx_gain_map": {
            "tx_pattern measured": ({}, {"pattern": "measured", "flipped": False}),
            "tx_tilt": ({"tilt_deg": 20.0, "azimuth_deg": 0.0}, {}),
        },
        "excess_loss": {
            "path_gain_slope": ({"n_extra": 1.0}, {}),
            "ground_reflection": ({"log10_eps_r": 1.2, "log10_sigma": -2.3}, {"polarization": "V"}),
        },
    }[kind]
    base = [pipe.predict_channel(f, i) for f, i in zip(flights, idx, strict=True)]
    t = _centered(list(term), [np.ones(len(x)) for x in term])
    out: dict[str, float] = {}
    for label, (th, ch) in refs.items():
        cname = label.split()[0]
        cand = lib.get(cname)
        if cand is None or not cand.applicable(pipe):
            continue
        try:
            new = cand.build(pipe, th, ch)
        except (KeyError, ValueError):
            continue
        d = [new.predict_channel(f, i) - b for f, i, b in zip(flights, idx, base, strict=True)]
        r = _centered(d, [np.ones(len(x)) for x in d])
        den = float(np.linalg.norm(r) * np.linalg.norm(t))
        out[label] = float(abs(r @ t) / den) if den > 0 else 0.0
    if not out:
        return "none", 0.0, out
    best = max(out, key=lambda k: out[k])
    return best, out[best], out


def where_it_acts(kind: str, a: np.ndarray, b: np.ndarray, term: np.ndarray) -> dict[str, float]:
    """Where the fitted term peaks and where it dips on the flown samples (degrees, metres)."""
    out: dict[str, float] = {}
    for lab, k in (("peak", int(np.argmax(term))), ("trough", int(np.argmin(term)))):
        if kind == "excess_loss":
            out[f"{lab}_distance_m"] = float(100.0 * 10 ** a[k])
            out[f"{lab}_height_m"] = float(35.0 + 25.0 * b[k])
        elif kind == "rx_gain_map":
            out[f"{lab}_body_azimuth_deg"] = float(np.rad2deg(a[k]) % 360.0)
            out[f"{lab}_body_depression_deg"] = float(np.rad2deg(np.arcsin(b[k])))
        else:
            out[f"{lab}_world_azimuth_deg"] = float(np.rad2deg(a[k]) % 360.0)
            out[f"{lab}_elevation_deg"] = float(np.rad2deg(np.arcsin(b[k])))
    return out


def ridge_cv(
    Xs: Sequence[np.ndarray],
    rs: Sequence[np.ndarray],
    ws: Sequence[np.ndarray],
    halves: Sequence[np.ndarray],
    pen: np.ndarray,
    lambdas: Sequence[float],
    min_n: int = 0,
) -> tuple[np.ndarray, Any]:
    """Weighted ridge regression of residuals ``rs`` on designs ``Xs`` (one per flight), both
    centred per flight (the free offset), penalty ``lambda * n * diag(pen)``: the two-fold
    cross-validation error for each lambda (train on one of ``halves`` 0/1, score the other) and
    ``fit_all(lambda)`` -> coefficients on every sample.

    Why one routine: the free-form maps and the site map are the same smooth fit over other
    variables. Flights with fewer than ``min_n`` samples in a selection sit that selection out.
    """

    def gram(sel: Sequence[np.ndarray]) -> tuple[np.ndarray, np.ndarray, int]:
        """X^T W X and X^T W y of the selected samples, centred per flight (computed once per
        selection)."""
        use = [k for k, s in enumerate(sel) if s.sum() >= min_n]
        X = _centered([Xs[k][sel[k]] for k in use], [ws[k][sel[k]] for k in use])
        y = _centered([rs[k][sel[k]] for k in use], [ws[k][sel[k]] for k in use])
        if not use:
            return np.zeros((len(pen), len(pen))), np.zeros(len(pen)), 0
        XtW = X.T * np.concatenate([ws[k][sel[k]] for k in use])
        return XtW @ X, XtW @ y, len(y)

    def solve(g: tuple[np.ndarray, np.ndarray, int], lam: float) -> np.ndarray:
        A, c, n = g
        return np.linalg.solve(A + lam * max(n, 1) * np.diag(pen), c)

    grams = [gram([h != a for h in halves]) for a in (0, 1)]
    errs = np.zeros(len(lambdas))
    for j, lam in enumerate(lambdas):
        for a in (0, 1):
            coef = solve(grams[a], lam)
            te = [h == a for h in halves]
            use = [k for k, s in enumerate(te) if s.sum() >= max(min_n, 1)]
            d = _centered(
                [rs[k][te[k]] - Xs[k][te[k]] @ coef for k in use], [ws[k][te[k]] for k in use]
            )
            w_te = np.concatenate([ws[k][te[k]] for k in use]) if use else np.zeros(0)
            errs[j] += float(np.sum(w_te * d * d))
    return errs, lambda lam: solve(gram([np.ones(len(r), bool) for r in rs]), lam)


def fit_freeform(
    kind: str,
    pipe: Pipeline,
    flights: Sequence[FlightSamples],
    idx: Sequence[np.ndarray],
    resid: Sequence[np.ndarray],
    cfg: Any = None,
    period_s: float = 30.0,
    named: Mapping[str, Candidate] | None = None,
) -> tuple[Pipeline, dict]:
    """Fit the ``kind`` map to the offset-removed training residuals; lambda by inner two-fold
    CV."""
    loss = getattr(cfg, "loss", "l2")
    f_scale = getattr(cfg, "f_scale_db", 6.0)
    keep = [k for k, i in enumerate(idx) if len(i)]
    fl = [flights[k] for k in keep]
    ix = [idx[k] for k in keep]
    rs = [np.asarray(resid[k], dtype=float) for k in keep]
    ab = [map_variables(kind, link_of(pipe, f, i)) for f, i in zip(fl, ix, strict=True)]
    Xs = [design(kind, a, b) for a, b in ab]
    ws = [np.ones(len(r)) if loss == "l2" else 1.0 / np.sqrt(1.0 + (r / f_scale) ** 2) for r in rs]
    half = [(np.floor(f.t_s[i] / period_s).astype(int) % 2) for f, i in zip(fl, ix, strict=True)]
    errs, fit_all = ridge_cv(Xs, rs, ws, half, ridge_penalty(basis_orders(kind)), LAMBDAS)
    lam = float(LAMBDAS[int(np.argmin(errs))])
    coef = fit_all(lam)
    term = FreeFormTerm(kind, tuple(float(c) for c in coef))
    new = pipe.replace(model=pipe.model.with_effect(term))
    vals = [x @ coef for x in Xs]
    allv = np.concatenate(vals) if vals else np.zeros(1)
    size = float(np.quantile(allv, 0.95) - np.quantile(allv, 0.05)) if allv.size else 0.0
    sub = [np.arange(0, len(i), max(1, len(i) // 1500)) for i in ix]
    like, corr, corrs = resemblance(
        kind,
        [v[s] for v, s in zip(vals, sub, strict=True)],
        pipe,
        fl,
        [i[s] for i, s in zip(ix, sub, strict=True)],
        named,
    )
    a_all = np.concatenate([a for a, _ in ab])
    b_all = np.concatenate([b for _, b in ab])
    params = {
        "lambda": float(lam),
        "size_db": size,
        "resembles": like,
        "resemblance_corr": corr,
        "where": where_it_acts(kind, a_all, b_all, allv),
        "resemblances": corrs,
        "shape": term.on_grid(),
    }
    return new, params


def freeform_candidate(kind: str, named: Mapping[str, Candidate] | None = None) -> Candidate:
    """The ``kind`` map as a candidate; ``named``: the named candidates its fit is compared with."""
    desc = {
        "rx_gain_map": "smooth UAV body-frame gain map (body azimuth x depression)",
        "tx_gain_map": "smooth transmitter gain map (world azimuth x elevation)",
        "excess_loss": "smooth excess loss over distance and UAV height",
    }[kind]

    # only via direct_fit
    def build(p: Pipeline, th: dict[str, float], ch: dict[str, Any]) -> Pipeline:
        return p

    def withhold(p: Pipeline) -> Pipeline:
        return p.replace(model=p.model.without(kind)) if p.model.has(kind) else p

    def direct_fit(
        p: Pipeline,
        flights: Sequence[FlightSamples],
        idx: Sequence[np.ndarray],
        resid: Sequence[np.ndarray],
        rng: np.random.Generator,
        cfg: Any = None,
    ) -> tuple[Pipeline, dict[str, Any]]:
        if kind == "rx_gain_map" and not p.model.has("attitude"):
            # a body-frame map needs the body frame: the logged attitude joins the model with the
            # map
            p = p.replace(model=p.model.with_effect(Attitude()))
            resid = offset_residuals(
                p,
                flights,
                idx,
                getattr(cfg, "slope", False),
                getattr(cfg, "loss", "l2"),
                getattr(cfg, "f_scale_db", 6.0),
            )
            new, params = fit_freeform(kind, p, flights, idx, resid, cfg, named=named)
            return new, {**params, "adds_attitude": True}
        return fit_freeform(kind, p, flights, idx, resid, cfg, named=named)

    return Candidate(
        kind,
        desc,
        (),
        build,
        lambda p: not p.model.has(kind),
        withhold,
        direct_fit=direct_fit,
        tier=TIER_FREEFORM,
    )


FREEFORM_NAMES = tuple(KINDS)

"""Classical transmitter localizers, scikit-learn style: ``fit`` (no-op), ``predict(flight) ->
Estimate``.

``flight`` is a ``FlightLog`` (positions in its own origin's ENU frame), a
``mission.samples.FlightSamples`` or a tuple ``(enu (N, 3), rss (N,), attitude (N, 3) radians or
None)``.  All estimators are invariant to a constant RSS offset (a real receiver's dB are not
calibrated dBm, SPEC section 5).

- ``StrongestSample``: position of the maximum of the grouped, Gaussian-smoothed RSS (features.py
  settings).
- ``WeightedCentroid``: centroid of the ``top_k`` strongest smoothed samples weighted by *relative*
  linear power ``10^((p - p_max)/10)``.
- ``ModelGridSearch``: maximum likelihood with a propagation model from ``mission.physics``: for
  each candidate transmitter position (x, y, ``tx_height_m``) the model's predicted RSS along the
  logged positions and attitudes is compared with the measured RSS after removing the best constant
  offset (robust: median, then one Huber IRLS step); the cost is a robust loss (``soft_l1`` or
  ``huber``, scale ``f_scale_db``) of the residuals.  Candidates form a grid over the search area,
  refined coarse to fine around the best few; the flight is block-averaged in dB to at most
  ``max_points`` samples first.
- ``FixedGeometrySearch`` (``ModelGridSearch.fixed_geometry``): the same model and candidates for
  many RSS records along one flown geometry, predictions computed once, least squares with each
  record's mean offset (maximum likelihood under Gaussian noise); the mission preview's
  expected-error map uses it.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from mission.defaults import DEFAULT_TX_HEIGHT_M
from mission.errors import InputError
from mission.flightlog import FlightLog
from mission.geo import Area, square_grid
from mission.localize import Estimate
from mission.localize.features import FeatureConfig, gaussian_smooth, preprocess
from mission.physics import make_model
from mission.robust import robust_cost
from mission.samples import FlightSamples


def as_flight(obj, origin=None) -> FlightSamples:
    """FlightLog / FlightSamples / (enu, rss[, attitude]) -> FlightSamples, validated and float64:
    the input boundary of every localizer (a partly NaN attitude reads as 0, an all-NaN one as
    none)."""
    if isinstance(obj, FlightSamples):
        fs = obj
    elif isinstance(obj, FlightLog):
        fs = obj.samples(origin)
    elif isinstance(obj, tuple | list) and len(obj) in (2, 3):
        fs = FlightSamples(
            enu_m=np.asarray(obj[0], dtype=float),
            rss_dbm=np.asarray(obj[1], dtype=float),
            attitude_rad=None
            if len(obj) == 2 or obj[2] is None
            else np.asarray(obj[2], dtype=float),
        )
    else:
        raise InputError(
            f"cannot localize from a {type(obj).__name__}: expected a FlightLog or (enu, rss, "
            "attitude)"
        )
    enu = np.asarray(fs.enu_m, dtype=float)
    rss = np.asarray(fs.rss_dbm, dtype=float).ravel()
    if enu.ndim != 2 or enu.shape[1] != 3 or enu.shape[0] != rss.size:
        raise InputError(
            f"positions must be (N, 3) with N = {rss.size} RSS samples, got {enu.shape}"
        )
    att = fs.attitude_rad
    if att is not None:
        att = np.asarray(att, dtype=float)
        if att.shape != enu.shape:
            raise InputError(f"attitude must be (N, 3), got {att.shape}")
        if np.isnan(att).any():
            att = None if np.isnan(att).all() else np.nan_to_num(att)
    return replace(fs, enu_m=enu, rss_dbm=rss, attitude_rad=att)


class _Base:
    name = "base"

    def fit(self, flights=None, truths=None) -> _Base:
        """No calibration needed (kept for the scikit-learn-style interface)."""
        return self

    def _estimate(self, x: float, y: float, model: str | None = None, **extras) -> Estimate:
        return Estimate(float(x), float(y), self.name, model, extras=extras)


class StrongestSample(_Base):
    """Position of the strongest grouped and smoothed RSS sample."""

    name = "strongest"

    def __init__(self, cfg: FeatureConfig | None = None) -> None:
        self.cfg = cfg or FeatureConfig()

    def predict(self, flight, origin=None) -> Estimate:
        f = as_flight(flight, origin)
        gx, gy, gp = preprocess(f.enu_m[:, 0], f.enu_m[:, 1], f.rss_dbm, self.cfg)
        i = int(np.argmax(gp))
        return self._estimate(gx[i], gy[i], None, index=i)


class WeightedCentroid(_Base):
    """Centroid of the ``top_k`` strongest smoothed samples, weighted by relative linear power."""

    name = "centroid"

    def __init__(self, top_k: int = 200, cfg: FeatureConfig | None = None) -> None:
        self.top_k = int(top_k)
        self.cfg = cfg or FeatureConfig()

    def predict(self, flight, origin=None) -> Estimate:
        f = as_flight(flight, origin)
        gx, gy, gp = preprocess(f.enu_m[:, 0], f.enu_m[:, 1], f.rss_dbm, self.cfg)
        k = min(self.top_k, gp.size)
        idx = np.argpartition(-gp, k - 1)[:k]
        w = 10.0 ** ((gp[idx] - gp.max()) / 10.0)
        return self._estimate(
            np.sum(w * gx[idx]) / w.sum(), np.sum(w * gy[idx]) / w.sum(), None, top_k=k
        )


def search_bounds(area, enu: np.ndarray, margin_m: float):
    """(xmin, ymin, xmax, ymax) and the polygon (or None) of a grid search: an ``Area`` (its box and
    polygon), a ``(xmin, ymin, xmax, ymax)`` box, or None for the flight's box grown by
    ``margin_m``."""
    if isinstance(area, Area):
        return area.bounds, area
    if area is not None:
        return tuple(float(v) for v in area), None
    lo = enu[:, :2].min(axis=0) - margin_m
    hi = enu[:, :2].max(axis=0) + margin_m
    return (lo[0], lo[1], hi[0], hi[1]), None


def block_average(f: FlightSamples, max_points: int) -> FlightSamples:
    """Average RSS (dB) and positions over consecutive blocks so at most ``max_points`` remain.

    The attitude of a block is that of its middle sample (angles are not averaged across the yaw
    wrap).
    """
    n = f.rss_dbm.size
    b = max(1, int(np.ceil(n / max_points)))
    m = n // b
    if m == 0:
        return f
    rss = f.rss_dbm[: m * b].reshape(m, b).mean(axis=1)
    enu = f.enu_m[: m * b].reshape(m, b, 3).mean(axis=1)
    att = None if f.attitude_rad is None else f.attitude_rad[b // 2 : m * b : b][:m]
    return FlightSamples(enu_m=enu, rss_dbm=rss, attitude_rad=att, tx_enu_m=f.tx_enu_m, name=f.name)


class ModelGridSearch(_Base):
    """Model-based maximum-likelihood grid search with a free constant offset and a robust loss.

    ``model``: a ``mission.physics`` model name (built with ``make_model(model, **model_params)``)
    or any object with ``rss_dbm(tx (K, 1, 3), rx (N, 3), attitude (N, 3) | None) -> (K, N)``
    (outer product).
    ``area``: search region, an ``Area`` or ``(xmin, ymin, xmax, ymax)``; by default the flight's
    bounding box grown by ``margin_m``.  Candidates outside an ``Area`` polygon are not considered.
    """

    name = "grid"

    def __init__(
        self,
        model="e2r",
        model_params: dict | None = None,
        tx_height_m: float = DEFAULT_TX_HEIGHT_M,
        area=None,
        margin_m: float = 60.0,
        step_m: float = 10.0,
        refinements: int = 3,
        keep: int = 5,
        max_points: int = 1500,
        loss: str = "soft_l1",
        f_scale_db: float = 4.0,
        use_attitude: bool = True,
        chunk: int = 512,
        smooth_samples: float = 0.0,
        floor_db: float | None = None,
    ) -> None:
        self.model = model
        self.model_params = dict(model_params or {})
        self.tx_height_m = float(tx_height_m)
        self.area = area
        self.margin_m = float(margin_m)
        self.step_m = float(step_m)
        self.refinements = int(refinements)
        self.keep = int(keep)
        self.max_points = int(max_points)
        self.loss = loss
        self.f_scale_db = float(f_scale_db)
        self.use_attitude = use_attitude
        self.chunk = int(chunk)
        self.smooth_samples = float(smooth_samples)
        self.floor_db = floor_db
        self._model_obj = None

    @property
    def model_name(self) -> str:
        if isinstance(self.model, str):
            extra = ",".join(f"{k}={v}" for k, v in sorted(self.model_params.items()))
            return f"{self.model}({extra})" if extra else self.model
        return getattr(self.model, "name", type(self.model).__name__)

    def _get_model(self):
        if self._model_obj is None:
            if isinstance(self.model, str):
                try:
                    self._model_obj = make_model(self.model, **self.model_params)
                except (ValueError, TypeError) as e:
                    raise InputError(f"physics model {self.model!r}: {e}", field="model") from None
            else:
                self._model_obj = self.model
        return self._model_obj

    def candidate_rss(
        self, cand_xy: np.ndarray, enu: np.ndarray, attitude: np.ndarray | None
    ) -> np.ndarray:
        """Model RSS (K, N) dBm of transmitters at candidates (K, 2), ``tx_height_m`` high, along
        the positions (N, 3) and attitude (N, 3) rad (ignored unless ``use_attitude``): what every
        cost compares with."""
        tx = np.column_stack([cand_xy, np.full(len(cand_xy), self.tx_height_m)])
        att = attitude if self.use_attitude else None
        pred = self._get_model().rss_dbm(tx[:, None, :], enu, att)
        return np.asarray(pred, dtype=float).reshape(len(cand_xy), -1)

    def coarse_candidates(
        self, enu: np.ndarray
    ) -> tuple[tuple[float, float, float, float], np.ndarray]:
        """The search box and the first pass's candidates: a ``step_m`` grid from the box's corner,
        kept inside the area's polygon when there is one (all of them if none falls inside)."""
        bounds, poly = search_bounds(self.area, enu, self.margin_m)
        cand = square_grid(bounds, self.step_m).reshape(-1, 2)
        if poly is not None:
            inside = poly.contains(cand)
            cand = cand[inside] if inside.any() else cand
        return bounds, cand

    def fixed_geometry(
        self, enu: np.ndarray, attitude: np.ndarray | None, cand_xy: np.ndarray | None = None
    ) -> FixedGeometrySearch:
        """This search for many RSS records flown along one geometry (``FixedGeometrySearch``);
        candidates ``cand_xy`` (K, 2), by default the first pass's grid (no refinement)."""
        if cand_xy is None:
            cand_xy = self.coarse_candidates(np.asarray(enu, dtype=float))[1]
        return FixedGeometrySearch(
            self, np.asarray(enu, dtype=float), attitude, np.asarray(cand_xy, dtype=float)
        )

    def cost(self, f: FlightSamples, cand_xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Robust cost and fitted offset for candidate positions (K, 2) on an (already reduced)
        flight."""
        costs, offs = np.empty(len(cand_xy)), np.empty(len(cand_xy))
        for s in range(0, len(cand_xy), self.chunk):
            c = cand_xy[s : s + self.chunk]
            pred = self.candidate_rss(c, f.enu_m, f.attitude_rad)
            if self.floor_db is not None:
                lo = f.rss_dbm < f.rss_dbm.max() - self.floor_db
                resid = f.rss_dbm[None, :] - pred
                off0 = np.median(resid[:, ~lo], axis=1)
                # censored samples: measured value is an upper bound of the signal (noise floor)
                resid[:, lo] = np.maximum(resid[:, lo], off0[:, None])
                offs[s : s + len(c)], costs[s : s + len(c)] = robust_cost(
                    resid, self.loss, self.f_scale_db
                )
                continue
            offs[s : s + len(c)], costs[s : s + len(c)] = robust_cost(
                f.rss_dbm[None, :] - pred, self.loss, self.f_scale_db
            )
        return costs, offs

    def _reduce(self, flight, origin=None) -> FlightSamples:
        f = as_flight(flight, origin)
        if self.smooth_samples > 0:
            f = replace(f, rss_dbm=gaussian_smooth(f.rss_dbm, self.smooth_samples))
        return block_average(f, self.max_points)

    def predict(self, flight, origin=None) -> Estimate:
        f = self._reduce(flight, origin)
        (xmin, ymin, xmax, ymax), cand = self.coarse_candidates(f.enu_m)
        step = self.step_m
        n_eval = 0
        for rnd in range(self.refinements):
            cost, off = self.cost(f, cand)
            n_eval += len(cand)
            best = np.argsort(cost)[: self.keep]
            if rnd == self.refinements - 1:
                break
            step /= 4.0
            d = np.arange(-4, 5) * step
            local = np.stack(np.meshgrid(d, d), axis=-1).reshape(-1, 2)
            new = (cand[best][:, None, :] + local[None, :, :]).reshape(-1, 2)
            new[:, 0] = np.clip(new[:, 0], xmin, xmax)
            new[:, 1] = np.clip(new[:, 1], ymin, ymax)
            cand = np.unique(np.round(new, 6), axis=0)
        i = int(best[0])
        resid_rms = float(np.sqrt(cost[i]))
        return self._estimate(
            cand[i, 0],
            cand[i, 1],
            self.model_name,
            offset_db=float(off[i]),
            cost=float(cost[i]),
            cost_rms_db=resid_rms,
            n_points=int(f.rss_dbm.size),
            candidates=n_eval,
            tx_height_m=self.tx_height_m,
            loss=self.loss,
            search_box=[float(xmin), float(ymin), float(xmax), float(ymax)],
        )


class FixedGeometrySearch:
    """``ModelGridSearch`` for many RSS records flown along one geometry (simulation studies: the
    preview's expected-error map scores hundreds of transmitters on one simulated flight).

    The model's predictions at the fixed candidates are computed once; each record is scored by
    least squares after removing its own mean offset from both sides, the maximum-likelihood
    estimate under Gaussian dB noise with an unknown constant offset.  (A single flight's
    ``predict`` is robust instead: median/Huber offset and soft-L1 for real fades; that offset would
    cost a median per candidate and record.)
    """

    def __init__(
        self,
        search: ModelGridSearch,
        enu: np.ndarray,
        attitude: np.ndarray | None,
        cand_xy: np.ndarray,
    ) -> None:
        self.cand = cand_xy
        pred = np.concatenate(
            [
                search.candidate_rss(cand_xy[s : s + search.chunk], enu, attitude)
                for s in range(0, len(cand_xy), search.chunk)
            ],
            axis=0,
        )
        self.pred_c = pred - pred.mean(axis=1, keepdims=True)
        self.pred_sq = np.sum(self.pred_c**2, axis=1)

    def predict_xy(self, rss: np.ndarray) -> np.ndarray:
        """RSS records (T, N) (or one (N,)) -> best candidates (T, 2)."""
        r = np.atleast_2d(np.asarray(rss, dtype=float))
        rc = r - r.mean(axis=1, keepdims=True)
        # + |rc|^2, the same for every candidate
        sse = self.pred_sq[:, None] - 2.0 * self.pred_c @ rc.T
        return self.cand[np.argmin(sse, axis=0)]

"""A prediction pipeline = a physics propagation model plus the effects the physics does not model.

Why: the sim-to-real diagnosis tries effects one at a time, so every effect must be a separately
switchable, parameterised component.  Effects that change how the radio channel behaves live in
``mission.physics`` (``PropagationModel`` effects).  What happens *around* the channel lives here:

- ``time_offset_s``: the RSS sample stamped ``t`` was received where the UAV was at ``t - tau`` (a
  lag of the receiver's clock or pipe behind the telemetry); applied by interpolating the telemetry.
- ``Receiver``: noise floor and saturation, both soft (in the model's dB scale, before the free
  offset): ``p -> 10 log10(10^(p/10) + 10^(floor/10))`` then ``-10 log10(10^(-p/10) +
  10^(-sat/10))``.
- ``TxTilt``: a ``mission.physics`` effect (``rss_term_db``) for a tilted transmitter dipole: the
  direct ray's gain change between a dipole tilted by ``tilt_deg`` towards compass ``azimuth_deg``
  and an upright one.  It is an additive approximation (the reflected ray keeps the upright gain).
- Spatially correlated shadowing (``spatial``): an additive field over the UAV's horizontal position
  per transmitter; the truth in simulations is a random field, in diagnosis a kriging predictor
  fitted on the training part of the data (``mission.gap.candidates.KrigedShadowing``).
"""

from __future__ import annotations

import math
import operator
from collections.abc import Callable, Hashable, Sequence
from dataclasses import dataclass, replace
from typing import Any, ClassVar, Protocol

import numpy as np

from mission.physics import PropagationModel
from mission.physics.antenna import Dipole
from mission.physics.geometry import sin_elevation, slant_distance
from mission.physics.model import PreparedLinks
from mission.robust import LOSSES, huber_weights, median_1d, offset_residual
from mission.samples import FlightSamples


class SpatialField(Protocol):
    """Additive dB field over the UAV's horizontal position, for the flight's transmitter."""

    def field_db(self, flight: FlightSamples, rx_xy: np.ndarray) -> np.ndarray: ...


class TemporalField(Protocol):
    """Additive dB term over a flight's time (a gain drifting or stepping;
    ``mission.gap.temporal``)."""

    def field_db(self, flight: FlightSamples, t: np.ndarray) -> np.ndarray: ...


@dataclass(frozen=True)
class Receiver:
    """Soft noise floor and saturation of the receiver, in the model's dB scale (before the free
    offset)."""

    floor_db: float = -300.0
    sat_db: float = 300.0

    def apply(self, p: np.ndarray) -> np.ndarray:
        out = np.logaddexp(p * (np.log(10) / 10), self.floor_db * (np.log(10) / 10)) * (
            10 / np.log(10)
        )
        return -np.logaddexp(-out * (np.log(10) / 10), -self.sat_db * (np.log(10) / 10)) * (
            10 / np.log(10)
        )


@dataclass(frozen=True)
class TxTilt:
    """Transmitter dipole tilted by ``tilt_deg`` towards compass ``azimuth_deg`` (additive gain
    change)."""

    tilt_deg: float = 0.0
    azimuth_deg: float = 0.0
    name: ClassVar[str] = "tx_tilt"

    def rss_term_db(self, link: Any) -> np.ndarray:
        """G_dip(angle to the tilted axis) - G_dip(angle to the vertical) on the direct ray, dB."""
        dx, dy, dz = (np.asarray(v, dtype=float) for v in link.delta)
        d = slant_distance(dx, dy, dz)
        # unit vector tx -> rx (ENU) = -delta / d
        ux, uy, uz = -dx / d, -dy / d, -dz / d
        t, a = math.radians(self.tilt_deg), math.radians(self.azimuth_deg)
        ax, ay, az = math.sin(t) * math.sin(a), math.sin(t) * math.cos(a), math.cos(t)
        sin_new = np.clip(ux * ax + uy * ay + uz * az, -1.0, 1.0)
        # upright: the UAV's elevation
        term = _dipole_db(sin_new) - _dipole_db(sin_elevation(-dz, d))
        return term.astype(np.asarray(link.d_los).dtype, copy=False)


def _dipole_db(sin_el: np.ndarray) -> np.ndarray:
    """The library's vertical dipole (``mission.physics.antenna.Dipole``, floor GAIN_FLOOR_DBI) at
    asin(sin_el)."""
    return Dipole().gain_dbi(np.arcsin(sin_el))


@dataclass(frozen=True)
class Pipeline:
    """Physics model + time offset + receiver + spatial shadowing: predicts a flight's RSS (model
    dB)."""

    model: PropagationModel
    time_offset_s: float = 0.0
    receiver: Receiver | None = None
    spatial: SpatialField | None = None
    temporal: TemporalField | None = None

    def replace(self, **kw: Any) -> Pipeline:
        return replace(self, **kw)

    def geometry(
        self,
        flight: FlightSamples,
        idx: np.ndarray | None = None,
        yaw: np.ndarray | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """UAV positions and attitudes for the samples ``idx`` at their RSS times shifted by the
        time offset (``yaw``: the flight's unwrapped yaw, ``unwrapped_yaw``, if already made)."""
        t = flight.t_s if idx is None else flight.t_s[idx]
        if self.time_offset_s == 0.0:
            sl = slice(None) if idx is None else idx
            return flight.enu_m[sl], flight.attitude_rad[sl]
        return shifted_geometry(flight, t - self.time_offset_s, yaw)

    def predict_channel(self, flight: FlightSamples, idx: np.ndarray | None = None) -> np.ndarray:
        """Model RSS (dB) before the spatial field and the receiver."""
        rx, att = self.geometry(flight, idx)
        return np.asarray(self.model.rss_dbm(flight.tx_enu_m, rx, att), dtype=float)

    def finish(
        self, p: np.ndarray, flight: FlightSamples, idx: np.ndarray | None = None
    ) -> np.ndarray:
        """Add the spatial field and pass through the receiver."""
        if self.spatial is not None:
            xy = (flight.enu_m if idx is None else flight.enu_m[idx])[:, :2]
            p = p + self.spatial.field_db(flight, xy)
        if self.temporal is not None:
            p = p + self.temporal.field_db(flight, flight.t_s if idx is None else flight.t_s[idx])
        if self.receiver is not None:
            p = self.receiver.apply(p)
        return p

    def predict(self, flight: FlightSamples, idx: np.ndarray | None = None) -> np.ndarray:
        """Predicted RSS (model dB scale) of the samples ``idx`` (all by default)."""
        return self.finish(self.predict_channel(flight, idx), flight, idx)

    def components(self) -> tuple[str, ...]:
        """Names of every effect in the pipeline (physics effects first)."""
        names = list(self.model.names)
        if self.time_offset_s != 0.0:
            names.append("time_offset")
        if self.receiver is not None:
            names.append("receiver")
        if self.spatial is not None:
            names.append(getattr(self.spatial, "name", "spatial_shadowing"))
        if self.temporal is not None:
            names.append(getattr(self.temporal, "name", "time_drift"))
        return tuple(names)


def unwrapped_yaw(flight: FlightSamples) -> np.ndarray:
    """The flight's yaw series unwrapped (continuous), as ``shifted_geometry`` interpolates it."""
    return np.unwrap(flight.attitude_rad[:, 2])


def shifted_geometry(
    flight: FlightSamples, t_query: np.ndarray, yaw: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Telemetry (positions, attitudes) linearly interpolated at ``t_query`` (yaw unwrapped; clamped
    ends). ``yaw``: ``unwrapped_yaw(flight)`` when the caller keeps it (a time-offset fit shifts the
    same flights hundreds of times)."""
    t = flight.t_s
    rx = np.stack([np.interp(t_query, t, flight.enu_m[:, k]) for k in range(3)], axis=-1)
    att = flight.attitude_rad
    yaw = unwrapped_yaw(flight) if yaw is None else yaw
    a = np.stack(
        [
            np.interp(t_query, t, att[:, 0]),
            np.interp(t_query, t, att[:, 1]),
            np.mod(np.interp(t_query, t, yaw), 2 * np.pi),
        ],
        axis=-1,
    )
    return rx, a


class LocalizationModel:
    """Adapter: a pipeline as an ``rss_dbm(tx (K,1,3), rx, att)`` model for ``ModelGridSearch``.

    The spatial field is dropped (it is tied to the true transmitter) and the time offset must
    already be applied to the geometry handed in; the receiver nonlinearity is kept.
    """

    def __init__(self, pipeline: Pipeline, name: str = "rung") -> None:
        self.pipeline = pipeline
        self.name = name

    def rss_dbm(
        self, tx_enu: np.ndarray, rx_enu: np.ndarray, attitude_rad: np.ndarray | None = None
    ) -> np.ndarray:
        p = np.asarray(self.pipeline.model.rss_dbm(tx_enu, rx_enu, attitude_rad), dtype=float)
        if self.pipeline.receiver is not None:
            p = self.pipeline.receiver.apply(p)
        return p


class Selection(tuple):
    """One index array per flight of ``flights`` (a tuple of them, usable wherever the fits take
    ``idx``) that owns what stays the same while a fit evaluates those samples again and again: the
    joint geometry per time offset, the links made ready for the model per attitude effect
    (rotation planes, block geometry, the terms of effects already evaluated), the fitted fields at
    the samples.

    Why: a fit calls the objective thousands of times on the same selection; the owner is the fit
    (or the fold) that made the selection, and everything cached goes with it, so no cache outlives
    its flights or is keyed by an object's identity.  A plain sequence of arrays is evaluated afresh
    on every call, with the very same values.
    """

    flights: tuple[FlightSamples, ...]

    def __new__(cls, flights: Sequence[FlightSamples], idx: Sequence[np.ndarray]) -> Selection:
        self = super().__new__(cls, (np.asarray(i) for i in idx))
        if len(self) != len(flights):
            raise ValueError(f"{len(self)} index arrays for {len(flights)} flights")
        self.flights = tuple(flights)
        self._joint: dict[float, JointGeometry | None] = {}
        self._links: dict[tuple, PreparedLinks] = {}
        self._fields: list[tuple[object, bool, np.ndarray]] = []
        self._children: dict[Hashable, Selection] = {}
        self._yaw: dict[int, np.ndarray] = {}
        return self

    def yaw(self, k: int) -> np.ndarray:
        """``unwrapped_yaw`` of flight ``k``, kept (shared by every time offset tried)."""
        hit = self._yaw.get(k)
        if hit is None:
            hit = self._yaw[k] = unwrapped_yaw(self.flights[k])
        return hit

    def child(self, key: Hashable, pick: Callable[[np.ndarray], np.ndarray]) -> Selection:
        """The selection ``pick(i)`` of every index array, kept under ``key`` (the fits' decimated
        and thinned training samples of a fold: every candidate fitted on the fold shares them,
        with their geometry, links and the terms of the fold's rung)."""
        hit = self._children.get(key)
        if hit is None:
            hit = self._children[key] = Selection(self.flights, [pick(i) for i in self])
        return hit

    def __reduce__(self) -> tuple:
        return (Selection, (self.flights, tuple(self)))

    def of(self, flights: Sequence[FlightSamples]) -> bool:
        """Whether this selection was made for exactly these flights (the same objects)."""
        return len(flights) == len(self.flights) and all(map(operator.is_, flights, self.flights))

    def joint(self, pipe: Pipeline) -> JointGeometry | None:
        """``joint_geometry`` of these samples under ``pipe``'s time offset, kept."""
        key = pipe.time_offset_s
        if key not in self._joint:
            if len(self._joint) >= _KEEP:
                self._joint.clear()  # a time-offset fit tries many offsets: keep the last few
            self._joint[key] = joint_geometry(pipe, self.flights, self, self.yaw)
        return self._joint[key]

    def links(
        self, model: PropagationModel, time_offset_s: float, joint: JointGeometry
    ) -> PreparedLinks | None:
        """The joint samples (``joint``, from ``self.joint``) made ready for ``model``
        (``PropagationModel.prepare_links``: centred inputs, rotation planes, then each block's
        geometry and the terms of the effects evaluated on it), kept per time offset, attitude
        effect and dtype; None for an attitude effect that cannot be a key."""
        effect = model.effect("attitude") if model.has("attitude") else None
        key = (time_offset_s, effect, np.dtype(model.dtype).str)
        try:
            hit = self._links.get(key)
        except TypeError:
            return None
        if hit is None:
            if len(self._links) >= _KEEP:
                self._links.clear()
            hit = self._links[key] = model.prepare_links(
                joint.tx, joint.rx, joint.att, centre=joint.centre
            )
        return hit

    def field(self, term: SpatialField | TemporalField, live: list[int], time: bool) -> np.ndarray:
        """A fitted (immutable) field or temporal term at the samples of the ``live`` flights,
        concatenated (read-only), kept for the last few terms."""
        for t, tm, v in self._fields:
            if t is term and tm == time:
                return v
        out = _field(term, self.flights, self, live, time)
        out.flags.writeable = False
        self._fields = [(term, time, out), *self._fields[: _KEEP - 1]]
        return out


_KEEP = 8  # entries a selection keeps per kind (time offsets, attitude effects, fields)


def _owned(flights: Sequence[FlightSamples], idx: Sequence[np.ndarray]) -> Selection | None:
    """``idx`` when it is a ``Selection`` of these flights (its caches apply), else None."""
    return idx if isinstance(idx, Selection) and idx.of(flights) else None


@dataclass(frozen=True, eq=False)
class JointGeometry:
    """The selected samples of several flights as one set of rows (read-only arrays): what every
    evaluation of a fit shares, and the per-flight bookkeeping of the offsets taken on them."""

    live: list[int]  # flights with samples, in order
    ends: np.ndarray  # row after each live flight's last
    starts: np.ndarray  # each live flight's first row
    counts: np.ndarray  # rows per live flight (each > 0)
    bounds: list[tuple[int, int, int]]  # (flight, start, end) per live flight
    tx: np.ndarray  # (N, 3) each row's transmitter
    rx: np.ndarray  # (N, 3) UAV positions (time offset applied)
    att: np.ndarray  # (N, 3) attitudes
    centre: np.ndarray  # (N, 3) each row's flight centre (z = 0): float32 centring per flight
    meas: np.ndarray  # (N,) measured RSS
    row_flight: np.ndarray  # (N,) position of each row's flight in ``live``
    pad: np.ndarray  # (N,) flat index of each row in a (live flights, width) array
    width: int  # the longest live flight's rows
    mid: tuple[np.ndarray, np.ndarray]  # per live flight: the middle pair's columns when sorted

    def medians(self, r: np.ndarray) -> np.ndarray:
        """``median_1d`` of every live flight's rows of ``r``, bit for bit (the same middle pair,
        from one sort of the flights side by side, padded with +inf; flight by flight if NaN)."""
        if np.isnan(r).any():
            return np.array([median_1d(r[a:b])[0] for _, a, b in self.bounds])
        m = np.full((len(self.live), self.width), np.inf)
        m.ravel()[self.pad] = r
        m.sort(axis=1)
        rows = np.arange(len(self.live))
        return (m[rows, self.mid[0]] + m[rows, self.mid[1]]) / 2.0

    def sums(self, x: np.ndarray) -> np.ndarray:
        """Every live flight's sum of ``x`` in one call (``np.add.reduceat`` adds in row order):
        the offsets need per-flight sums on every objective call, and one sum per flight was a
        third of a fit's numpy calls.  Equal to each flight's ``np.sum`` to rounding, not bit for
        bit (numpy sums pairwise)."""
        return np.add.reduceat(x, self.starts)


def joint_geometry(
    pipe: Pipeline,
    flights: Sequence[FlightSamples],
    idx: Sequence[np.ndarray],
    yaw: Callable[[int], np.ndarray] | None = None,
) -> JointGeometry | None:
    """The selected samples of all flights as one ``JointGeometry``; None where one call per flight
    is needed (no samples, a flight without attitude or transmitter).  Kept by a ``Selection``
    passed as ``idx`` (``Selection.joint``); ``yaw(k)``: flight k's unwrapped yaw, kept by it."""
    live = [k for k, i in enumerate(idx) if len(i)]
    geo = {
        k: pipe.geometry(
            flights[k],
            idx[k],
            None if yaw is None or pipe.time_offset_s == 0.0 else yaw(k),
        )
        for k in live
    }
    if not live or any(geo[k][1] is None or flights[k].tx_enu_m is None for k in live):
        return None
    rx = [np.asarray(geo[k][0], dtype=float) for k in live]
    n = np.array([len(r) for r in rx])
    ends = np.cumsum(n)
    starts = ends - n
    tx, centre = np.empty((int(ends[-1]), 3)), np.zeros((int(ends[-1]), 3))
    for k, r, e, m in zip(live, rx, ends, n, strict=True):
        tx[e - m : e] = flights[k].tx_enu_m
        centre[e - m : e, :2] = r[:, :2].mean(axis=0)
    meas = np.concatenate([np.asarray(flights[k].rss_dbm[idx[k]], dtype=float) for k in live])
    row_flight = np.repeat(np.arange(len(live)), n)
    pad = row_flight * int(n.max()) + (np.arange(int(ends[-1])) - np.repeat(starts, n))
    h = n // 2
    out = JointGeometry(
        live,
        ends,
        starts,
        n,
        [(k, int(a), int(b)) for k, a, b in zip(live, starts, ends, strict=True)],
        tx,
        np.concatenate(rx),
        np.concatenate([geo[k][1] for k in live]),
        centre,
        meas,
        row_flight,
        pad,
        int(n.max()),
        (np.where(n % 2 == 1, h, h - 1), h),
    )
    for a in (tx, out.rx, out.att, centre, meas, row_flight, pad, ends, starts, n):
        a.flags.writeable = False  # shared between calls
    return out


def _joint(
    pipe: Pipeline, flights: Sequence[FlightSamples], idx: Sequence[np.ndarray]
) -> tuple[JointGeometry | None, Selection | None]:
    """The joint geometry (kept by a ``Selection`` passed as ``idx``) and that selection."""
    sel = _owned(flights, idx)
    return (sel.joint(pipe) if sel is not None else joint_geometry(pipe, flights, idx)), sel


def _joint_rss(pipe: Pipeline, joint: JointGeometry, sel: Selection | None) -> np.ndarray:
    """The model's channel RSS at the joint samples (through the selection's prepared links if
    any: the same values)."""
    links = None if sel is None else sel.links(pipe.model, pipe.time_offset_s, joint)
    if links is not None:
        return np.asarray(pipe.model.rss_dbm(joint.tx, joint.rx, links=links), dtype=float)
    return np.asarray(
        pipe.model.rss_dbm(joint.tx, joint.rx, joint.att, centre=joint.centre), dtype=float
    )


def predict_channels(
    pipe: Pipeline, flights: Sequence[FlightSamples], idx: Sequence[np.ndarray]
) -> list[np.ndarray]:
    """``pipe.predict_channel`` of every flight's samples ``idx``, in one model call: each sample
    paired with its flight's transmitter and shifted by its flight's centre, so the values equal one
    call per flight bit for bit (the physics is elementwise), without the per-call overhead that
    dominates the small fits."""
    joint, sel = _joint(pipe, flights, idx)
    if joint is None:
        return [
            pipe.predict_channel(f, i) if len(i) else np.zeros(0)
            for f, i in zip(flights, idx, strict=True)
        ]
    p = _joint_rss(pipe, joint, sel)
    out = [np.zeros(0) for _ in idx]
    for k, part in zip(joint.live, np.split(p, joint.ends[:-1]), strict=True):
        out[k] = part
    return out


def offset_residuals(
    pipe: Pipeline,
    flights: Sequence[FlightSamples],
    idx: Sequence[np.ndarray],
    slope: bool = False,
    loss: str = "l2",
    f_scale_db: float = 6.0,
    cache: Sequence[np.ndarray] | None = None,
) -> list[np.ndarray]:
    """Offset-removed residuals per flight on the samples ``idx`` (``cache``: channel predictions to
    reuse).

    Every score in the diagnosis is taken on these: the receiver's dB are uncalibrated, so each
    flight's constant offset (and with ``slope`` a path-gain slope) is fitted on the very samples
    scored."""
    joint = joint_offset_residuals(pipe, flights, idx, slope, loss, f_scale_db, cache)
    if joint is not None:
        r, bounds = joint
        out = [np.zeros(0) for _ in idx]
        for k, a, b in bounds:
            out[k] = r[a:b]
        return out
    out = []
    cache = predict_channels(pipe, flights, idx) if cache is None else cache
    for k, (f, i) in enumerate(zip(flights, idx, strict=True)):
        if len(i) == 0:
            out.append(np.zeros(0))
            continue
        p = pipe.finish(cache[k], f, i)
        out.append(offset_residual(f.rss_dbm[i], p, slope, loss, f_scale_db))
    return out


def _field(
    term: SpatialField | TemporalField,
    flights: Sequence[FlightSamples],
    idx: Sequence[np.ndarray],
    live: list[int],
    time: bool,
) -> np.ndarray:
    """A field (``time``: a temporal term) at the selected samples of the ``live`` flights,
    concatenated."""
    return np.concatenate(
        [
            term.field_db(
                flights[k], flights[k].t_s[idx[k]] if time else flights[k].enu_m[idx[k]][:, :2]
            )
            for k in live
        ]
    )


def joint_offset_residuals(
    pipe: Pipeline,
    flights: Sequence[FlightSamples],
    idx: Sequence[np.ndarray],
    slope: bool,
    loss: str,
    f_scale_db: float,
    cache: Sequence[np.ndarray] | None = None,
) -> tuple[np.ndarray, list[tuple[int, int, int]]] | None:
    """``offset_residuals`` of all flights as one array and (flight, start, end) per non-empty
    flight, the elementwise steps and the per-flight sums on all samples at once: the values of
    ``mission.robust.offset_residual`` flight by flight to rounding (the sums add in row order,
    ``JointGeometry.sums``). None where that path does not apply (a slope, a single flight)."""
    if slope or loss not in LOSSES:
        return None
    joint, sel = _joint(pipe, flights, idx)
    if joint is None:
        return None
    live, bounds = joint.live, joint.bounds
    if cache is None:
        p = _joint_rss(pipe, joint, sel)
    else:
        p = np.concatenate([np.asarray(cache[k], dtype=float) for k in live])
    for term, time in ((pipe.spatial, False), (pipe.temporal, True)):
        if term is not None:
            p = p + (
                sel.field(term, live, time)
                if sel is not None
                else _field(term, flights, idx, live, time)
            )
    if pipe.receiver is not None:
        p = pipe.receiver.apply(p)
    r = joint.meas - p
    if loss == "l2":
        off = joint.sums(r) / joint.counts
    else:
        med = joint.medians(r)
        z = r - med[joint.row_flight]
        w = huber_weights(z, f_scale_db)
        off = med + joint.sums(w * z) / joint.sums(w)
    return r - off[joint.row_flight], bounds


def memo(
    obj: object,
    arrays: tuple[np.ndarray, ...],
    compute: Callable[[], np.ndarray],
    extra: object = None,
    size: int = 256,
) -> np.ndarray:
    """Per-object cache of a computed array by the exact input ``arrays`` (their bytes): the fits
    evaluate a fitted term (a kriged field, a free-form map) on the same samples many times.  The
    result is shared: callers must not change it in place."""
    cache: dict = obj.__dict__.setdefault("_cache", {})
    key = (
        extra,
        *(a.shape for a in arrays),
        *(hash(np.ascontiguousarray(a).tobytes()) for a in arrays),
    )
    if key not in cache:
        if len(cache) > size:
            cache.clear()
        cache[key] = compute()
    return cache[key]

"""Uncertainty regions for estimates without a posterior: error circles calibrated by split
conformal prediction.

Why: a network, the strongest sample, the weighted centroid and the plain grid answer with a point
and no posterior, yet every estimate must carry 50 % and 90 % regions.  Flights like those the
method will face, never tuned on, give the distribution of its 2D error; the circle around the
estimate whose radius is that error's conformal quantile (the ``ceil((n + 1) level)``-th smallest of
``n`` calibration errors) holds the truth at the nominal rate or more on any flight exchangeable
with them.  Nothing about the flight at hand narrows the circle: it is honest on average over its
calibration domain and says nothing finer.

One calibration per kind of log:

- ``sim``: held-out simulated flights (for a network, the domain where ``localize`` uses it on
  simulated logs);
- ``real``: the unseen-flight benchmark (``afar`` family, seeds 2027 and 2028), for receiver and
  benchmark logs.

Networks keep theirs in their card (``models/<name>.json``, key ``regions``, with the model file's
sha256); the classical methods in their default configuration in
``mission/data/method_circles.json`` (``benchmarks/calibrate_error_circles.py`` writes both).
Regions are ``mission.localize.region.Region`` of kind ``CIRCLE``: in JSON the layout of
:mod:`mission.localize.uncertainty` (``level``, ``hpd_mass``, ``area_m2``, ``ellipse``,
``polygons``) plus ``kind = "error circle"``, ``radius_m`` and ``calibrated_on``.

What was flown: a flight that flew only part of its planned track (an aborted mission) errs more
than the full flights a record was calibrated on.  A record may carry ``track``: Mondrian
(stratified) conformal radii per stratum of ``coverage``, the share of the planned track flown
(``training_domain.track_coverage``), with the strata's lower ``bounds`` (e.g. [0.18, 0.5, 0.9]);
below the first bound, or for a partial flight under a record without ``track``, no calibration
applies and the estimate says so instead of printing a circle.  A flight whose attitude leaves the
network's training span gets that note too.

Where the transmitter's area is known (the rover area), each circle is clipped to it: the
transmitter cannot lie outside, so the clipped region holds the truth exactly as often as the circle
and is smaller.  Clipped regions carry ``clipped_to`` (the area's name); ``polygons`` and
``area_m2`` are then the clipped region's, ``radius_m`` and ``ellipse`` the circle's.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from mission.errors import InputError
from mission.fields import REQUIRED, Fields
from mission.geo import Area, clip_polygon, polygon_area_m2
from mission.localize import Estimate
from mission.localize.card import REFUSED_KEY, REGIONS_KEY, ModelCard, card_path, model_digest
from mission.localize.methods import FROM_METHOD_CIRCLES, names_where
from mission.localize.region import CIRCLE, Ellipse, Region

METHOD_CIRCLES = Path(__file__).resolve().parent.parent / "data" / "method_circles.json"
# the methods whose circles mission/data/method_circles.json holds (calibrated in their default
# configuration)
CIRCLE_METHODS = names_where(calibration=FROM_METHOD_CIRCLES)
LEVELS = (0.5, 0.9)
NO_CIRCLE_APPLIES = "No uncertainty region: no calibration applies to it."
FULL_TRACK = 0.9  # a flight that flew at least this share of its planned track counts as full
N_VERTICES = 72


def _read_entries(p: Path, what: str) -> dict:
    """The ``{domain: record}`` mapping under ``what`` in JSON file ``p`` ({} when absent)."""
    try:
        entries = json.loads(p.read_text()).get(what) or {}
        if not isinstance(entries, dict):
            raise AttributeError
    except (json.JSONDecodeError, AttributeError):
        raise InputError(
            f"not a JSON object with a {what} mapping", source=str(p), field=what
        ) from None
    return entries


def _checked(rec, p: Path, key: str) -> dict:
    """A stored record with its radii as {level: metres}; ``InputError`` naming file and key when
    malformed (``mission.fields``)."""
    f = Fields(rec, str(p), key)
    try:
        radii = {float(k): float(v) for k, v in f.sub("radii_m", REQUIRED).d.items()}
    except (TypeError, ValueError):
        raise f.err("radii_m", "needs {level: metres}") from None
    if not radii or not all(0.0 < k < 1.0 and 0.0 < v < math.inf for k, v in radii.items()):
        raise f.err("radii_m", "needs levels in (0, 1) and positive finite radii")
    if not f.has("track"):
        return dict(rec, radii_m=radii)
    t = f.sub("track")
    try:
        b = [float(x) for x in t.raw("bounds", REQUIRED)]
        t_radii = {float(k): [float(r) for r in v] for k, v in t.sub("radii_m", REQUIRED).d.items()}
    except (TypeError, ValueError):
        raise f.err("track", "track needs bounds and radii_m") from None
    if (
        set(t_radii) != set(radii)
        or not b
        or not 0.0 < b[0] <= 1.0
        or b != sorted(b)
        or not all(
            len(v) == len(b) and all(0.0 < r < math.inf for r in v) for v in t_radii.values()
        )
    ):
        raise f.err(
            "track",
            "track needs ascending coverage bounds in (0, 1] and, for each of the record's "
            "levels, one positive radius per bound",
        )
    return dict(rec, track=dict(t.d, bounds=b, radii_m=t_radii), radii_m=radii)


def flown_radii(rec: dict, coverage: float | None) -> tuple[dict[float, float] | None, str]:
    """(level -> radius, how) for a flight that flew ``coverage`` of its planned track (None: no
    plan known), or (None, why no calibration applies)."""
    tr = rec.get("track")
    if coverage is None:
        return rec["radii_m"], ""
    if tr is not None and coverage >= tr["bounds"][0]:
        k = int(np.searchsorted(tr["bounds"], coverage, side="right")) - 1
        hi = tr["bounds"][k + 1] if k + 1 < len(tr["bounds"]) else 1.0
        return (
            {lv: r[k] for lv, r in tr["radii_m"].items()},
            f"; for flights that flew {100 * tr['bounds'][k]:.0f}-{100 * hi:.0f} % of their "
            "planned track "
            f"(this one {100 * coverage:.0f} %)",
        )
    if coverage >= FULL_TRACK:
        return rec["radii_m"], ""
    lo = f"{100 * tr['bounds'][0]:.0f}" if tr is not None else f"{100 * FULL_TRACK:.0f}"
    return None, (
        f"no calibration applies: this flight flew {100 * coverage:.0f} % of its planned "
        "track, its "
        f"circles were calibrated on flights that flew {lo}-100 %"
    )


def card_calibration(model, domain: str) -> tuple[dict | None, str | None]:
    """(the card's calibration for ``domain`` ("sim" or "real"), None) or (None, why there is none:
    no card, no entry, or an entry measured on another model file); a malformed entry is an
    ``InputError`` naming the card and key.  ``model``: a ``card.ModelCard`` (read once with its
    network) or a model file's path."""
    path = model.path if isinstance(model, ModelCard) else model
    p = card_path(path)
    where = f"{p.name}, benchmarks/calibrate_error_circles.py"
    if isinstance(model, ModelCard):
        entries, digest = model.regions, model.sha256
        if entries is not None and not isinstance(entries, dict):
            raise InputError(
                f"not a JSON object with a {REGIONS_KEY} mapping", source=str(p), field=REGIONS_KEY
            )
    else:
        entries = _read_entries(p, REGIONS_KEY) if p.is_file() else None
        digest = None
    if entries is None:
        return None, f"{Path(path).name} has no model card ({where})"
    rec = entries.get(domain)
    if rec is None:
        return None, f"{Path(path).name} has no '{domain}' calibration in its card ({where})"
    if isinstance(rec, dict) and set(rec) == {REFUSED_KEY}:  # calibrated, then refused by a rule
        why = Fields(rec, str(p), f"{REGIONS_KEY}.{domain}").str_(REFUSED_KEY)
        return None, f"{Path(path).name}'s '{domain}' circles were refused: {why}"
    rec = _checked(rec, p, f"{REGIONS_KEY}.{domain}")
    if rec.get("model_sha256") != (digest or model_digest(path)):
        return (
            None,
            f"the '{domain}' calibration in {p.name} was measured on another version of the "
            "model file",
        )
    return rec, None


def method_calibration(
    method: str, domain: str, path: Path = METHOD_CIRCLES
) -> tuple[dict | None, str | None]:
    """(the calibration of a classical method's default configuration for ``domain``, None) or
    (None, why not)."""
    rec = _read_entries(path, method).get(domain) if path.is_file() else None
    if rec is None:
        return None, f"no '{domain}' calibration of {method} in {path.name}"
    return _checked(rec, path, f"{method}.{domain}"), None


def circle_regions(
    x: float, y: float, radii: dict[float, float], calibrated_on: str, area: Area | None = None
) -> tuple[Region, ...]:
    """Error circles around (x, y) for each level -> radius (``Region`` of kind ``CIRCLE``);
    clipped to ``area`` where it is given and overlaps the circle (a circle that misses it is kept
    whole)."""
    t = np.linspace(0.0, 2.0 * np.pi, N_VERTICES + 1)
    out = []
    for lv, r in sorted(radii.items()):
        ring = np.stack([x + r * np.cos(t), y + r * np.sin(t)], axis=1)
        area_m2, clipped_to, polys = float(np.pi * r * r), None, [ring]
        if area is not None and not area.contains(ring[:-1]).all():
            parts = clip_polygon(area.vertices, ring[:-1])  # a non-convex area may leave several
            if parts:
                area_m2 = float(sum(polygon_area_m2(p) for p in parts))
                clipped_to = area.name
                polys = [np.vstack([p, p[:1]]) for p in parts]
        out.append(
            Region(
                level=float(lv),
                mass=float(lv),
                area_m2=area_m2,
                ellipse=Ellipse(float(x), float(y), float(r), float(r), 0.0),
                polygons=tuple(tuple(map(tuple, np.round(p, 1).tolist())) for p in polys),
                kind=CIRCLE,
                radius_m=float(r),
                calibrated_on=calibrated_on,
                clipped_to=clipped_to,
            )
        )
    return tuple(out)


def attach_circles(
    est: Estimate,
    calibration: tuple[dict | None, str | None],
    area: Area | None = None,
    flown: dict | None = None,
) -> str | None:
    """Give ``est`` the error circles of ``calibration`` (a ``card_calibration`` /
    ``method_calibration`` answer) around its point, clipped to ``area``, sized for what was
    ``flown`` (``training_domain.flown_domain``); returns the note to show when there is no
    calibration."""
    flown = flown or {}
    cov = flown.get("track_coverage")
    if cov is not None:
        est.extras["track_coverage"] = round(float(cov), 3)
    if flown.get("attitude_note"):
        return f"{flown['attitude_note']}. {NO_CIRCLE_APPLIES}"
    rec, why = calibration
    if rec is None:
        return f"no uncertainty region: {why}"
    radii, how = flown_radii(rec, cov)
    if radii is None:
        return f"no uncertainty region: {how}"
    src = (
        rec["track"].get("calibrated_on", "")
        if how and "track" in rec
        else rec.get("calibrated_on", "")
    )
    est.regions = circle_regions(est.x_m, est.y_m, radii, str(src) + how, area)
    return None

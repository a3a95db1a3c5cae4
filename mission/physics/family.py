"""Physics families: a distribution over propagation models and residual structure, drawn once per
flight.

A family is a JSON record (``rfsl gap --family F.json`` writes one from the diagnosis of real
flights; the shipped ``mission/data/afar_family.json`` is the AFAR one).  Simulated benchmarks,
training sets and the track-matched inference draw each simulated flight's physics from it, so that
what they see spreads the way real flights spread, not around one calibrated point.

Schema (``schema`` 1)::

    {"schema": 1, "name": "...", "description": "...", "source": {...how it was made...},
     "spec": {...},            # a model spec (mission.physics.presets.build_model); any value may
                               # be a distribution (below), nested dicts (e.g. "ground") are drawn
                               # key by key
     "variants": [             # optional: alternatives merged into the spec, one drawn per flight
        {"p": 0.6, "spec": {"rx_pattern": "measured", "rx_flipped": true}}, ...],
     # correlated field + white nugget
     "residual": {"shadowing_db": D, "shadowing_corr_m": D, "noise_db": D},
     "shadowing_over": "ground",  # optional: or "path" (below)
     "shadowing_marginal": {"p": [...], "q": [...]},  # optional: the shadowing's shape (below)
     "shadowing_covariance": "gaussian",  # optional: or "exponential" (below)
     "offset_db": D,           # the receiver's uncalibrated offset
     "nuisance": {"time_drift_db": D, "radial_db": D},  # optional: per-flight structure (below)
     "per_flight": [...]}      # optional: the fitted values per real flight (information only)

A distribution ``D`` is a number (fixed) or ``{"dist": "uniform", "lo", "hi"}``, ``{"dist":
"loguniform", "lo", "hi"}``, ``{"dist": "normal", "mean", "sd", ["lo", "hi"]}`` (clipped),
``{"dist": "choice", "options": [...], ["p": [...]]}`` or ``{"dist": "empirical", "values": [...]}``
(one of the values, uniformly: a parameter's per-flight fits when too few flights support a
parametric shape).

Draw order per flight (reproducible from the caller's generator): spec values in key order (nested
dicts in their key order), the variant, residual (shadowing_db, shadowing_corr_m, noise_db), offset,
then the nuisance values in key order (only a family that has them draws them: an older family's
draws are unchanged).

Per-flight nuisance (``nuisance``): structure that repeats within a flight but is not in the model
spec, drawn once per flight so that only what is left is drawn as shadowing.  ``time_drift_db``:
the std (over the flight's samples) of a smooth gain drift along the flight, a random combination of
Legendre P_1..P_4 over the samples' order scaled to [-1, 1] (coefficient sd 1 / (1 + p^2), the
smooth part of the gap's ``time_drift`` basis) rescaled to that std; ``simulate_rss`` adds it after
the shadowing.  ``radial_db``: the std of a smooth profile over the log distance to the
transmitter (``radial_profile``: Legendre P_1..P_4 of ``log_distance_unit``, the same coefficient
sd), added after the drift: structure about the transmitter, which leaves the RSS peak where it is.
``azimuth_db``: the std of a ripple over the body azimuth of the transmitter seen from the UAV
(``azimuth_ripple``: cos and sin of k az_b for k = 1..DRIFT_ORDER, coefficient sd 1 / (1 + k^2)),
added after the radial profile: an antenna pattern the model does not have, fixed to the body.

What the shadowing is fixed to (``shadowing_over``, ``physics.shadowing.SHADOWING_OVER``): the
ground (the default; every older family), or the flight's own path (``path_shadowing``: correlated
along the track with the same sigma and correlation length, independent on a later pass over the
same ground), which is what the gap diagnosis finds on the real flights ("correlated within
flights").  It takes no random numbers of its own: a family's draws are the same either way.

The shadowing's shape (``shadowing_marginal``, optional): a standardized marginal (probabilities
``p``, increasing in (0, 1), and quantiles ``q``, non-decreasing, mean 0 and std 1) to which the
Gaussian draw is mapped sample by sample (``physics.shadowing.quantile_mapped``, a Gaussian
copula: the correlation's ranks are kept).  The real flights' residual is skewed to fades; without
the key the shadowing is Gaussian, as in every older family.  It takes no random numbers either.

The shadowing's covariance (``shadowing_covariance``, optional): ``gaussian`` (exp(-h^2/L^2),
smooth; every older family) or ``exponential`` (exp(-h/L), rough: Gudmundson's model), whose
``residual`` sigma and range are then an exponential variogram's (``--family-exponential``).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from mission.errors import InputError
from mission.fields import REQUIRED, Fields, is_number
from mission.files import read_text
from mission.physics.geometry import body_angles, horizontal_distance, link_delta
from mission.physics.presets import build_model
from mission.physics.shadowing import COVARIANCES, SHADOWING_OVER, Marginal, draw_shadowing

SCHEMA = 1
DISTS = ("uniform", "loguniform", "normal", "choice", "empirical")
RESIDUAL_KEYS = ("shadowing_db", "shadowing_corr_m", "noise_db")
NUISANCE_KEYS = ("time_drift_db", "radial_db", "azimuth_db")
# how a family's shadowing is drawn beyond sigma and range, each key only where it is not the
# default (a ground field of Gaussian shape)
SHADOWING_KEYS = ("shadowing_over", "shadowing_marginal", "shadowing_covariance")
DRIFT_ORDER = 4  # Legendre orders of the drawn time drift (the gap's ``temporal.DRIFT_ORDER``)
# ``afar-fades``: issue 34's family (fades of the real shape, exponential covariance; passes 9 of
# the benchmark's 13 predictive checks against the shipped ``afar``'s 8, mission/gap/README.md)
SHIPPED = {"afar": "afar_family.json", "afar-fades": "afar_fades_family.json"}


def _is_dist(v: Any) -> bool:
    return isinstance(v, dict) and "dist" in v


def check_dist(v: Any, where: str, source: str | None = None) -> None:
    """Refuse a malformed distribution (one line naming the field, ``mission.fields``)."""
    if isinstance(v, bool) or v is None or isinstance(v, str):
        return
    f, name = Fields.holding(v, source, where)
    if isinstance(v, int | float):
        f.num(name)
        return
    if not _is_dist(v):
        raise f.err(name, "neither a number nor a distribution")
    d = f.sub(name)
    kind = d.str_("dist", choices=DISTS)
    if kind in ("uniform", "loguniform"):
        lo = d.num("lo")
        d.num("hi", lo=lo)  # a range: hi >= lo
        if kind == "loguniform" and lo <= 0:
            raise d.err("lo", f"a loguniform range needs lo > 0, got {lo}")
    elif kind == "normal":
        d.num("mean")
        d.num("sd", lo=0.0)
        d.num("lo", None)  # optional clipping bounds
        d.num("hi", None)
    else:
        vals = d.raw("options" if kind == "choice" else "values", REQUIRED)
        if not isinstance(vals, list) or not vals:
            raise d.err("options" if kind == "choice" else "values", "needs a non-empty list")
        p = d.raw("p")
        if (
            kind == "choice"
            and p is not None
            and (
                not isinstance(p, list)
                or len(p) != len(vals)
                or not all(is_number(x) for x in p)
                or not abs(sum(p) - 1.0) <= 1e-6  # NaN weights too
            )
        ):
            raise d.err("p", "must have one weight per option and sum to 1")


def draw_value(v: Any, rng: np.random.Generator) -> Any:
    """One draw of a distribution (a plain value is returned as it is)."""
    if not _is_dist(v):
        return v
    kind = v["dist"]
    if kind == "uniform":
        lo, hi = float(v["lo"]), float(v["hi"])
        return float(rng.uniform(lo, hi)) if hi > lo else lo
    if kind == "loguniform":
        lo, hi = math.log(float(v["lo"])), math.log(float(v["hi"]))
        return float(math.exp(rng.uniform(lo, hi))) if hi > lo else math.exp(lo)
    if kind == "normal":
        x = float(rng.normal(float(v["mean"]), float(v["sd"])))
        return float(np.clip(x, float(v.get("lo", -np.inf)), float(v.get("hi", np.inf))))
    if kind == "choice":
        opts = v["options"]
        return opts[int(rng.choice(len(opts), p=v.get("p")))]
    vals = v["values"]
    return vals[int(rng.integers(len(vals)))]


def _draw_tree(tree: dict, rng: np.random.Generator) -> dict:
    out: dict = {}
    for k in sorted(tree):
        v = tree[k]
        if isinstance(v, dict) and not _is_dist(v):
            out[k] = _draw_tree(v, rng)
        else:
            out[k] = draw_value(v, rng)
    return out


def _check_tree(tree: dict, where: str, source: str | None) -> None:
    for k, v in tree.items():
        if isinstance(v, dict) and not _is_dist(v):
            _check_tree(v, f"{where}.{k}", source)
        else:
            check_dist(v, f"{where}.{k}", source)


@dataclass(frozen=True)
class FamilyDraw:
    """One flight's physics: the model spec (for ``build_model``), the residual field and the
    offset."""

    spec: dict
    shadowing_db: float
    shadowing_corr_m: float
    noise_db: float
    offset_db: float
    time_drift_db: float = 0.0  # std of the flight's smooth gain drift (``nuisance``)
    radial_db: float = 0.0  # std of the flight's profile over the distance to the rover
    azimuth_db: float = 0.0  # std of the flight's ripple over the body azimuth of the rover
    shadowing_over: str = "ground"  # what the shadowing is fixed to (``SHADOWING_OVER``)
    shadowing_marginal: Marginal | None = None  # its standardized shape; None: Gaussian
    shadowing_covariance: str = "gaussian"  # its covariance (``COVARIANCES``)

    def model(self, name: str = "family"):
        """The propagation model of this draw."""
        return build_model(self.spec, name=name)

    def to_dict(self) -> dict:
        over = shadowing_record(
            self.shadowing_over, self.shadowing_marginal, self.shadowing_covariance
        )
        return (
            {
                "spec": self.spec,
                "shadowing_db": self.shadowing_db,
                "shadowing_corr_m": self.shadowing_corr_m,
                "noise_db": self.noise_db,
                "offset_db": self.offset_db,
            }
            | over
            | {k: v for k, v in self.nuisance().items() if v}
        )

    def nuisance(self) -> dict[str, float]:
        """The per-flight nuisance stds by ``NUISANCE_KEYS`` (``nuisance_rss`` draws them)."""
        return {k: getattr(self, k) for k in NUISANCE_KEYS}


def lowest(v: Any) -> float:
    """The lowest value a distribution (or a number) can draw: what a physical bound is checked
    against."""
    if not isinstance(v, dict):
        return float(v)
    if v["dist"] in ("uniform", "loguniform"):  # drawn between lo and hi, whichever is lower
        return min(float(v["lo"]), float(v["hi"]))
    if v["dist"] == "normal":  # clipped to [lo, hi]: hi when hi < lo
        return min(float(v.get("lo", -np.inf)), float(v.get("hi", np.inf)))
    return min(float(x) for x in v["options" if v["dist"] == "choice" else "values"])


@dataclass(frozen=True)
class PhysicsFamily:
    """A distribution over per-flight physics (module docstring); ``draw(rng)`` gives one
    flight's."""

    name: str
    spec: dict
    residual: dict
    offset_db: Any = 0.0
    variants: tuple = ()
    record: dict = field(default_factory=dict, compare=False, repr=False)
    nuisance: dict = field(default_factory=dict)
    shadowing_over: str = "ground"
    shadowing_marginal: Marginal | None = None
    shadowing_covariance: str = "gaussian"

    @classmethod
    def from_dict(cls, d: dict, source: str | None = None) -> PhysicsFamily:
        """Validate and build (bad records raise ``InputError`` naming the field)."""
        if not isinstance(d, dict):
            raise InputError("a physics family must be a JSON object", source=source)
        schema = d.get("schema")
        if isinstance(schema, bool) or not isinstance(schema, int | float) or schema != SCHEMA:
            raise InputError(
                f"physics family schema {d.get('schema')!r} (expected {SCHEMA})",
                source=source,
                field="schema",
            )
        spec = d.get("spec")
        if not isinstance(spec, dict) or "base" not in spec:
            raise InputError(
                "physics family needs a 'spec' object with a 'base'", source=source, field="spec"
            )
        _check_tree(spec, "spec", source)
        # a negative sigma, noise or correlation length is no physics
        res = d.get("residual", {})
        _check_section(res, "residual", RESIDUAL_KEYS, source, positive=("shadowing_corr_m",))
        check_dist(d.get("offset_db", 0.0), "offset_db", source)
        nuis = d.get("nuisance", {})
        _check_section(nuis, "nuisance", NUISANCE_KEYS, source)
        nuis = dict(nuis)
        over = _one_of(d, "shadowing_over", SHADOWING_OVER, "ground", source)
        marginal = check_marginal(d.get("shadowing_marginal"), source)
        cov = _one_of(d, "shadowing_covariance", COVARIANCES, "gaussian", source)
        variants = d.get("variants", [])
        if not isinstance(variants, list):
            raise InputError("variants must be a list", source=source, field="variants")
        for i, v in enumerate(variants):
            if (
                not isinstance(v, dict)
                or not isinstance(v.get("spec"), dict)
                or not float(v.get("p", -1)) >= 0
            ):
                raise InputError(
                    f"variants[{i}] needs 'p' >= 0 and a 'spec' object",
                    source=source,
                    field=f"variants[{i}]",
                )
            _check_tree(v["spec"], f"variants[{i}].spec", source)
        if variants and abs(sum(float(v["p"]) for v in variants) - 1.0) > 1e-6:
            raise InputError("variants' p must sum to 1", source=source, field="variants")
        fam = cls(
            str(d.get("name", "family")),
            spec,
            res,
            d.get("offset_db", 0.0),
            tuple(variants),
            dict(d),
            nuis,
            over,
            marginal,
            cov,
        )
        fam._check_builds(source)
        return fam

    def _check_builds(self, source: str | None) -> None:
        """Every variant's spec must build (a typo in a key fails here, not in a worker later)."""
        rng = np.random.default_rng(0)
        for v in self.variants or ({"spec": {}},):
            spec = {**_draw_tree(self.spec, rng), **_draw_tree(v["spec"], rng)}
            try:
                FamilyDraw(spec, 0.0, 1.0, 0.0, 0.0).model()
            except (ValueError, KeyError, TypeError) as e:
                raise InputError(
                    f"physics family spec does not build: {e}", source=source, field="spec"
                ) from None

    def draw(self, rng: np.random.Generator) -> FamilyDraw:
        """One flight's physics (draw order in the module docstring)."""
        spec = _draw_tree(self.spec, rng)
        if self.variants:
            p = np.array([float(v["p"]) for v in self.variants])
            v = self.variants[int(rng.choice(len(p), p=p / p.sum()))]
            spec.update(_draw_tree(v["spec"], rng))
        res = _draw_tree(self.residual, rng)
        offset = float(draw_value(self.offset_db, rng))
        nuis = _draw_tree(self.nuisance, rng) if self.nuisance else {}
        return FamilyDraw(
            spec,
            float(res.get("shadowing_db", 0.0)),
            float(res.get("shadowing_corr_m", 30.0)),
            float(res.get("noise_db", 0.0)),
            offset,
            *(float(nuis.get(k, 0.0)) for k in NUISANCE_KEYS),
            shadowing_over=self.shadowing_over,
            shadowing_marginal=self.shadowing_marginal,
            shadowing_covariance=self.shadowing_covariance,
        )

    def to_dict(self) -> dict:
        d = dict(self.record)
        d.update(
            schema=SCHEMA,
            name=self.name,
            spec=self.spec,
            residual=self.residual,
            offset_db=self.offset_db,
        )
        if self.variants:
            d["variants"] = list(self.variants)
        if self.nuisance:
            d["nuisance"] = self.nuisance
        d.update(
            shadowing_record(
                self.shadowing_over, self.shadowing_marginal, self.shadowing_covariance
            )
        )
        return d


def shadowing_record(over: str, marginal: Marginal | None, covariance: str) -> dict[str, Any]:
    """The ``SHADOWING_KEYS`` of a family or a draw, each only where it is not the default (a
    ground field of Gaussian shape and covariance), so that an older record is unchanged."""
    out: dict[str, Any] = {}
    if over != "ground":
        out["shadowing_over"] = over
    if marginal is not None:
        out["shadowing_marginal"] = {"p": list(marginal[0]), "q": list(marginal[1])}
    if covariance != "gaussian":
        out["shadowing_covariance"] = covariance
    return out


def _one_of(d: dict, key: str, options: tuple[str, ...], default: str, source: str | None) -> str:
    """``d[key]`` (``default`` when absent) if it is one of ``options``; a one-line
    ``InputError`` naming the field otherwise."""
    value = d.get(key, default)
    if value not in options:
        raise InputError(
            f"{key} {value!r} must be one of {', '.join(options)}", source=source, field=key
        )
    return value


def check_marginal(m: Any, source: str | None = None) -> Marginal | None:
    """A family's ``shadowing_marginal`` as (p, q) tuples, None when absent; a one-line
    ``InputError`` naming the field unless ``p`` and ``q`` are lists of at least 3 finite numbers
    of one length, ``p`` increasing inside (0, 1) and ``q`` non-decreasing."""
    if m is None:
        return None
    field = "shadowing_marginal"
    try:
        p = np.asarray(m["p"], dtype=float)
        q = np.asarray(m["q"], dtype=float)
    except (TypeError, KeyError, ValueError, IndexError):
        raise InputError(
            f"{field} must be an object with lists 'p' and 'q' of numbers",
            source=source,
            field=field,
        ) from None
    if not isinstance(m, dict) or p.ndim != 1 or p.shape != q.shape or len(p) < 3:
        raise InputError(
            f"{field}: 'p' and 'q' must be lists of one length, at least 3",
            source=source,
            field=field,
        )
    if not (np.isfinite(p).all() and np.isfinite(q).all()):
        raise InputError(f"{field}: every p and q must be finite", source=source, field=field)
    if not (p[0] > 0 and p[-1] < 1 and (np.diff(p) > 0).all() and (np.diff(q) >= 0).all()):
        raise InputError(
            f"{field}: 'p' must increase inside (0, 1) and 'q' must not decrease",
            source=source,
            field=field,
        )
    return tuple(p.tolist()), tuple(q.tolist())


def _check_section(
    obj: Any, name: str, keys: tuple[str, ...], source: str | None, positive: tuple[str, ...] = ()
) -> None:
    """A family's ``residual`` or ``nuisance`` object: known ``keys``, each a number or
    distribution never drawn below 0 (above 0 for ``positive``); a one-line ``InputError`` naming
    the field otherwise."""
    if not isinstance(obj, dict) or set(obj) - set(keys):
        raise InputError(f"{name} keys must be among {', '.join(keys)}", source=source, field=name)
    _check_tree(obj, name, source)
    _check_never_negative(obj, name, source, positive=positive)


def _check_never_negative(
    values: dict, where: str, source: str | None, positive: tuple[str, ...] = ()
) -> None:
    """Each value of ``values`` (the family's ``where`` object) is a number or a distribution that
    is never drawn below 0 (never at or below 0 for the keys in ``positive``); a one-line
    ``InputError`` naming the field otherwise."""
    for k, v in values.items():
        field = f"{where}.{k}"
        try:
            low = lowest(v)
        except (TypeError, ValueError, KeyError):
            raise InputError(
                f"{field} must be a number or a distribution", source=source, field=field
            ) from None
        if not low >= 0 or (k in positive and low <= 0):
            raise InputError(
                f"{field} can be drawn {'<=' if k in positive else '<'} 0",
                source=source,
                field=field,
            )


def time_drift(n: int, std_db: float, rng: np.random.Generator) -> np.ndarray:
    """A smooth gain drift over ``n`` samples in flight order, std ``std_db`` over them: a random
    combination of Legendre P_1..P_DRIFT_ORDER of the order scaled to [-1, 1], coefficient sd
    1 / (1 + p^2) (module docstring); zeros when ``std_db`` is 0 or fewer than 3 samples."""
    if std_db <= 0 or n < 3:
        return np.zeros(n)
    return _smooth_draw(np.linspace(-1.0, 1.0, n), std_db, rng)


def _smooth_draw(u: np.ndarray, std_db: float, rng: np.random.Generator) -> np.ndarray:
    """A random combination of Legendre P_1..P_DRIFT_ORDER of ``u`` (on [-1, 1]), coefficient sd
    1 / (1 + p^2), rescaled to std ``std_db`` over the samples; zeros where it does not vary (all
    ``u`` equal): the draw of both the time drift and the radial profile."""
    c = rng.normal(0.0, 1.0, DRIFT_ORDER) / _ORDER_DIV
    return _rescaled(np.polynomial.legendre.legval(u, np.concatenate([[0.0], c])), std_db)


# every smooth draw's coefficient of order k = 1..DRIFT_ORDER is a standard normal / (1 + k^2)
_ORDER_DIV = 1.0 + np.arange(1, DRIFT_ORDER + 1) ** 2


def _rescaled(g: np.ndarray, std_db: float) -> np.ndarray:
    """``g`` scaled to std ``std_db`` over its samples; zeros where it does not vary."""
    sd = float(np.std(g))
    return g * (std_db / sd) if sd > 1e-12 else np.zeros(len(g))


def radial_coordinate(tx_enu: np.ndarray, rx_enu: np.ndarray) -> np.ndarray:
    """``log_distance_unit`` of each sample's horizontal distance to the transmitter: the
    coordinate the radial profile is drawn over and the gap's family fits it on."""
    d = np.asarray(rx_enu, dtype=float)[:, :2] - np.asarray(tx_enu, dtype=float)[None, :2]
    return log_distance_unit(horizontal_distance(d[:, 0], d[:, 1]))


def log_distance_unit(d_m: np.ndarray) -> np.ndarray:
    """Horizontal distance to the transmitter as a coordinate on [-1, 1]: log10 over 10-500 m
    (clipped), the scale of the radial profiles and of the gap's site maps."""
    return np.clip(np.log10(np.maximum(np.asarray(d_m, dtype=float), 5.0) / 70.7) / 0.85, -1.0, 1.0)


def radial_profile(
    tx_enu: np.ndarray, rx_enu: np.ndarray, std_db: float, rng: np.random.Generator
) -> np.ndarray:
    """A smooth profile over the samples' distance to the transmitter, std ``std_db`` over them: a
    random combination of Legendre P_1..P_DRIFT_ORDER of ``log_distance_unit``, coefficient sd
    1 / (1 + p^2), as ``time_drift`` draws over time; zeros when ``std_db`` is 0, with fewer than 3
    samples or all at one distance."""
    n = len(rx_enu)
    if std_db <= 0 or n < 3:
        return np.zeros(n)
    return _smooth_draw(radial_coordinate(tx_enu, rx_enu), std_db, rng)


def azimuth_coordinate(
    tx_enu: np.ndarray, rx_enu: np.ndarray, attitude_rad: np.ndarray | None
) -> np.ndarray:
    """The body azimuth (rad, in [0, 2 pi)) of the transmitter seen from each sample's UAV: the
    coordinate the azimuth ripple is drawn over and the gap's family fits it on."""
    dx, dy, dz = link_delta(tx_enu, np.asarray(rx_enu, dtype=float))
    az, _ = body_angles(np.stack([dy, dx, -dz], axis=-1), attitude_rad)
    return az


def azimuth_basis(az: np.ndarray) -> np.ndarray:
    """(N, 2 DRIFT_ORDER) columns cos k az, sin k az for k = 1..DRIFT_ORDER."""
    k = np.arange(1, DRIFT_ORDER + 1)
    return np.column_stack([np.cos(az[:, None] * k), np.sin(az[:, None] * k)])


def azimuth_ripple(
    tx_enu: np.ndarray,
    rx_enu: np.ndarray,
    attitude_rad: np.ndarray | None,
    std_db: float,
    rng: np.random.Generator,
) -> np.ndarray:
    """A ripple over the body azimuth of the transmitter, std ``std_db`` over the samples: a random
    combination of ``azimuth_basis`` (coefficient sd 1 / (1 + k^2) for cos and sin of k az_b);
    zeros when ``std_db`` is 0, with fewer than 3 samples or one azimuth throughout."""
    n = len(rx_enu)
    if std_db <= 0 or n < 3:
        return np.zeros(n)
    c = rng.normal(0.0, 1.0, 2 * DRIFT_ORDER) * np.tile(1.0 / _ORDER_DIV, 2)
    return _rescaled(azimuth_basis(azimuth_coordinate(tx_enu, rx_enu, attitude_rad)) @ c, std_db)


def load_family(name_or_path: str | Path = "afar") -> PhysicsFamily:
    """A shipped family by name (``afar``) or a family JSON file (``rfsl gap --family`` output)."""
    s = str(name_or_path)
    if s in SHIPPED:
        ref = resources.files("mission").joinpath("data", SHIPPED[s])
        src = str(ref)
        try:
            d = json.loads(ref.read_text(encoding="utf-8"))
        except (OSError, json.JSONDecodeError) as e:
            raise InputError(f"cannot read shipped physics family {s!r}: {e}", source=src) from None
        return PhysicsFamily.from_dict(d, source=src)
    p = Path(s)
    if not p.suffix.lower() == ".json":
        raise InputError(
            f"unknown physics family {s!r} (a shipped name: {', '.join(SHIPPED)}, or a .json file)",
            field="family",
        )

    if not p.exists():
        raise InputError("cannot read physics family: no such file", source=s)
    try:
        d = json.loads(read_text(p, "physics family", max_bytes=50_000_000))
    except json.JSONDecodeError as e:
        raise InputError(f"not JSON (line {e.lineno}): {e.msg}", source=s) from None
    except RecursionError:
        raise InputError("JSON nested too deeply to be a physics family", source=s) from None
    return PhysicsFamily.from_dict(d, source=s)


def simulate_rss(
    draw: FamilyDraw,
    tx_enu: np.ndarray,
    rx_enu: np.ndarray,
    attitude_rad: np.ndarray,
    rng: np.random.Generator,
    model=None,
) -> np.ndarray:
    """RSS (dBm) of one flight under a family draw: model + offset + correlated shadowing (over the
    ground or along the path, ``draw.shadowing_over``) + white noise + the per-flight nuisance
    (``simulate_parts``, summed).

    ``model`` may be passed when the caller already built ``draw.model()`` (it is the expensive
    part)."""
    p = simulate_parts(draw, tx_enu, rx_enu, attitude_rad, rng, model)
    return p["model"] + p["noise"] + p["shadowing"] + p["nuisance"]


def simulate_parts(
    draw: FamilyDraw,
    tx_enu: np.ndarray,
    rx_enu: np.ndarray,
    attitude_rad: np.ndarray,
    rng: np.random.Generator,
    model=None,
) -> dict[str, np.ndarray]:
    """The parts ``simulate_rss`` sums (dB per sample): ``model`` (with the offset), white
    ``noise``, ``shadowing`` and the per-flight ``nuisance``, drawn in that order from ``rng`` (the
    one home of the draw order; ``benchmarks/copy_parts.py`` adds them one at a time)."""
    m = draw.model() if model is None else model
    rx = np.asarray(rx_enu, dtype=float)
    base = np.asarray(m.rss_dbm(np.asarray(tx_enu, dtype=float), rx, attitude_rad), dtype=float)
    base = base + draw.offset_db
    noise = rng.normal(0.0, draw.noise_db, size=base.shape)
    shadowing = np.zeros_like(base)
    if draw.shadowing_db > 0:
        shadowing = draw_shadowing(
            rx,
            draw.shadowing_db,
            draw.shadowing_corr_m,
            draw.shadowing_over,
            rng,
            draw.shadowing_marginal,
            draw.shadowing_covariance,
        )
    nuisance = nuisance_rss(tx_enu, rx, attitude_rad, draw.nuisance(), rng)
    return {"model": base, "noise": noise, "shadowing": shadowing, "nuisance": nuisance}


def nuisance_rss(
    tx_enu: np.ndarray,
    rx_enu: np.ndarray,
    attitude_rad: np.ndarray,
    stds: Mapping[str, float],
    rng: np.random.Generator,
) -> np.ndarray:
    """The per-flight nuisance (dB) of a flight's samples from ``stds`` (by ``NUISANCE_KEYS``, a
    missing key 0), each part drawn only when its std is positive, in the order drift, radial
    profile, azimuth ripple: a draw without one is unchanged (the family's draws and the
    benchmark's flights share this one order)."""
    time_drift_db, radial_db, azimuth_db = (float(stds.get(k, 0.0)) for k in NUISANCE_KEYS)
    out = np.zeros(len(rx_enu))
    if time_drift_db > 0:  # after the shadowing: a draw without drift is unchanged
        out += time_drift(len(out), time_drift_db, rng)
    if radial_db > 0:  # after the drift
        out += radial_profile(tx_enu, rx_enu, radial_db, rng)
    if azimuth_db > 0:  # after the radial profile
        out += azimuth_ripple(tx_enu, rx_enu, attitude_rad, azimuth_db, rng)
    return out

"""One uncertainty region of an estimate, typed: an HPD set of a posterior
(``uncertainty.hpd_regions``) or an error circle (``error_circles.circle_regions``).

Why a dataclass: the regions were dicts read by key in a dozen places; ``Region`` names each field
once, says in one place how a region reads (``describe``) and how it is written (``to_dict``, the
``localize --json`` layout of ``mission.localize.uncertainty``'s docstring, key for key and in the
same order), and reads an old ``--json`` output back with a one-line error on a bad field
(``from_dict``).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

from mission.fields import REQUIRED, Fields, is_number

HPD = "hpd"  # a highest-posterior-density set of the method's own posterior
CIRCLE = "error circle"  # a split-conformal circle around the point (``error_circles``)
ELLIPSE_KEYS = ("x_m", "y_m", "a_m", "b_m", "angle_deg")

Polygon = tuple[tuple[float, float], ...]


@dataclass(frozen=True)
class Ellipse:
    """The ellipse that summarises a region: centre (``x_m``, ``y_m``), semi-axes ``a_m`` >=
    ``b_m`` and the major axis ``angle_deg`` counter-clockwise from east (a circle: a = b =
    radius)."""

    x_m: float
    y_m: float
    a_m: float
    b_m: float
    angle_deg: float

    def to_dict(self) -> dict[str, float]:
        return {k: getattr(self, k) for k in ELLIPSE_KEYS}

    @classmethod
    def from_fields(cls, f: Fields) -> Ellipse:
        """Read from a mapping with the five keys (``Fields``: a bad one is a one-line error)."""
        e = cls(*(f.num(k, REQUIRED) for k in ELLIPSE_KEYS))
        f.done()
        return e

    def contains(self, x: float, y: float) -> bool:
        """Whether (x, y) lies inside the ellipse."""
        t = math.radians(self.angle_deg)
        dx, dy = x - self.x_m, y - self.y_m
        u = dx * math.cos(t) + dy * math.sin(t)
        v = -dx * math.sin(t) + dy * math.cos(t)
        return bool((u / max(self.a_m, 1e-9)) ** 2 + (v / max(self.b_m, 1e-9)) ** 2 <= 1.0)


@dataclass(frozen=True)
class Region:
    """A region that holds the transmitter with nominal probability ``level``.

    ``kind`` ``HPD``: the HPD set of posterior mass ``mass`` (the level recalibrated on the
    benchmark), its density threshold ``density`` (per m^2).  ``kind`` ``CIRCLE``: the circle of
    ``radius_m`` around the estimate, ``calibrated_on`` naming the flights it was calibrated on,
    ``clipped_to`` the area it was clipped to (then ``polygons`` and ``area_m2`` are the clipped
    region's, ``radius_m`` and ``ellipse`` the circle's).  ``polygons``: closed outlines in the
    log's ENU frame (m)."""

    level: float
    mass: float
    area_m2: float
    ellipse: Ellipse
    polygons: tuple[Polygon, ...] = ()
    kind: str = HPD
    density: float | None = None
    radius_m: float | None = None
    calibrated_on: str | None = None
    clipped_to: str | None = None

    def __post_init__(self) -> None:
        if self.kind not in (HPD, CIRCLE):
            raise ValueError(f"region kind must be {HPD!r} or {CIRCLE!r}, got {self.kind!r}")
        if (self.kind == CIRCLE) != (self.radius_m is not None):
            raise ValueError("an error circle, and only one, has a radius")

    @property
    def is_circle(self) -> bool:
        return self.kind == CIRCLE

    def to_dict(self) -> dict[str, Any]:
        """The ``--json`` layout (``mission.localize.uncertainty``), keys in their historic
        order."""
        d: dict[str, Any] = {"level": self.level, "hpd_mass": self.mass}
        if self.is_circle:
            d.update(kind=CIRCLE, radius_m=self.radius_m)
        d["area_m2"] = self.area_m2
        if not self.is_circle:
            d["density"] = self.density
        d["ellipse"] = self.ellipse.to_dict()
        d["polygons"] = [[list(v) for v in p] for p in self.polygons]
        if self.is_circle:
            d["calibrated_on"] = self.calibrated_on
            if self.clipped_to is not None:
                d["clipped_to"] = self.clipped_to
        return d

    @classmethod
    def from_dict(cls, d: Any, source: str | None = None, key: str = "regions") -> Region:
        """A region read back from ``--json`` output; ``InputError`` naming ``source`` and the
        dotted field (``key``) for a missing, unknown or malformed value."""
        f = Fields(d, source, key, shape="a region (a JSON object)")
        kind = f.str_("kind", HPD, choices=(HPD, CIRCLE))
        circle = kind == CIRCLE
        reg = cls(
            level=f.num("level", REQUIRED, lo=0.0, hi=1.0, strict_lo=True),
            mass=f.num("hpd_mass", REQUIRED, lo=0.0, hi=1.0, strict_lo=True),
            area_m2=f.num("area_m2", REQUIRED, lo=0.0),
            ellipse=Ellipse.from_fields(f.sub("ellipse", REQUIRED)),
            polygons=_polygons(f),
            kind=kind,
            density=None if circle else f.num("density", REQUIRED, lo=0.0),
            radius_m=f.num("radius_m", REQUIRED, lo=0.0, strict_lo=True) if circle else None,
            calibrated_on=f.str_("calibrated_on", REQUIRED) if circle else None,
            clipped_to=f.str_("clipped_to", None) if circle else None,
        )
        f.done()
        return reg

    def describe(self, short: bool = False) -> str:
        """One line: an error circle's radius or an HPD set's area and ellipse; ``short`` leaves
        out where the circle was calibrated and where the ellipse lies."""
        el = self.ellipse
        if self.is_circle:
            clipped = (
                f"; clipped to the {self.clipped_to}: {self.area_m2:.0f} m^2"
                if self.clipped_to is not None
                else ""
            )
            return f"within {self.radius_m:.0f} m of the estimate" + (
                ""
                if short
                else f" (error circle; calibrated on {self.calibrated_on or 'the card'}{clipped})"
            )
        if short:
            return f"{self.area_m2:.0f} m^2 (ellipse {el.a_m:.0f} x {el.b_m:.0f} m)"
        return (
            f"{self.area_m2:.0f} m^2; ellipse centre {el.x_m:.1f}, {el.y_m:.1f} m, semi-axes "
            f"{el.a_m:.0f} x {el.b_m:.0f} m at {el.angle_deg:.0f} deg from east"
        )


def widest(regions: Iterable[Region]) -> Region | None:
    """The region of the highest level (None for none)."""
    return max(regions, key=lambda r: r.level, default=None)


def _polygons(f: Fields) -> tuple[Polygon, ...]:
    """``polygons``: a list of outlines, each a list of [x, y] pairs of finite numbers."""
    raw = f.raw("polygons", REQUIRED)
    ok = isinstance(raw, list) and all(
        isinstance(p, list)
        and all(isinstance(v, list) and len(v) == 2 and all(map(is_number, v)) for v in p)
        for p in raw
    )
    if not ok:
        raise f.err("polygons", "expected a list of outlines, each a list of [x, y] numbers")
    return tuple(tuple((v[0], v[1]) for v in p) for p in raw)

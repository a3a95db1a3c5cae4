"""Trajectory generators: waypoint patterns over the mission field, all inside the flight area.

Every generator has the signature ``gen(field, altitude_m, **params) -> (K, 3)`` ENU waypoints at
``altitude_m`` (take-off, transit and landing are added by ``MissionSpec.flight_path_enu``).  The
default region is the *overlap* of the flight area and the rover area: the UAV may only fly in the
flight area and the transmitter is only in the rover area, so (as in the paper, which drops the
lower half of the AFAR flight area) flying outside the overlap collects little useful RSS.
``margin_m`` keeps the pattern that far inside the region's boundary; spacings are upper bounds
(legs are spread evenly so that every point of the region is within half a spacing of the path).

The patterns exist so that generalisation across trajectories can be measured as in the paper's
Fig. "Generalization performance across UAV trajectories".
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Callable

import numpy as np

from mission.errors import InputError
from mission.fields import Fields
from mission.geo import Area, Field, clip_polygon, polygon_area_m2

Generator = Callable[..., np.ndarray]


# ----------------------------------------------------------------------------------------------
# regions


def overlap_area(field: Field) -> Area:
    """The overlap of the rover area with the flight area (its largest part where non-convex areas
    leave several)."""
    parts = clip_polygon(field.rover_area.vertices, field.flight_area.vertices)
    if not parts:
        raise InputError("the rover area and the flight area do not overlap", field="rover_area")
    return Area("overlap", max(parts, key=polygon_area_m2))


def region_area(field: Field, region: str) -> Area:
    """The area a pattern covers: ``overlap`` (default), ``flight`` (whole flight area) or
    ``rover``.

    ``rover`` is clipped to the flight area as well, since the UAV may not leave it.
    """
    if region == "overlap" or region == "rover":
        return overlap_area(field)
    if region == "flight":
        return field.flight_area
    raise InputError(
        f"unknown region '{region}' (expected overlap, flight or rover)", field="region"
    )


def _box(area: Area, margin_m: float) -> tuple[float, float, float, float]:
    """Axis-aligned bounding box of ``area`` shrunk by ``margin_m`` on each side."""
    x0, y0, x1, y1 = area.bounds
    x0, y0, x1, y1 = x0 + margin_m, y0 + margin_m, x1 - margin_m, y1 - margin_m
    for _ in range(8):  # a geodetic "box" is not exactly axis-aligned in ENU: shrink until it fits
        if x1 <= x0 or y1 <= y0:
            break
        s = np.linspace(0.0, 1.0, 64)[:, None]
        c = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])
        ring = (c[:, None] + s[None] * (np.roll(c, -1, 0) - c)[:, None]).reshape(-1, 2)
        short = margin_m - float(np.min(area.signed_distance(ring)))
        if short <= 0:
            break
        x0, y0, x1, y1 = x0 + short + 1e-7, y0 + short + 1e-7, x1 - short - 1e-7, y1 - short - 1e-7
    if x1 <= x0 or y1 <= y0:
        raise InputError(f"margin {margin_m} m leaves nothing of the {area.name}", field="margin_m")
    return x0, y0, x1, y1


def _lines(lo: float, hi: float, spacing_m: float) -> np.ndarray:
    """Evenly spread positions from ``lo`` to ``hi`` inclusive, no more than ``spacing_m`` apart."""
    n = max(int(math.ceil((hi - lo) / spacing_m - 1e-9)), 1)
    return np.linspace(lo, hi, n + 1)


def _chord(area: Area, margin_m: float, y: float, horizontal: bool = True, step: float = 0.25):
    """Extent (lo, hi) of the line ``y = const`` (or ``x = const``) inside ``area`` with
    ``margin_m``."""
    x0, y0, x1, y1 = area.bounds
    lo, hi = (x0, x1) if horizontal else (y0, y1)
    s = np.arange(lo, hi + step, step)
    pts = (
        np.stack([s, np.full_like(s, y)], -1)
        if horizontal
        else np.stack([np.full_like(s, y), s], -1)
    )
    ok = area.contains(pts, max(margin_m - 1e-6, 0.0))
    if not ok.any():
        return None
    return float(s[ok].min()), float(s[ok].max())


def _check_positive(**kw: float) -> None:
    f = Fields(kw)
    for k in kw:
        f.num(k, lo=0.0, strict_lo=True)


def _at(xy: np.ndarray, altitude_m: float) -> np.ndarray:
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    keep = np.concatenate([[True], np.linalg.norm(np.diff(xy, axis=0), axis=1) > 1e-6])
    xy = xy[keep]
    return np.column_stack([xy, np.full(len(xy), float(altitude_m))])


# -------------------------------------------------------------------------------------------
# patterns


def coverage_radius(spacing_m: float) -> float:
    """Largest distance from a point of the covered box to a rectangular spiral with this ring
    spacing.

    Outside an inner ring's corner the nearest path is either the outer ring's legs or that corner:
    max over u of min(u, sqrt(2) (s - u)) = sqrt(2) s / (1 + sqrt(2)).
    """
    return spacing_m * math.sqrt(2) / (1 + math.sqrt(2))


def spiral(
    field: Field,
    altitude_m: float,
    spacing_m: float = 22.0,
    margin_m: float = 5.0,
    region: str = "overlap",
    start: str = "se",
) -> np.ndarray:
    """The paper's fixed rectangular spiral, inward from the outer ring over the region's bounding
    box.

    Rows (east-west legs) and columns (north-south legs) are spread evenly between the box inset by
    ``margin_m``, at most ``spacing_m`` apart; the spiral takes the outermost unflown row or column
    in turn (bottom, left, top, right, ...), so neighbouring parallel legs are at most one spacing
    apart. Coverage: every point of the box lies within ``spacing_m / 2`` of the path except in
    small triangles on the outside of each inner ring corner (about 1 % of the area), where the
    bound is ``coverage_radius(spacing_m) = spacing_m * sqrt(2) / (1 + sqrt(2))`` (0.59 spacing),
    provided ``margin_m <= coverage_radius / sqrt(2)``.  ``start`` is the outer-ring corner it
    starts from (``se``, nearest the AFAR launch point, runs clockwise; the other corners are its
    mirror images).
    """
    _check_positive(spacing_m=spacing_m)
    if margin_m < 0:
        raise InputError(f"must be >= 0, got {margin_m}", field="margin_m")
    x0, y0, x1, y1 = _box(region_area(field, region), margin_m)
    xs, ys = _lines(x0, x1, spacing_m), _lines(y0, y1, spacing_m)
    if start not in ("se", "sw", "ne", "nw"):
        raise InputError(f"unknown start corner '{start}' (se, sw, ne, nw)", field="start")
    # Build for start = "se" (west along the bottom, north, east along the top, south, ...), then
    # mirror.
    flip_x, flip_y = start[1] == "w", start[0] == "n"
    if flip_x:
        xs = (x0 + x1) - xs[::-1]
    if flip_y:
        ys = (y0 + y1) - ys[::-1]
    b, t, lft, r = 0, len(ys) - 1, 0, len(xs) - 1
    pts = [(xs[r], ys[b])]
    while True:
        if lft > r:
            break
        pts.append((xs[lft], ys[b]))  # west along the bottom row
        b += 1
        if b > t:
            break
        pts.append((xs[lft], ys[t]))  # north along the left column
        lft += 1
        if lft > r:
            break
        pts.append((xs[r], ys[t]))  # east along the top row
        t -= 1
        if b > t:
            break
        pts.append((xs[r], ys[b]))  # south along the right column
        r -= 1
    xy = np.array(pts)
    if flip_x:
        xy[:, 0] = (x0 + x1) - xy[:, 0]
    if flip_y:
        xy[:, 1] = (y0 + y1) - xy[:, 1]
    return _at(xy, altitude_m)


def lawnmower(
    field: Field,
    altitude_m: float,
    spacing_m: float = 22.0,
    margin_m: float = 5.0,
    region: str = "overlap",
    direction: str = "ew",
) -> np.ndarray:
    """Boustrophedon: parallel legs (``ew`` east-west rows or ``ns`` north-south columns), clipped
    to the region with ``margin_m`` (any convex region), starting from the south (or east) side."""
    _check_positive(spacing_m=spacing_m)
    area = region_area(field, region)
    x0, y0, x1, y1 = _box(area, margin_m)
    if direction not in ("ew", "ns"):
        raise InputError(f"unknown direction '{direction}' (ew or ns)", field="direction")
    horizontal = direction == "ew"
    pos = _lines(y0, y1, spacing_m) if horizontal else _lines(x0, x1, spacing_m)[::-1]
    pts = []
    for i, p in enumerate(pos):
        ext = _chord(area, margin_m, p, horizontal)
        if ext is None:
            continue
        a, b = (ext[1], ext[0]) if i % 2 == 0 else ext  # first leg runs west (or south)
        pts += [(a, p), (b, p)] if horizontal else [(p, b), (p, a)]
    return _at(np.array(pts), altitude_m)


def edge_sweep(
    field: Field,
    altitude_m: float,
    spacing_m: float = 22.0,
    margin_m: float = 5.0,
    region: str = "overlap",
) -> np.ndarray:
    """The bottom edge (east to west) and the left edge (south to north) first, as one AFAR team
    flew, then north-south columns inward from the left edge to the right edge."""
    _check_positive(spacing_m=spacing_m)
    x0, y0, x1, y1 = _box(region_area(field, region), margin_m)
    pts = [(x1, y0), (x0, y0), (x0, y1)]
    xs = _lines(x0, x1, spacing_m)[1:]
    ys_lo = _lines(y0, y1, spacing_m)[1]  # the bottom edge already covers the lowest row
    for i, x in enumerate(xs):
        lo = ys_lo if x < x1 else y0
        pts += [(x, y1), (x, lo)] if i % 2 == 0 else [(x, lo), (x, y1)]
    return _at(np.array(pts), altitude_m)


def expanding_square(
    field: Field,
    altitude_m: float,
    spacing_m: float = 22.0,
    margin_m: float = 5.0,
    region: str = "overlap",
    center: tuple[float, float] | None = None,
) -> np.ndarray:
    """Search-and-rescue expanding square from ``center`` (default: the region's box centre): legs
    of 1, 1, 2, 2, 3, 3, ... spacings turning clockwise, until a leg would leave the box; that last
    leg is cut at the box edge."""
    _check_positive(spacing_m=spacing_m)
    x0, y0, x1, y1 = _box(region_area(field, region), margin_m)
    c = np.array(center if center is not None else ((x0 + x1) / 2, (y0 + y1) / 2), dtype=float)
    if c.shape != (2,) or not (x0 <= c[0] <= x1 and y0 <= c[1] <= y1):
        raise InputError(
            f"center {center} must be an (x, y) inside the region with the margin", field="center"
        )
    dirs = np.array([[0, 1], [1, 0], [0, -1], [-1, 0]], dtype=float)  # N, E, S, W: clockwise
    pts, p, k = [c.copy()], c.copy(), 0
    while True:
        d = dirs[k % 4]
        q = p + d * spacing_m * (k // 2 + 1)
        qc = np.clip(q, [x0, y0], [x1, y1])
        pts.append(qc)
        if not np.allclose(q, qc):
            break
        p, k = q, k + 1
    return _at(np.array(pts), altitude_m)


def random_waypoints(
    field: Field,
    altitude_m: float,
    n: int = 14,
    seed: int = 0,
    margin_m: float = 5.0,
    region: str = "overlap",
    order: str = "nearest",
) -> np.ndarray:
    """``n`` waypoints drawn uniformly in the region with ``margin_m`` (seeded: same seed, same
    path), visited in draw order (``order: random``) or greedily nearest-first from the south-east
    corner (``nearest``, shorter).  Legs leaving a non-convex region are redrawn."""
    Fields({"n": n}).int_("n", lo=1)
    if order not in ("nearest", "random"):
        raise InputError(f"unknown order '{order}' (nearest or random)", field="order")
    area = region_area(field, region)
    x0, y0, x1, y1 = _box(area, margin_m)
    rng = np.random.default_rng(seed)
    pts: list[np.ndarray] = []
    tries = 0
    while len(pts) < n:
        tries += 1
        if tries > 1000 * n:
            raise InputError(f"could not place {n} waypoints in the {area.name}", field="n")
        q = rng.uniform([x0, y0], [x1, y1])
        if not area.contains(q, margin_m):
            continue
        if pts and order == "random" and not _leg_inside(area, pts[-1], q, margin_m):
            continue
        pts.append(q)
    xy = np.array(pts)
    if order == "nearest":
        cur, rest, out = np.array([x1, y0]), list(range(n)), []
        while rest:
            j = min(rest, key=lambda i: float(np.linalg.norm(xy[i] - cur)))
            out.append(j)
            rest.remove(j)
            cur = xy[j]
        xy = xy[out]
    return _at(xy, altitude_m)


def _leg_inside(area: Area, a, b, margin_m: float) -> bool:
    n = max(int(np.linalg.norm(np.subtract(b, a)) / 0.5), 2)
    s = np.linspace(0, 1, n)[:, None]
    return bool(area.contains(np.asarray(a) + s * (np.asarray(b) - np.asarray(a)), margin_m).all())


GENERATORS: dict[str, Generator] = {
    "spiral": spiral,
    "lawnmower": lawnmower,
    "edge_sweep": edge_sweep,
    "expanding_square": expanding_square,
    "random_waypoints": random_waypoints,
}


def trajectory_params(name: str, rng: np.random.Generator, base: dict, random_params: bool) -> dict:
    """Generator parameters: the mission's own ones (same generator) or a random draw (datasets and
    the unseen-flight benchmark draw them here)."""
    if not random_params:
        return dict(base)
    p: dict = {
        "spacing_m": float(rng.uniform(16.0, 32.0)),
        "margin_m": float(rng.uniform(3.0, 10.0)),
    }
    if name == "spiral":
        p["start"] = ("se", "sw", "ne", "nw")[int(rng.integers(4))]
    elif name == "lawnmower":
        p["direction"] = ("ew", "ns")[int(rng.integers(2))]
    elif name == "random_waypoints":
        p = {
            "n": int(rng.integers(8, 25)),
            "seed": int(rng.integers(2**31)),
            "margin_m": p["margin_m"],
        }
    elif name == "expanding_square":
        p["spacing_m"] = float(rng.uniform(20.0, 35.0))
    return p


def generate(name: str, field: Field, altitude_m: float, **params) -> np.ndarray:
    """Run generator ``name``; unknown names and parameters become an ``InputError``."""
    gen = GENERATORS.get(name)
    if gen is None:
        raise InputError(
            f"unknown generator '{name}' (expected one of {', '.join(GENERATORS)})",
            field="generator",
        )

    allowed = set(inspect.signature(gen).parameters) - {"field", "altitude_m"}
    for k in params:
        if k not in allowed:
            raise InputError(
                f"unknown parameter '{k}' of generator '{name}' (expected one of "
                f"{', '.join(sorted(allowed))})",
                field=k,
            )
    try:
        return gen(field, altitude_m, **params)
    except TypeError as e:  # e.g. a string where a number belongs
        raise InputError(f"bad parameter for generator '{name}': {e}") from None

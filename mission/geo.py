"""Geodesy and mission areas: WGS84 <-> local ENU about a mission origin, and polygon areas
(shapely).

The local frame is ENU metres about the mission origin (SPEC section 1): x east, y north, z up above
the origin's ground.  The conversion is delegated to ``pymap3d`` rather than hand-rolled
trigonometry.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pymap3d
import shapely

from mission.errors import InputError


@dataclass(frozen=True)
class Origin:
    """Mission origin: WGS84 latitude/longitude in degrees and ground altitude in metres AMSL."""

    lat_deg: float
    lon_deg: float
    alt_m: float = 0.0

    def to_enu(self, lat_deg, lon_deg, alt_m=None) -> np.ndarray:
        """Geodetic -> local ENU (..., 3) in metres; ``alt_m`` is AMSL (defaults to the origin's
        ground)."""
        lat = np.asarray(lat_deg, dtype=float)
        lon = np.asarray(lon_deg, dtype=float)
        alt = np.full_like(lat, self.alt_m) if alt_m is None else np.asarray(alt_m, dtype=float)
        e, n, u = pymap3d.geodetic2enu(lat, lon, alt, self.lat_deg, self.lon_deg, self.alt_m)
        return np.stack(np.broadcast_arrays(e, n, u), axis=-1)

    def to_geodetic(self, enu) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Local ENU (..., 3) -> (lat_deg, lon_deg, alt_m AMSL)."""
        enu = np.asarray(enu, dtype=float)
        lat, lon, alt = pymap3d.enu2geodetic(
            enu[..., 0], enu[..., 1], enu[..., 2], self.lat_deg, self.lon_deg, self.alt_m
        )
        return np.asarray(lat), np.asarray(lon), np.asarray(alt)

    def to_dict(self) -> dict:
        return {"lat_deg": self.lat_deg, "lon_deg": self.lon_deg, "alt_m": self.alt_m}

    @classmethod
    def from_dict(cls, d: dict) -> Origin:
        return cls(float(d["lat_deg"]), float(d["lon_deg"]), float(d.get("alt_m", 0.0)))


@dataclass(frozen=True)
class Area:
    """A named polygon in the local ENU plane (vertices (K, 2), metres), e.g. the flight or rover
    area."""

    name: str
    vertices: np.ndarray
    _polygon: shapely.Polygon = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        v = np.asarray(self.vertices, dtype=float)
        if v.ndim != 2 or v.shape[1] != 2 or len(v) < 3:
            raise InputError(
                f"area '{self.name}' needs at least 3 (x, y) vertices, got shape {v.shape}"
            )
        object.__setattr__(self, "vertices", v)
        poly = shapely.Polygon(v)
        shapely.prepare(poly)
        # derived from the vertices once, in construction
        object.__setattr__(self, "_polygon", poly)

    @classmethod
    def from_geodetic(cls, name: str, lat_lon: np.ndarray, origin: Origin) -> Area:
        """Build from (K, 2) latitude/longitude vertices, projected about ``origin``."""
        ll = np.asarray(lat_lon, dtype=float)
        return cls(name, origin.to_enu(ll[:, 0], ll[:, 1])[:, :2])

    @classmethod
    def from_box(cls, name: str, box: dict, origin: Origin) -> Area:
        """Build from a lat/lon box ``{lat_min, lat_max, lon_min, lon_max}`` (the AFAR geometry
        format)."""
        ll = np.array(
            [
                [box["lat_min"], box["lon_min"]],
                [box["lat_min"], box["lon_max"]],
                [box["lat_max"], box["lon_max"]],
                [box["lat_max"], box["lon_min"]],
            ]
        )
        return cls.from_geodetic(name, ll, origin)

    @property
    def polygon(self) -> shapely.Polygon:
        """The area as a (prepared) shapely polygon: what its geometric queries run on."""
        return self._polygon

    def contains(self, xy, margin_m: float = 0.0) -> np.ndarray:
        """True where points (..., 2) lie inside the polygon (its boundary excluded) and at least
        ``margin_m`` from its edges."""
        p = np.asarray(xy, dtype=float)[..., :2]
        inside = shapely.contains_xy(self._polygon, p[..., 0], p[..., 1])
        if margin_m > 0:
            inside &= self.edge_distance(p) >= margin_m
        return inside

    def edge_distance(self, xy) -> np.ndarray:
        """Distance (m) from points (..., 2) to the nearest polygon edge (unsigned)."""
        p = np.asarray(xy, dtype=float)[..., :2]
        return shapely.distance(self._polygon.exterior, shapely.points(p))

    def signed_distance(self, xy) -> np.ndarray:
        """Distance to the boundary, positive inside and negative outside (m)."""
        d = self.edge_distance(xy)
        return np.where(self.contains(xy), d, -d)

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """(xmin, ymin, xmax, ymax) in metres."""
        v = self.vertices
        return (
            float(v[:, 0].min()),
            float(v[:, 1].min()),
            float(v[:, 0].max()),
            float(v[:, 1].max()),
        )

    def sample_uniform(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """``n`` points drawn uniformly inside the polygon (rejection sampling on its bounding
        box)."""
        xmin, ymin, xmax, ymax = self.bounds
        out = np.empty((0, 2))
        while len(out) < n:
            cand = rng.uniform([xmin, ymin], [xmax, ymax], size=(max(2 * (n - len(out)), 16), 2))
            out = np.vstack([out, cand[self.contains(cand)]])
        return out[:n]


def square_grid(bounds, step_m: float, centred: bool = False) -> np.ndarray:
    """Points (ny, nx, 2) of a square grid with spacing ``step_m`` over the box (xmin, ymin, xmax,
    ymax): from the corner up to the far edge included (the localizers' candidate transmitters), or
    with ``centred`` the centres of the ``step_m`` cells inside the box (area coverage).  Rows run
    along y, columns along x (``np.meshgrid``)."""
    x0, y0, x1, y1 = bounds
    if centred:
        xs, ys = np.arange(x0 + step_m / 2, x1, step_m), np.arange(y0 + step_m / 2, y1, step_m)
    else:
        xs, ys = np.arange(x0, x1 + 1e-9, step_m), np.arange(y0, y1 + 1e-9, step_m)
    return np.stack(np.meshgrid(xs, ys), axis=-1)


def clip_polygon(subject: np.ndarray, clip: np.ndarray) -> list[np.ndarray]:
    """The parts of polygon ``subject`` inside polygon ``clip`` ((K, 2) each, either may be
    non-convex): a list of (M, 2) rings, counter-clockwise, without the closing vertex; empty when
    they do not overlap."""
    inter = shapely.intersection(
        *(shapely.make_valid(shapely.Polygon(np.asarray(v, dtype=float))) for v in (subject, clip))
    )
    parts = [g for g in shapely.get_parts(inter) if isinstance(g, shapely.Polygon) and g.area > 0]
    return [np.asarray(shapely.orient_polygons(g).exterior.coords, dtype=float)[:-1] for g in parts]


def polygon_area_m2(v: np.ndarray) -> float:
    """Area (m^2) of the polygon (K, 2)."""
    return float(shapely.area(shapely.Polygon(np.asarray(v, dtype=float))))


@dataclass(frozen=True)
class Field:
    """A mission field: origin, flight area (the UAV must stay inside) and rover area (the
    transmitter)."""

    origin: Origin
    flight_area: Area
    rover_area: Area
    name: str = "field"
    takeoff_home: tuple[float, float] | None = None  # lat, lon


MAX_FLIGHT_KM = (
    200.0  # a sample farther than this from its mission origin is not a position in degrees
)


def latlon_unit_problem(lat, lon, origin: Origin | None) -> tuple[int, str] | None:
    """Index and reason of the first lat/lon sample that cannot be a flight position in degrees, or
    None.

    Why: radians pass the +-90/+-180 range check and then give NaN fits or estimates thousands of km
    away. With an origin, any sample more than ``MAX_FLIGHT_KM`` from it is wrong; without one, a
    whole track within +-pi/2, +-pi is taken for radians (a flight near 0 N 0 E needs a sidecar with
    its origin).
    """
    lat, lon = np.asarray(lat, dtype=float), np.asarray(lon, dtype=float)
    if lat.size == 0:
        return None
    radians = bool(np.all(np.abs(lat) <= np.pi / 2) and np.all(np.abs(lon) <= np.pi))
    hint = (
        f" (radians? in degrees that is {np.degrees(lat[0]):.5f}, {np.degrees(lon[0]):.5f})"
        if radians
        else " (wrong units?)"
    )
    if origin is None:
        return (0, f"the whole track lies within +-pi/2, +-pi{hint}") if radians else None
    dlat = np.radians(lat - origin.lat_deg)
    dlon = np.radians((lon - origin.lon_deg + 180.0) % 360.0 - 180.0) * np.cos(
        np.radians(origin.lat_deg)
    )
    km = 6371.0 * np.hypot(dlat, dlon)
    far = np.flatnonzero(km > MAX_FLIGHT_KM)
    if not far.size:
        return None
    i = int(far[0])
    return i, (
        f"{lat[i]:g}, {lon[i]:g} is {km[i]:,.0f} km from the origin "
        f"{origin.lat_deg:.5f}, {origin.lon_deg:.5f}{hint}"
    )


AFAR_GEOMETRY = {
    "field": "AERPAW Lake Wheeler Road Field Labs, AFAR challenge (December 2023)",
    "source": "AFAR_Drone.kml / AFAR_Rover.kml of SunLab-UGA/AERPAW_AFAR (commit aeb1a793)",
    "flight_area": {
        "lat_min": 35.72688213193035,
        "lat_max": 35.72931030026633,
        "lon_min": -78.69953825817279,
        "lon_max": -78.69621514941473,
    },
    "rover_area": {
        "lat_min": 35.72774492720433,
        "lat_max": 35.7303079937812,
        "lon_min": -78.69980159100491,
        "lon_max": -78.69670002283071,
    },
    "takeoff_home": {"lat": 35.72737, "lon": -78.69622},
}


def afar_field(geometry: dict | str | Path | None = None, origin: Origin | None = None) -> Field:
    """The AFAR Lake Wheeler field (embedded copy of ``shared/afar_geometry.json``, or a given
    file).

    The default origin is the flight area's south-west corner at ground level (0 m AMSL nominal), so
    all of the field lies at positive x, y.
    """
    if geometry is None:
        g = AFAR_GEOMETRY
    elif isinstance(geometry, dict):
        g = geometry
    else:
        g = json.loads(Path(geometry).read_text())
    fa = g["flight_area"]
    origin = origin or Origin(fa["lat_min"], fa["lon_min"], 0.0)
    home = g.get("takeoff_home")
    return Field(
        origin,
        Area.from_box("flight area", fa, origin),
        Area.from_box("rover area", g["rover_area"], origin),
        name=g.get("field", "AFAR"),
        takeoff_home=(home["lat"], home["lon"]) if home else None,
    )

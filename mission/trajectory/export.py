"""Mission exports: QGroundControl ``.plan`` JSON, QGC WPL 110 text, GeoJSON and KML.

The ``.plan`` and ``.waypoints`` hold exactly the items ``fly-mission`` uploads
(``mission.trajectory.items``): take-off at home, the cruise speed, the trajectory as waypoints in
frame 3 (altitude relative to home), then return-to-launch (or a landing at the last waypoint); the
``.plan`` adds the planned home position, the flight area as an inclusion geofence and the cruise
speed, and QGroundControl opens it directly.  ``.waypoints`` (QGC WPL 110) starts with the home item
0 as an ArduPilot upload does, in the text format ArduPilot tools and pymavlink's ``MAVWPLoader``
read.  GeoJSON (lon, lat order) and KML (AERPAW's geofences are KML) carry the trajectory and both
areas."""

from __future__ import annotations

import json
from pathlib import Path
from xml.sax.saxutils import escape

import numpy as np

from mission.files import write_text
from mission.trajectory.items import RawItem, build_items, home_geodetic

FORMATS = ("plan", "wpl", "geojson", "kml")


def _ring_latlon(spec, area) -> list[list[float]]:
    v = area.vertices
    lat, lon, _ = spec.field.origin.to_geodetic(np.column_stack([v, np.zeros(len(v))]))
    return [[float(a), float(b)] for a, b in zip(lat, lon, strict=True)]


def _params7(it: RawItem) -> list[float | None]:
    """MISSION_ITEM's seven params: param1-4 (NaN, "unchanged", as JSON null), then lat, lon (deg),
    altitude."""
    p4 = [None if np.isnan(v) else float(v) for v in it.params]
    return p4 + ([it.lat_deg, it.lon_deg, float(it.z)] if it.has_position else [0.0, 0.0, 0.0])


def to_plan(spec) -> dict:
    """QGroundControl ``.plan`` (fileType Plan, version 1) as a dict: the uploaded items
    (``build_items``)."""
    items = []
    for i, it in enumerate(build_items(spec)):
        p = _params7(it)
        pos = (
            {"AMSLAltAboveTerrain": None, "Altitude": p[6], "AltitudeMode": 1}
            if it.has_position
            else {}
        )
        items.append(
            {
                **pos,
                "autoContinue": True,
                "command": it.command,
                "doJumpId": i + 1,
                "frame": it.frame,
                "params": p,
                "type": "SimpleItem",
            }
        )
    return {
        "fileType": "Plan",
        "version": 1,
        "groundStation": "QGroundControl",
        "geoFence": {
            "circles": [],
            "version": 2,
            "polygons": [
                {
                    "inclusion": True,
                    "version": 1,
                    "polygon": _ring_latlon(spec, spec.field.flight_area),
                }
            ],
        },
        "mission": {
            "version": 2,
            "firmwareType": 3,
            "vehicleType": 2,
            "globalPlanAltitudeMode": 1,
            "cruiseSpeed": spec.cruise_speed_mps,
            "hoverSpeed": spec.cruise_speed_mps,
            "plannedHomePosition": list(home_geodetic(spec)),
            "items": items,
        },
        "rallyPoints": {"points": [], "version": 2},
    }


def to_wpl(spec) -> str:
    """QGC WPL 110 text: the items an ArduPilot upload sends (home first, the only current item);
    lat/lon as the items' 1e-7 degrees, NaN params written as ``nan`` as pymavlink's ``MAVWPLoader``
    does."""
    lines = ["QGC WPL 110"]
    for seq, it in enumerate(build_items(spec, home_item=True)):
        p = [float("nan") if v is None else v for v in _params7(it)]
        lines.append(
            "\t".join(
                [
                    str(seq),
                    str(int(seq == 0)),
                    str(it.frame),
                    str(it.command),
                    *(f"{v:.8f}" for v in p[:4]),
                    f"{p[4]:.10f}",
                    f"{p[5]:.10f}",
                    f"{p[6]:.6f}",
                    "1",
                ]
            )
        )
    return "\n".join(lines) + "\n"


def _lonlat_line(spec) -> list[list[float]]:
    w = spec.waypoints_enu()
    lat, lon, _ = spec.field.origin.to_geodetic(np.column_stack([w[:, :2], np.zeros(len(w))]))
    return [[float(b), float(a), float(z)] for a, b, z in zip(lat, lon, w[:, 2], strict=True)]


def to_geojson(spec) -> dict:
    """GeoJSON FeatureCollection: the trajectory LineString (lon, lat, height), both areas, home."""
    feats = [
        {
            "type": "Feature",
            "properties": {
                "name": f"{spec.name} trajectory",
                "kind": "trajectory",
                "altitude_mode": "relative_to_home",
                "generator": spec.trajectory.generator,
            },
            "geometry": {"type": "LineString", "coordinates": _lonlat_line(spec)},
        }
    ]
    for area, kind in (
        (spec.field.flight_area, "flight_area"),
        (spec.field.rover_area, "rover_area"),
    ):
        ring = [[b, a] for a, b in _ring_latlon(spec, area)]
        feats.append(
            {
                "type": "Feature",
                "properties": {"name": area.name, "kind": kind},
                "geometry": {"type": "Polygon", "coordinates": [ring + [ring[0]]]},
            }
        )
    hlat, hlon, _ = home_geodetic(spec)
    feats.append(
        {
            "type": "Feature",
            "properties": {"name": "home", "kind": "home"},
            "geometry": {"type": "Point", "coordinates": [hlon, hlat]},
        }
    )
    return {"type": "FeatureCollection", "name": spec.name, "features": feats}


def to_kml(spec) -> str:
    """KML document: the trajectory (relativeToGround LineString), both areas as polygons, home."""

    def coords(pts) -> str:
        return " ".join(
            ",".join(f"{c:.9f}" if k < 2 else f"{c:.2f}" for k, c in enumerate(p)) for p in pts
        )

    def poly(area, colour: str) -> str:
        ring = [[b, a, 0.0] for a, b in _ring_latlon(spec, area)]
        return (
            f"<Placemark><name>{escape(area.name)}</name>"
            f"<Style><LineStyle><color>ff{colour}</color>"
            f"<width>2</width></LineStyle><PolyStyle><color>40{colour}</color></PolyStyle></Style>"
            f"<Polygon><outerBoundaryIs><LinearRing><coordinates>{coords(ring + [ring[0]])}"
            f"</coordinates></LinearRing></outerBoundaryIs></Polygon></Placemark>"
        )

    hlat, hlon, _ = home_geodetic(spec)
    body = [
        f"<Placemark><name>{escape(spec.name)} "
        "trajectory</name><Style><LineStyle><color>ff0000ff</color>"
        f"<width>3</width></LineStyle></Style><LineString><tessellate>1</tessellate>"
        f"<altitudeMode>relativeToGround</altitudeMode><coordinates>{coords(_lonlat_line(spec))}"
        f"</coordinates></LineString></Placemark>",
        poly(spec.field.flight_area, "ff7f1f"),  # KML colours are aabbggrr: blue
        poly(spec.field.rover_area, "2ca02c"),  # green
        f"<Placemark><name>home</name><Point>"
        f"<coordinates>{hlon:.9f},{hlat:.9f},0</coordinates></Point>"
        f"</Placemark>",
    ]
    return (
        '<?xml version="1.0" encoding="UTF-8"?>\n<kml '
        'xmlns="http://www.opengis.net/kml/2.2"><Document>'
        f"<name>{escape(spec.name)}</name>\n" + "\n".join(body) + "\n</Document></kml>\n"
    )


def export_mission(spec, fmt: str, out: str | Path) -> Path:
    """Write ``spec`` in format ``fmt`` (plan, wpl, geojson, kml) to ``out``."""
    out = Path(out)
    if fmt == "plan":
        text = json.dumps(to_plan(spec), indent=2)
    elif fmt == "wpl":
        text = to_wpl(spec)
    elif fmt == "geojson":
        text = json.dumps(to_geojson(spec), indent=2)
    elif fmt == "kml":
        text = to_kml(spec)
    else:
        raise ValueError(f"unknown export format {fmt!r}")

    return write_text(out, text)  # whole or not at all; an OS error is one line naming the file

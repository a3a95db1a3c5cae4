"""Mission exports: QGroundControl ``.plan`` JSON, QGC WPL 110 text, GeoJSON and KML.

The ``.plan`` holds a take-off at home, the trajectory as waypoints in frame 3 (global, altitude relative
to home), then return-to-launch (or a landing at the last waypoint), the planned home position, the flight
area as an inclusion geofence and the cruise speed; QGroundControl opens it directly.  ``.waypoints``
(QGC WPL 110) is the same item list in the text format ArduPilot tools and pymavlink's ``MAVWPLoader``
read.  GeoJSON (lon, lat order) and KML (AERPAW's geofences are KML) carry the trajectory and both areas.
"""

from __future__ import annotations

import json
from pathlib import Path
from xml.sax.saxutils import escape

import numpy as np

from mission.errors import InputError

MAV_CMD_NAV_WAYPOINT = 16
MAV_CMD_NAV_RETURN_TO_LAUNCH = 20
MAV_CMD_NAV_LAND = 21
MAV_CMD_NAV_TAKEOFF = 22
MAV_FRAME_GLOBAL = 0
MAV_FRAME_MISSION = 2
MAV_FRAME_GLOBAL_RELATIVE_ALT = 3
FORMATS = ("plan", "wpl", "geojson", "kml")


def mission_items(spec) -> list[dict]:
    """The mission as MAVLink items: dicts of command, frame and 7 params (params[4:7] = lat, lon, alt)."""
    o = spec.field.origin
    w = spec.waypoints_enu()
    lat, lon, _ = o.to_geodetic(np.column_stack([w[:, :2], np.zeros(len(w))]))
    home = np.asarray(spec.home_enu, dtype=float)
    hlat, hlon, _ = o.to_geodetic(home)
    rel = w[:, 2] - home[2]
    items = [{"command": MAV_CMD_NAV_TAKEOFF, "frame": MAV_FRAME_GLOBAL_RELATIVE_ALT,
              "params": [0.0, 0.0, 0.0, None, float(hlat), float(hlon), float(rel[0])]}]
    for i in range(len(w)):
        items.append({"command": MAV_CMD_NAV_WAYPOINT, "frame": MAV_FRAME_GLOBAL_RELATIVE_ALT,
                      "params": [0.0, 0.0, 0.0, None, float(lat[i]), float(lon[i]), float(rel[i])]})
    if spec.return_behaviour == "land":
        items.append({"command": MAV_CMD_NAV_LAND, "frame": MAV_FRAME_GLOBAL_RELATIVE_ALT,
                      "params": [0.0, 0.0, 0.0, None, float(lat[-1]), float(lon[-1]), 0.0]})
    else:
        items.append({"command": MAV_CMD_NAV_RETURN_TO_LAUNCH, "frame": MAV_FRAME_MISSION,
                      "params": [0.0] * 7})
    return items


def _home_geodetic(spec) -> tuple[float, float, float]:
    lat, lon, alt = spec.field.origin.to_geodetic(np.asarray(spec.home_enu, dtype=float))
    return float(lat), float(lon), float(alt)


def _ring_latlon(spec, area) -> list[list[float]]:
    v = area.vertices
    lat, lon, _ = spec.field.origin.to_geodetic(np.column_stack([v, np.zeros(len(v))]))
    return [[float(a), float(b)] for a, b in zip(lat, lon, strict=True)]


def to_plan(spec) -> dict:
    """QGroundControl ``.plan`` (fileType Plan, version 1) as a dict."""
    items = []
    for i, it in enumerate(mission_items(spec)):
        p = it["params"]
        items.append({"AMSLAltAboveTerrain": None, "Altitude": p[6], "AltitudeMode": 1, "autoContinue": True,
                      "command": it["command"], "doJumpId": i + 1, "frame": it["frame"], "params": p,
                      "type": "SimpleItem"})
    return {
        "fileType": "Plan", "version": 1, "groundStation": "QGroundControl",
        "geoFence": {"circles": [], "version": 2, "polygons": [
            {"inclusion": True, "version": 1, "polygon": _ring_latlon(spec, spec.field.flight_area)}]},
        "mission": {"version": 2, "firmwareType": 3, "vehicleType": 2, "globalPlanAltitudeMode": 1,
                    "cruiseSpeed": spec.cruise_speed_mps, "hoverSpeed": spec.cruise_speed_mps,
                    "plannedHomePosition": list(_home_geodetic(spec)), "items": items},
        "rallyPoints": {"points": [], "version": 2},
    }


def to_wpl(spec) -> str:
    """QGC WPL 110 text: item 0 is home (absolute altitude), then the mission items; 8 decimals of degree."""
    hlat, hlon, halt = _home_geodetic(spec)
    rows = [(0, 1, MAV_FRAME_GLOBAL, MAV_CMD_NAV_WAYPOINT, [0, 0, 0, 0, hlat, hlon, halt])]
    for i, it in enumerate(mission_items(spec)):
        rows.append((i + 1, 0, it["frame"], it["command"], [0.0 if v is None else v for v in it["params"]]))
    lines = ["QGC WPL 110"]
    for seq, cur, frame, cmd, p in rows:
        lines.append("\t".join([str(seq), str(cur), str(frame), str(cmd), *(f"{v:.8f}" for v in p[:4]),
                                f"{p[4]:.10f}", f"{p[5]:.10f}", f"{p[6]:.6f}", "1"]))
    return "\n".join(lines) + "\n"


def _lonlat_line(spec) -> list[list[float]]:
    w = spec.waypoints_enu()
    lat, lon, _ = spec.field.origin.to_geodetic(np.column_stack([w[:, :2], np.zeros(len(w))]))
    return [[float(b), float(a), float(z)] for a, b, z in zip(lat, lon, w[:, 2], strict=True)]


def to_geojson(spec) -> dict:
    """GeoJSON FeatureCollection: the trajectory LineString (lon, lat, height), both areas, home."""
    feats = [{"type": "Feature", "properties": {"name": f"{spec.name} trajectory", "kind": "trajectory",
                                                "altitude_mode": "relative_to_home",
                                                "generator": spec.trajectory.generator},
              "geometry": {"type": "LineString", "coordinates": _lonlat_line(spec)}}]
    for area, kind in ((spec.field.flight_area, "flight_area"), (spec.field.rover_area, "rover_area")):
        ring = [[b, a] for a, b in _ring_latlon(spec, area)]
        feats.append({"type": "Feature", "properties": {"name": area.name, "kind": kind},
                      "geometry": {"type": "Polygon", "coordinates": [ring + [ring[0]]]}})
    hlat, hlon, _ = _home_geodetic(spec)
    feats.append({"type": "Feature", "properties": {"name": "home", "kind": "home"},
                  "geometry": {"type": "Point", "coordinates": [hlon, hlat]}})
    return {"type": "FeatureCollection", "name": spec.name, "features": feats}


def to_kml(spec) -> str:
    """KML document: the trajectory (relativeToGround LineString), both areas as polygons, home."""
    def coords(pts) -> str:
        return " ".join(",".join(f"{c:.9f}" if k < 2 else f"{c:.2f}" for k, c in enumerate(p)) for p in pts)

    def poly(area, colour: str) -> str:
        ring = [[b, a, 0.0] for a, b in _ring_latlon(spec, area)]
        return (f"<Placemark><name>{escape(area.name)}</name><Style><LineStyle><color>ff{colour}</color>"
                f"<width>2</width></LineStyle><PolyStyle><color>40{colour}</color></PolyStyle></Style>"
                f"<Polygon><outerBoundaryIs><LinearRing><coordinates>{coords(ring + [ring[0]])}"
                f"</coordinates></LinearRing></outerBoundaryIs></Polygon></Placemark>")

    hlat, hlon, _ = _home_geodetic(spec)
    body = [
        f"<Placemark><name>{escape(spec.name)} trajectory</name><Style><LineStyle><color>ff0000ff</color>"
        f"<width>3</width></LineStyle></Style><LineString><tessellate>1</tessellate>"
        f"<altitudeMode>relativeToGround</altitudeMode><coordinates>{coords(_lonlat_line(spec))}"
        f"</coordinates></LineString></Placemark>",
        poly(spec.field.flight_area, "ff7f1f"),   # KML colours are aabbggrr: blue
        poly(spec.field.rover_area, "2ca02c"),    # green
        f"<Placemark><name>home</name><Point><coordinates>{hlon:.9f},{hlat:.9f},0</coordinates></Point>"
        f"</Placemark>",
    ]
    return ('<?xml version="1.0" encoding="UTF-8"?>\n<kml xmlns="http://www.opengis.net/kml/2.2"><Document>'
            f"<name>{escape(spec.name)}</name>\n" + "\n".join(body) + "\n</Document></kml>\n")


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
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(text)
    except OSError as e:  # a parent that is a file, a read-only folder
        raise InputError(f"cannot write: {e.strerror or e}", source=str(out)) from None
    return out

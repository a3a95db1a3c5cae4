"""Exports: the .plan items round-trip through pymavlink's waypoint loader; GeoJSON, KML well formed."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from pymavlink import mavwp

from mission.cli.main import main
from mission.spec import load_mission

MISSIONS = Path(__file__).resolve().parents[1] / "missions"


@pytest.mark.parametrize("name", ["spiral", "waypoints"])
def test_plan_round_trips_through_mavwploader(tmp_path, name):
    mission = MISSIONS / f"{name}.yaml"
    plan_p, wpl_p = tmp_path / "m.plan", tmp_path / "m.waypoints"
    assert main(["export", str(mission), "--format", "plan", "--out", str(plan_p)]) == 0
    assert main(["export", str(mission), "--format", "wpl", "--out", str(wpl_p)]) == 0
    plan = json.loads(plan_p.read_text())
    assert plan["fileType"] == "Plan" and plan["version"] == 1
    m = plan["mission"]
    items = m["items"]
    spec = load_mission(mission)
    assert m["cruiseSpeed"] == spec.cruise_speed_mps
    assert [it["command"] for it in items] == [22] + [16] * len(spec.waypoints_enu()) + [20]
    assert all(it["type"] == "SimpleItem" and it["frame"] == 3 for it in items[:-1])
    fence = plan["geoFence"]["polygons"][0]
    assert fence["inclusion"] and len(fence["polygon"]) == 4

    loader = mavwp.MAVWPLoader()
    assert loader.load(str(wpl_p)) == len(items) + 1  # + home item 0
    home = loader.wp(0)
    assert (home.x, home.y) == pytest.approx(tuple(m["plannedHomePosition"][:2]), abs=1e-7)
    for i, it in enumerate(items):
        w = loader.wp(i + 1)
        assert (w.command, w.frame) == (it["command"], it["frame"])
        if it["command"] != 20:
            assert abs(w.x - it["params"][4]) < 1e-7 and abs(w.y - it["params"][5]) < 1e-7
            assert w.z == pytest.approx(it["params"][6], abs=1e-5)
    # and both agree with the mission's ENU waypoints
    wps = spec.waypoints_enu()
    lat, lon, _ = spec.field.origin.to_geodetic(np.column_stack([wps[:, :2], np.zeros(len(wps))]))
    got = np.array([[loader.wp(i + 2).x, loader.wp(i + 2).y] for i in range(len(wps))])
    assert np.max(np.abs(got - np.column_stack([lat, lon]))) < 1e-7
    assert np.allclose([loader.wp(i + 2).z for i in range(len(wps))], wps[:, 2], atol=1e-5)


def test_geojson(tmp_path):
    out = tmp_path / "m.geojson"
    assert main(["export", str(MISSIONS / "spiral.yaml"), "--format", "geojson", "--out", str(out)]) == 0
    fc = json.loads(out.read_text())
    kinds = {f["properties"]["kind"]: f["geometry"] for f in fc["features"]}
    assert fc["type"] == "FeatureCollection"
    assert kinds["trajectory"]["type"] == "LineString"
    lon, lat = kinds["trajectory"]["coordinates"][0][:2]
    assert -79 < lon < -78 and 35 < lat < 36  # lon, lat order
    ring = kinds["flight_area"]["coordinates"][0]
    assert kinds["flight_area"]["type"] == "Polygon" and ring[0] == ring[-1]


def test_kml(tmp_path):
    out = tmp_path / "m.kml"
    assert main(["export", str(MISSIONS / "edge_sweep.yaml"), "--out", str(out)]) == 0  # format from suffix
    root = ET.parse(out).getroot()
    ns = {"k": "http://www.opengis.net/kml/2.2"}
    marks = root.findall(".//k:Placemark", ns)
    assert len(marks) == 4
    ls = root.find(".//k:LineString", ns)
    assert ls.find("k:altitudeMode", ns).text == "relativeToGround"
    first = ls.find("k:coordinates", ns).text.split()[0].split(",")
    assert -79 < float(first[0]) < -78 and float(first[2]) == 30.0
    assert len(root.findall(".//k:Polygon", ns)) == 2

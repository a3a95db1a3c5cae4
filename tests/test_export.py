"""Exports: the .plan items round-trip through pymavlink's waypoint loader; GeoJSON, KML well
formed."""

from __future__ import annotations

import io
import json
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from pymavlink import mavwp
from pymavlink.dialects.v20 import common as mavlink2

from mission.cli.main import main
from mission.flight.plan import to_mavsdk
from mission.spec import load_mission
from mission.trajectory.items import build_items, home_geodetic
from sitl.mission_store import MissionStore

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
    assert [it["command"] for it in items] == [22, 178] + [16] * len(spec.waypoints_enu()) + [20]
    assert all(it["type"] == "SimpleItem" for it in items)
    assert [it["frame"] for it in items] == [3, 2] + [3] * len(spec.waypoints_enu()) + [2]
    assert items[1]["params"][1] == spec.cruise_speed_mps
    fence = plan["geoFence"]["polygons"][0]
    assert fence["inclusion"] and len(fence["polygon"]) == 4

    loader = mavwp.MAVWPLoader()
    assert loader.load(str(wpl_p)) == len(items) + 1  # + home item 0
    home = loader.wp(0)
    assert (home.x, home.y) == pytest.approx(tuple(m["plannedHomePosition"][:2]), abs=1e-7)
    for i, it in enumerate(items):
        w = loader.wp(i + 1)
        assert (w.command, w.frame) == (it["command"], it["frame"])
        if it["frame"] == 3:
            assert abs(w.x - it["params"][4]) < 1e-7 and abs(w.y - it["params"][5]) < 1e-7
            assert w.z == pytest.approx(it["params"][6], abs=1e-5)
    # and both agree with the mission's ENU waypoints
    wps = spec.waypoints_enu()
    lat, lon, _ = spec.field.origin.to_geodetic(np.column_stack([wps[:, :2], np.zeros(len(wps))]))
    got = np.array([[loader.wp(i + 3).x, loader.wp(i + 3).y] for i in range(len(wps))])
    assert np.max(np.abs(got - np.column_stack([lat, lon]))) < 1e-7
    assert np.allclose([loader.wp(i + 3).z for i in range(len(wps))], wps[:, 2], atol=1e-5)


def test_geojson(tmp_path):
    out = tmp_path / "m.geojson"
    assert (
        main(["export", str(MISSIONS / "spiral.yaml"), "--format", "geojson", "--out", str(out)])
        == 0
    )
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
    # format from suffix
    assert main(["export", str(MISSIONS / "edge_sweep.yaml"), "--out", str(out)]) == 0
    root = ET.parse(out).getroot()
    ns = {"k": "http://www.opengis.net/kml/2.2"}
    marks = root.findall(".//k:Placemark", ns)
    assert len(marks) == 4
    ls = root.find(".//k:LineString", ns)
    assert ls.find("k:altitudeMode", ns).text == "relativeToGround"
    first = ls.find("k:coordinates", ns).text.split()[0].split(",")
    assert -79 < float(first[0]) < -78 and float(first[2]) == 30.0
    assert len(root.findall(".//k:Polygon", ns)) == 2


class _Store(MissionStore):
    """sitl's mission store on a MAVLink encoder that writes nowhere: what the simulated vehicle
    keeps."""

    def __init__(self) -> None:
        self.mav = mavlink2.MAVLink(io.BytesIO(), srcSystem=1, srcComponent=1)
        self.items, self.current_seq, self._rx, self.uploads = [], 0, None, 0

    def log(self, msg: str) -> None:
        pass

    def send_mission_current(self) -> None:
        pass


def _uploaded_to_sitl(mavsdk_items) -> list:
    """Feed MAVSDK's upload items to sitl's mission store as the ground station's
    MISSION_ITEM_INTs."""
    gcs = mavlink2.MAVLink(io.BytesIO(), srcSystem=255, srcComponent=190)
    store = _Store()
    decode = mavlink2.MAVLink(io.BytesIO())
    store.on_mission_count(
        decode.decode(bytearray(gcs.mission_count_encode(1, 1, len(mavsdk_items), 0).pack(gcs)))
    )
    for m in mavsdk_items:
        msg = gcs.mission_item_int_encode(
            1,
            1,
            m.seq,
            m.frame,
            m.command,
            m.current,
            m.autocontinue,
            m.param1,
            m.param2,
            m.param3,
            m.param4,
            m.x,
            m.y,
            m.z,
            m.mission_type,
        )
        store.on_mission_item(decode.decode(bytearray(msg.pack(gcs))))
    assert store.uploads == 1
    return store.items


def _same(a: float, b: float, tol: float = 0.0) -> bool:
    return (np.isnan(a) and np.isnan(b)) or abs(a - b) <= tol


@pytest.mark.parametrize("name", ["spiral", "waypoints"])
def test_exported_items_are_the_uploaded_items(tmp_path, name):
    """One builder: the items MAVSDK uploads (as sitl's mission store keeps them) are the ones the
    WPL file and the .plan hold, field by field (lat/lon to the 1e-7 degree of MISSION_ITEM_INT)."""
    spec = load_mission(MISSIONS / f"{name}.yaml")
    stored = _uploaded_to_sitl(to_mavsdk(build_items(spec, home_geodetic(spec), home_item=True)))
    wpl_p, plan_p = tmp_path / "m.waypoints", tmp_path / "m.plan"
    assert main(["export", str(MISSIONS / f"{name}.yaml"), "--out", str(wpl_p)]) == 0
    assert main(["export", str(MISSIONS / f"{name}.yaml"), "--out", str(plan_p)]) == 0
    loader = mavwp.MAVWPLoader()
    assert loader.load(str(wpl_p)) == len(stored)
    plan_items = json.loads(plan_p.read_text())["mission"]["items"]
    assert len(plan_items) == len(stored) - 1  # the .plan keeps home apart (plannedHomePosition)
    for it in stored:
        w = loader.wp(it.seq)
        assert (w.seq, w.frame, w.command, w.current, w.autocontinue) == (
            it.seq,
            it.frame,
            it.command,
            it.current,
            it.autocontinue,
        )
        assert all(
            _same(a, b, 1e-8)
            for a, b in zip((w.param1, w.param2, w.param3, w.param4), it.params, strict=True)
        )
        assert (round(w.x * 1e7), round(w.y * 1e7)) == (it.x, it.y) and w.z == pytest.approx(
            it.z, abs=1e-6
        )
        if it.seq == 0:
            continue
        p = plan_items[it.seq - 1]
        assert (p["command"], p["frame"]) == (it.command, it.frame)
        assert all(
            _same(np.nan if a is None else a, b)
            for a, b in zip(p["params"][:4], it.params, strict=True)
        )
        if it.frame == 3:
            assert (round(p["params"][4] * 1e7), round(p["params"][5] * 1e7)) == (it.x, it.y)
            assert (
                p["params"][6] == pytest.approx(it.z, abs=1e-6) and p["Altitude"] == p["params"][6]
            )

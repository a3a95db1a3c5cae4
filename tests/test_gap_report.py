"""``rfsl gap`` reads at 80 columns: summary paragraph first, one line per rung, short flight
labels; the details go to the report folder; ``--family`` writes a family that loads."""

from __future__ import annotations

import json

import numpy as np

from mission.cli.main import main
from mission.flightlog import make_meta, write_flight_log
from mission.gap.selftest import simulate_case
from mission.geo import afar_field
from mission.physics.family import load_family


def _logs(tmp_path, n: int = 2) -> list[str]:
    _, _, flights = simulate_case("rx_pattern", 3, n_flights=n, dt_s=0.5, max_duration_s=200.0)
    origin = afar_field().origin
    out = []
    for k, f in enumerate(flights):
        lat, lon, alt = origin.to_geodetic(f.enu_m)
        att = np.rad2deg(f.attitude_rad)
        cols = {
            "t_s": f.t_s,
            "lat_deg": lat,
            "lon_deg": lon,
            "alt_m": alt,
            "rel_alt_m": f.enu_m[:, 2],
            "roll_deg": att[:, 0],
            "pitch_deg": att[:, 1],
            "yaw_deg": att[:, 2],
            "rss_dbm": f.rss_dbm,
        }
        meta = make_meta(
            origin,
            {"kind": "sim"},
            {"x_m": f.tx_enu_m[0], "y_m": f.tx_enu_m[1], "z_m": f.tx_enu_m[2]},
        )
        p = tmp_path / f"results_useful_ori_exp_{(288, 328)[k % 2]}_loc_{k + 1}.csv"
        out.append(str(write_flight_log(p, cols, meta)))
    return out


def test_report_fits_80_columns_and_family_loads(tmp_path, capsys, monkeypatch) -> None:
    monkeypatch.setenv("COLUMNS", "80")
    logs = _logs(tmp_path)
    capsys.readouterr()
    fam = tmp_path / "fam" / "f.json"
    # the loop check: test_family_fit.py
    rc = main(
        [
            "gap",
            *logs,
            "--base",
            "e2r",
            "--pattern",
            "isotropic",
            "--candidates",
            "rx_pattern,time_offset",
            "--max-rungs",
            "2",
            "--no-localize",
            "--report",
            str(tmp_path / "rep"),
            "--family",
            str(fam),
            "--family-name",
            "t",
            "--family-repeats",
            "0",
            "--family-radial",
        ]
    )
    assert rc == 0
    out = capsys.readouterr().out
    # a path is as long as it is
    lines = [x for x in out.splitlines() if not x.startswith("wrote ")]
    assert max(len(x) for x in lines) <= 80, max(lines, key=len)
    # the plain summary comes first
    assert lines[0].startswith("Held-out p90 |error| of e2r(isotropic)")
    assert "The model misses the UAV antenna's pattern" in " ".join(lines[:6])
    assert "288_loc_1" in out and "results_useful" not in out  # short labels
    ladder = [x for x in out.split("\n\n") if x.startswith("The ladder")][0].splitlines()
    # title, head, rule, one per rung
    assert len(ladder) == 3 + 2 and ladder[-1].startswith("+ rx_pattern")
    details = (tmp_path / "rep" / "details.txt").read_text().splitlines()
    assert max(len(x) for x in details) <= 80 and len(details) > len(lines)
    doc = json.loads((tmp_path / "rep" / "gap.json").read_text())
    assert doc["text"].startswith("Held-out p90") and doc["flights"][0]["name"] == "288_loc_1"
    f = load_family(fam)
    rec = json.loads(fam.read_text())
    assert (
        f.name == "t"
        and rec["effects"] == ["rx_antenna"]
        and rec["source"]["kind"] == "rfsl gap --family"
    )
    assert [p["flight"] for p in rec["per_flight"]] == ["288_loc_1", "328_loc_2"]
    assert {p["team"] for p in rec["per_flight"]} == {"288", "328"}
    # --family-radial: both kinds of per-flight structure, drawn by the loaded family
    assert set(rec["nuisance"]) == {"time_drift_db", "radial_db"}
    assert all("radial_db" in p["residual"] for p in rec["per_flight"])
    assert f.draw(np.random.default_rng(0)).radial_db >= 0.0

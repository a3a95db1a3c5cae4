"""Pre-flight checks: fence (waypoints and legs), altitude, time budget; refusal through `rfsl`."""

from __future__ import annotations

from pathlib import Path

import pytest

from mission.cli.main import main
from mission.errors import InputError
from mission.spec import load_mission
from mission.trajectory.checks import assert_flyable, check_mission

MISSIONS = Path(__file__).resolve().parents[1] / "missions"


def _mission(tmp_path, body: str) -> Path:
    p = tmp_path / "m.yaml"
    p.write_text(body)
    return p


def test_default_spiral_report():
    rep = check_mission(load_mission())
    assert rep.ok and rep.duration_s < 600 and rep.min_fence_clearance_m >= 3.0
    assert rep.n_samples == int(rep.duration_s / 0.03 + 1e-9) + 1


def test_waypoint_outside_fence_named_with_distance(tmp_path):
    p = _mission(tmp_path, "trajectory: {waypoints: [[50, 150], [320, 150], [100, 200]]}\n")
    with pytest.raises(InputError) as ei:
        assert_flyable(load_mission(p))
    msg = str(ei.value)
    assert ei.value.field == "trajectory.waypoints[1]" and str(p) in msg
    assert "waypoint 1" in msg and "19.4 m outside the flight area" in msg


def test_waypoint_inside_but_within_margin(tmp_path):
    p = _mission(tmp_path, "fence_margin_m: 5\ntrajectory: {waypoints: [[50, 150], [298, 150]]}\n")
    with pytest.raises(InputError, match=r"waypoint 1 .* only 2.6 m inside .* \(2.4 m short\)"):
        assert_flyable(load_mission(p))


def test_leg_leaving_a_non_convex_fence(tmp_path):
    # an L-shaped flight area: both waypoints inside, the leg between them cuts the missing corner
    p = _mission(
        tmp_path,
        """
field:
  flight_area: {enu: [[0, 0], [300, 0], [300, 150], [150, 150], [150, 270], [0, 270]]}
  rover_area: {enu: [[0, 0], [300, 0], [300, 270], [0, 270]]}
home: [290, 10]
trajectory: {waypoints: [[100, 250], [280, 100]]}
""",
    )
    with pytest.raises(
        InputError, match=r"leg from waypoint 0 to 1 .* outside the flight area"
    ) as ei:
        assert_flyable(load_mission(p))
    assert ei.value.field == "trajectory.waypoints[0]"


def test_altitude_and_budget(tmp_path):
    p = _mission(tmp_path, "altitude_m: 150\n")
    with pytest.raises(InputError, match="30.0 m above the upper limit 120 m") as ei:
        assert_flyable(load_mission(p))
    assert ei.value.field == "altitude_m"
    p = _mission(tmp_path, "time_budget_s: 300\n")
    with pytest.raises(InputError, match=r"exceeds the time budget 300 s by 2\d\d s") as ei:
        assert_flyable(load_mission(p))
    assert ei.value.field == "time_budget_s"


def test_rfsl_refuses_outside_waypoint_exit_2_one_line(tmp_path, capsys):
    p = _mission(tmp_path, "trajectory: {waypoints: [[50, 150], [100, 400]]}\n")
    out = tmp_path / "m.plan"
    rc = main(["export", str(p), "--format", "plan", "--out", str(out)])
    err = capsys.readouterr().err
    assert rc == 2 and not out.exists()
    assert err.count("\n") == 1 and "Traceback" not in err
    assert str(p) in err and "trajectory.waypoints[1]" in err and "waypoint 1" in err
    assert "m outside the flight area" in err

"""Units of the flight runner without a vehicle: phase tracking, option checks, MAVSDK log dedupe,
status lines."""

from __future__ import annotations

import errno
import io
import json
from types import SimpleNamespace

import numpy as np
import pytest
from rich.console import Console

from mission.errors import InputError
from mission.flight.context import FlightContext
from mission.flight.phases import MonotonicPhases, PhaseTracker
from mission.flight.preflight import check_connect, check_out, check_rss_source
from mission.flight.progress import Display, FlightStatus, plain_line, render
from mission.flight.sdklog import SdkLog
from mission.flight.tasks import log_failed
from mission.flight.telemetry import Telemetry
from mission.flightlog import FlightLogWriter, make_meta, sidecar_path
from mission.geo import Origin


def test_phase_tracker_follows_landed_state_and_mission_progress():
    ph = PhaseTracker()
    # ArduPilot: home, take-off, speed, waypoints, RTL
    ph.configure(first_wp=3, last_item=21, final="return")
    ph.on_landed_state(1.0, "TAKING_OFF")
    ph.on_progress(2.0, 1)
    ph.on_landed_state(3.0, "IN_AIR")
    ph.on_progress(5.0, 3)
    ph.on_progress(9.0, 4)
    ph.on_progress(20.0, 21)
    ph.on_landed_state(30.0, "LANDING")
    ph.on_landed_state(40.0, "ON_GROUND")
    names, items = ph.at(np.array([0.0, 1.5, 4.0, 6.0, 10.0, 25.0, 35.0, 45.0]))
    assert names.tolist() == [
        "ground",
        "takeoff",
        "takeoff",
        "mission",
        "mission",
        "return",
        "land",
        "ground",
    ]
    assert items.tolist() == [-1, -1, -1, 0, 1, -1, -1, -1]


def test_phase_tracker_commanded_return_and_land_item():
    ph = PhaseTracker()
    ph.configure(first_wp=2, last_item=10, final="land")
    ph.on_landed_state(0.0, "IN_AIR")
    ph.on_progress(1.0, 5)
    ph.on_return(2.0)  # Ctrl-C: RTL commanded mid-mission
    names, items = ph.at(np.array([1.5, 2.5]))
    assert names.tolist() == ["mission", "return"] and items.tolist() == [3, -1]
    ph2 = PhaseTracker()
    ph2.configure(first_wp=2, last_item=10, final="land")
    ph2.on_landed_state(0.0, "IN_AIR")
    ph2.on_progress(1.0, 10)  # the LAND item of return_behaviour: land
    assert ph2.at(np.array([1.5]))[0].tolist() == ["land"]


@pytest.mark.parametrize(
    "url",
    [
        "foo://bar",
        "udpin:0.0.0.0:14540",
        "tcpout://127.0.0.1",
        "udpin://:x",
        "serial:///dev/no_such_tty:57600",
    ],
)
def test_bad_connection_urls(url):
    with pytest.raises(InputError, match="--connect"):
        check_connect(url)


# a serial link needs a device that exists: /dev/null is a character device on every test machine
@pytest.mark.parametrize(
    "url", ["udpin://0.0.0.0:14540", "tcpout://127.0.0.1:5760", "serial:///dev/null:57600"]
)
def test_good_connection_urls(url):
    check_connect(url)


def test_rss_source_and_out_checks(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        check_rss_source(f"aerpaw-fifo:{tmp_path / 'Power'}")
    with pytest.raises(InputError, match="folder"):
        check_rss_source(f"aerpaw-fifo:{tmp_path}")
    with pytest.raises(InputError, match="unknown RSS source"):
        check_rss_source("tcp:1234")
    check_rss_source("udp:127.0.0.1:0")
    f = tmp_path / "file"
    f.write_text("")
    with pytest.raises(InputError, match="is a file"):
        check_out(f)
    with pytest.raises(InputError, match="is a file"):
        check_out(f / "sub")
    check_out(tmp_path / "new" / "folder")


def test_mavsdk_messages_once_each_without_colour_codes():
    log = SdkLog(verbose=True)  # not subscribed: feed it as MAVSDK's thread would
    for k in range(5):
        log.on_log(f"\x1b[31m[12:00:0{k}|Error] Connection refused (errno {k})\x1b[0m")
    log.on_log("Sending message failed")
    assert log.new_messages() == [
        "[12:00:00|Error] Connection refused (errno 0)",
        "Sending message failed",
    ]
    log.on_log("[12:00:09|Error] Connection refused (errno 9)")
    assert log.new_messages() == []


def test_mavsdk_dropped_callbacks_are_counted_though_shown_once():
    """MAVSDK repeats its drop warning with a running count; the line is shown once, the count kept
    (the sidecar's ``mavsdk_dropped_callbacks``)."""
    log = SdkLog(verbose=True)
    for n in (1, 4185, 12212):
        log.on_log(
            f"\x1b[31m[05:06:1{n % 10}|Error] \x1b[0mDropping subscription callbacks ({n} so far): "
            "a subscriber is not keeping up."
        )
    assert len(log.new_messages()) == 1 and log.dropped == 12212


def test_plain_status_lines_do_not_wrap(monkeypatch):
    s = FlightStatus(
        mission_name="spiral",
        budget_s=600,
        n_waypoints=18,
        stage="mission",
        rows=123456,
        last_rss=-45.25,
        best_rss=-31.5,
        best_xy=(1234.0, 5678.0),
        link_lost=True,
    )
    line = plain_line(s)
    assert line.startswith("[LINK LOST, last mission]")
    d = Display(s, plain_every_s=0.0)
    buf = io.StringIO()

    d.console = Console(file=buf, width=40, force_terminal=False)
    d.refresh()
    d.message("a warning that is much longer than forty characters, as warnings are")
    lines = buf.getvalue().splitlines()
    assert lines == [
        *line.splitlines(),
        "a warning that is much longer than forty characters, as warnings are",
    ]
    assert all(len(ln) <= 80 for ln in line.splitlines())


def test_first_status_line_has_no_nan():
    """Before the first RSS sample the status line says ``rss=-``, not ``rss=nan``."""
    line = plain_line(FlightStatus(mission_name="spiral", budget_s=600, n_waypoints=18))
    assert "nan" not in line and "rss=- " in line
    assert "OVER" in plain_line(FlightStatus(budget_s=600, t_start=0.0, t_now=601.0))
    s = FlightStatus(budget_s=600, t_start=0.0, t_now=100.0)
    s.predicted_s = 612.4
    assert "t=100/600s (land~612s) " in plain_line(s)


def test_live_panel_shows_no_raw_markup_when_a_message_interrupts_it():
    """A plain message printed under the live panel (``markup=False``) re-renders the panel with
    that option: the panel's cells must not show their markup tags ([red], [green]) then."""
    s = FlightStatus(
        mission_name="spiral",
        budget_s=600,
        n_waypoints=18,
        t_start=0.0,
        t_now=650.0,
        best_rss=-31.5,
        best_xy=(10.0, 20.0),
        link_lost=True,
        warnings=["[odd] text"],
    )
    s.predicted_s = 660.0
    for markup in (True, False):
        buf = io.StringIO()
        Console(file=buf, width=100, force_terminal=False).print(render(s), markup=markup)
        text = buf.getvalue()
        assert "[red]" not in text and "[green]" not in text and "[/" not in text, text
        assert (
            "(over budget)" in text and "-31.50 dB at (10, 20) m" in text and "[odd] text" in text
        )
        assert "landing at ~660 s" in text


def _context(tmp_path, policy: str, in_air: bool = True):
    """A flight's context with a real log writer and no vehicle (what ``tasks.log_failed`` acts
    on)."""
    ctx = FlightContext(
        spec=SimpleNamespace(on_write_error=policy),
        opts=None,
        speedup=1.0,
        url=None,
        status=FlightStatus(),
        tel=Telemetry(),
        phases=MonotonicPhases(),
    )
    ctx.st.was_in_air = ctx.st.in_air = in_air
    writer = FlightLogWriter(
        tmp_path / "f.csv", make_meta(Origin(35.7, -78.7, 90.0), {"kind": "sim"})
    )
    ctx.rows = SimpleNamespace(writer=writer)
    return ctx


@pytest.mark.parametrize("policy, returns", [("return", True), ("continue", False)])
def test_a_failed_log_write_is_said_at_once_and_returns_by_default(
    tmp_path, capsys, policy, returns
):
    ctx = _context(tmp_path, policy)
    log_failed(ctx, OSError(errno.ENOSPC, "No space left on device"))
    log_failed(ctx, OSError(errno.ENOSPC, "No space left on device"))  # said once
    err = " ".join(capsys.readouterr().err.split())  # lines are wrapped at 80 columns
    assert err.count("log write failed (No space left on device)") == 1
    assert ("returning to launch" in err) == returns and ("flying on" in err) == (not returns)
    assert ctx.abort.is_set() == returns and (ctx.abort_reason == "log write failed") == returns
    assert ctx.status.log_error == "No space left on device"
    assert "LOG FAILED" in plain_line(ctx.status)
    # in the sidecar at once
    rec = json.loads(sidecar_path(tmp_path / "f.csv").read_text())["log_error"]
    assert rec == {
        "error": "No space left on device",
        "rows_kept": 0,
        "policy": policy,
        "t_vehicle_s": None,
    }


def test_events_during_a_link_loss_carry_only_measured_times(tmp_path, capsys):
    """After a link loss no event is stamped with an extrapolated vehicle time: the last telemetry's
    time."""
    ctx = _context(tmp_path, "return")
    ctx.tel.add_position(100.0, 35.7, -78.7, 120.0, 30.0)
    ctx.tel.add_attitude(100.0, 0.0, 0.0, 0.0)
    ctx.event("x", "before")
    ctx.link_lost = True
    ctx.event("link", "lost")
    before, lost = ctx.st.events
    assert before["t_vehicle_s"] == 100.0 and "last_telemetry_vehicle_s" not in before
    assert lost["t_vehicle_s"] is None and lost["last_telemetry_vehicle_s"] == 100.0
    assert ctx.vehicle_state() == "unknown"
    ctx.link_lost, ctx.left_flying = False, True
    ctx.link_dead.set()
    assert ctx.vehicle_state() == "in flight"
    ctx.landed_disarmed.set()
    assert ctx.vehicle_state() == "landed"

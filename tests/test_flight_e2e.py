"""End-to-end flights of ``fly-mission`` against the simulated vehicle (the runner's acceptance).

Each test runs the real console entry point in a subprocess (``python -m mission.cli.fly``), so
signals, exit codes and the embedded vehicle are exercised exactly as a user would.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import resource
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from _flight_logs import log_of as _log_of
from _flight_logs import signal_group_at_rows
from _flight_logs import wait_rows as _wait_rows
from pymavlink import mavutil

from mission.cli.fly import main
from mission.flight.budget import plan_times
from mission.flight.runner import free_udp_port
from mission.flight.sources import recompute_sim_rss
from mission.flightlog import read_flight_log
from mission.localize.error_circles import card_calibration, flown_radii
from mission.localize.preprocess import select_samples
from mission.localize.training_domain import planned_track, track_coverage
from mission.spec import load_mission
from mission.trajectory.autopilot import VerticalSpeeds

ROOT = Path(__file__).resolve().parents[1]
SPIRAL = ROOT / "missions" / "spiral.yaml"
pytestmark = pytest.mark.slow


def _fly(args: list[str], **kw) -> subprocess.Popen:
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    return subprocess.Popen(
        [sys.executable, "-m", "mission.cli.fly", *args],
        cwd=ROOT,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        **kw,
    )


def _vehicle(port: int, speedup: float, *extra: str) -> subprocess.Popen:
    cmd = ["-m", "sitl.vehicle", "--port", str(port), "--speedup", str(speedup), *extra]
    return subprocess.Popen(
        [sys.executable, *cmd],
        cwd=ROOT,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )


def test_spiral_end_to_end(tmp_path, repo_dir):
    """The whole spiral at speed-up 20: lands, >= 95 % of samples, attitude varies, RSS
    reproducible, phases logged, measured speed-up recorded, the final line gives the localization
    error."""
    p = _fly([str(SPIRAL), "--speedup", "20", "--out", str(tmp_path)])
    out, err = p.communicate(timeout=150)
    assert p.returncode == 0, err[-3000:]
    # MAVSDK's callbacks kept up: the telemetry that arrived is close to what was asked for (a few
    # dropped callbacks on a loaded machine are tolerated: "Dropping subscription callbacks" may
    # appear once)
    assert "|Info" not in err and "|Debug" not in err  # MAVSDK's chatter is off by default
    assert "27 s of wall-clock time at speed-up 20" in err  # the duration notice
    log = read_flight_log(_log_of(tmp_path))
    assert log.meta["status"] == "completed"
    assert log.meta["rows"] == len(log)
    t = log["t_s"]
    spec = load_mission(SPIRAL)
    # what picks the spiral network (sim_default)
    assert log.meta["trajectory"] == spec.trajectory_meta()
    expected = (t[-1] - t[0]) / spec.source.sample_period_s + 1
    assert len(log) >= 0.95 * expected
    assert t[-1] - t[0] > 0.8 * log.meta["planned_duration_s"]  # the whole spiral was flown
    assert log["rel_alt_m"][-1] < 0.5 and log["rel_alt_m"].max() > 25  # took off and landed
    # measured speed-up and telemetry rates; phases in flight order, the first row before take-off
    assert 10 < log.meta["speedup_measured"] < 22 and log.meta["speedup_requested"] == 20
    for stream in ("position", "attitude"):
        assert (
            0.7 * log.meta["telemetry_rate_requested_hz"]
            < log.meta["telemetry_rate_hz"][stream]
            < 40
        )
    phase = log.columns["phase"]
    assert phase[0] == "ground" and {"takeoff", "mission", "return", "land"} <= set(phase)
    armed = next(e for e in log.meta["events"] if e["kind"] == "armed")
    assert log.meta["t0_vehicle_s"] < armed["t_vehicle_s"]  # the first row is logged before arming
    assert log.columns["mission_item"][phase == "mission"].max() == len(spec.waypoints_enu()) - 1
    # the run ends with the localizer's estimate, its method, region and error against the known
    # truth
    last = "estimate:" + out.rsplit("\nestimate:", 1)[-1]
    assert last.startswith("estimate: x=") and "\n  error: " in last, out
    assert max(len(ln) for ln in last.splitlines()) <= 80, last
    # the spiral network answered its own flight
    assert "\n  method: onnx rfsl_spiral_e2r_ens5.onnx\n" in last, last

    # the whole spiral flown: the full-flight stratum of its calibrated circles
    part, _ = select_samples(log)
    cov = track_coverage(planned_track(log.meta, log.origin), part.enu()[:, :2])
    r90 = flown_radii(
        card_calibration(repo_dir / "models" / "rfsl_spiral_e2r_ens5.onnx", "sim")[0], cov
    )[0][0.9]
    assert cov > 0.95 and f"\n  90 % region: within {r90:.0f} m of the estimate\n" in last, last
    cruise = log["rel_alt_m"] > 25
    for c in ("roll_deg", "pitch_deg"):
        assert np.std(log[c][cruise]) > 0.5
    assert np.ptp(log["yaw_deg"][cruise]) > 180
    rng = np.random.default_rng(spec.source.seed)
    tx = spec.transmitter()  # where rfsl simulate puts the same seed's transmitter
    assert np.allclose(tx, log.truth_enu)
    rss = recompute_sim_rss(log, spec.propagation_model(), rng, tx, spec.source.noise_db)
    assert np.max(np.abs(rss - log["rss_dbm"])) < 0.01


def test_fence_refused_nothing_uploaded(tmp_path):
    """A mission outside the fence is refused (exit 2) and the vehicle's mission count stays 0."""
    os.environ.setdefault("MAVLINK20", "1")

    bad = yaml.safe_load(SPIRAL.read_text())
    bad["trajectory"] = {"waypoints": [[10, 10], [2000, 10], [10, 20]]}
    mfile = tmp_path / "outside.yaml"
    mfile.write_text(yaml.safe_dump(bad))
    port = free_udp_port()
    veh = _vehicle(port, 5)
    try:
        p = _fly(
            [str(mfile), "--connect", f"udpin://127.0.0.1:{port}", "--out", str(tmp_path / "f")]
        )
        _, err = p.communicate(timeout=60)
        assert p.returncode == 2, err[-2000:]
        assert "error:" in err and "waypoint" in err.lower()
        assert not list((tmp_path / "f").glob("*/flight.csv"))
        gcs = mavutil.mavlink_connection(f"udpin:127.0.0.1:{port}", source_system=255)
        assert gcs.wait_heartbeat(timeout=10)
        gcs.mav.mission_request_list_send(1, 1, 0)
        msg = gcs.recv_match(type="MISSION_COUNT", blocking=True, timeout=5)
        assert msg is not None and msg.count == 0
        gcs.close()
    finally:
        veh.terminate()
        veh.wait(5)


def test_ctrl_c_returns_to_launch(tmp_path):
    """SIGINT mid-mission: RTL commanded, the vehicle lands, the log is closed and readable, exit
    130.  The signal comes 1500 rows (45 s of vehicle time) in: on the first legs, so the return is
    short."""
    p = _fly([str(SPIRAL), "--speedup", "20", "--out", str(tmp_path), "--no-localize"])
    try:
        _wait_rows(tmp_path, 1500, 60)
        p.send_signal(signal.SIGINT)
        _, err = p.communicate(timeout=90)
    finally:
        p.kill()
    assert p.returncode == 130, err[-3000:]
    assert "return to launch commanded" in err
    log = read_flight_log(_log_of(tmp_path))
    assert log.meta["status"].startswith("aborted")
    assert any(e["kind"] == "rtl" for e in log.meta["events"])
    assert any(e["kind"] == "landed" for e in log.meta["events"])
    assert log["rel_alt_m"][-1] < 0.5
    # stopped mid-mission
    assert "mission" in set(log.columns["phase"]) and "return" in set(log.columns["phase"])
    enu = log.enu()
    assert np.hypot(*enu[-1, :2] - enu[0, :2]) < 2.0  # landed back at home


def _fly_to(port: int, speedup: float, out: Path, *extra: str) -> subprocess.Popen:
    """``fly-mission`` of the spiral against the vehicle on ``port`` (no localization after)."""
    url = f"udpin://127.0.0.1:{port}"
    args = ["--speedup", f"{speedup:g}", "--out", str(out), "--no-localize", *extra]
    return _fly([str(SPIRAL), "--connect", url, *args])


def test_vehicle_killed_link_loss(tmp_path):
    """The vehicle process dies mid-flight: link loss reported, log closed and readable."""
    port = free_udp_port()
    veh = _vehicle(port, 20)
    try:
        p = _fly_to(port, 20, tmp_path, "--link-timeout", "5")
        _wait_rows(tmp_path, 2000, 60)
        veh.kill()
        _, err = p.communicate(timeout=60)
    finally:
        veh.kill()
        p.kill()
    assert p.returncode == 3, err[-3000:]
    assert "link lost" in err.lower()
    assert "\x1b[" not in err  # no raw colour codes from MAVSDK
    assert err.count("MAVLink link lost") == 1  # one warning, not one per second
    assert err.strip().splitlines()[-1].startswith("error: link lost")
    log = read_flight_log(_log_of(tmp_path))
    assert log.meta["link_lost"] is True
    assert len(log) > 2000
    # only measured times: no extrapolated arm-to-disarm time, the last telemetry's time, the state
    # unknown
    m = log.meta
    assert m["budget"]["used_s"] is None and m["vehicle_state"] == "unknown"
    lost = [e for e in m["events"] if e["kind"] == "link"]
    assert lost and all(e["t_vehicle_s"] is None for e in lost)
    assert all(e["last_telemetry_vehicle_s"] == m["last_telemetry_vehicle_s"] for e in lost)
    assert m["last_telemetry_vehicle_s"] - m["t0_vehicle_s"] >= log["t_s"][-1] - 1.0


def test_a_flight_stuck_in_its_take_off_is_brought_home(tmp_path):
    """A vehicle that barely climbs (0.01 m/s: the take-off never ends; PX4 SITL once sat at 0 m in
    a failsafe after "Takeoff detected" and the run logged "takeoff" until it was killed): past its
    budget by a quarter with no return begun, the flight's own watch commands the return, keeps the
    log and exits 3 with one line.  One ring of the spiral with a 260 s budget (the whole
    spiral's 600 s took 750 s of vehicle time to come due, 19 s of wall clock)."""
    d = yaml.safe_load(SPIRAL.read_text())
    d["trajectory"]["params"]["spacing_m"] = 200  # one ring: 223 s of flight
    d["time_budget_s"] = 260
    mfile = tmp_path / "ring.yaml"
    mfile.write_text(yaml.safe_dump(d))
    port = free_udp_port()
    veh = _vehicle(port, 40, "--kinematics", json.dumps({"climb_rate_mps": 0.01}))
    try:
        url = f"udpin://127.0.0.1:{port}"
        args = ["--speedup", "40", "--out", str(tmp_path / "f"), "--no-localize"]
        p = _fly([str(mfile), "--connect", url, *args, "--land-timeout", "5"])
        _, err = p.communicate(timeout=120)
    finally:
        veh.kill()
        p.kill()
    assert p.returncode == 3, err[-3000:]
    assert "overdue: " in err and "budget 260 s: returning to launch" in err
    assert err.strip().splitlines()[-1].startswith("error: aborted (overdue)")
    m = read_flight_log(_log_of(tmp_path / "f")).meta
    assert m["status"].startswith("aborted (overdue)")
    ev = next(e for e in m["events"] if e["kind"] == "abort")
    armed = next(e for e in m["events"] if e["kind"] == "armed")
    # the budget and its quarter (at least a minute), polled
    assert 320 < ev["t_vehicle_s"] - armed["t_vehicle_s"] < 340
    assert any(e["kind"] == "rtl" for e in m["events"])  # the return was commanded


def _no_autopilot_url(scheme: str) -> str:
    return f"{scheme}://127.0.0.1:{free_udp_port()}"


@pytest.mark.parametrize("scheme", ["udpin", "tcpout"])
def test_connecting_to_nothing_times_out_with_one_line(tmp_path, scheme):
    t0 = time.monotonic()
    p = _fly(
        [
            str(SPIRAL),
            "--connect",
            _no_autopilot_url(scheme),
            "--link-timeout",
            "3",
            "--out",
            str(tmp_path),
        ]
    )
    out, err = p.communicate(timeout=60)
    assert p.returncode == 3, err
    assert time.monotonic() - t0 < 30
    lines = err.strip().splitlines()
    # the pre-flight duration line (printed with --connect too), then exactly one error line, no
    # traceback
    assert lines[0].startswith("estimated flight: ") and "add --speedup" not in lines[0], err
    assert (
        len(lines) == 2
        and lines[1].startswith("error: no autopilot on")
        and "within 3 s" in lines[1]
    ), err
    assert not list(tmp_path.glob("*/flight.csv"))


def test_sigterm_before_takeoff_does_not_return_to_launch(tmp_path):
    p = _fly([str(SPIRAL), "--connect", _no_autopilot_url("udpin"), "--out", str(tmp_path)])
    # checked, handlers on, waiting for an autopilot
    assert p.stderr.readline().startswith("estimated flight")
    p.send_signal(signal.SIGTERM)
    _, err = p.communicate(timeout=30)
    assert p.returncode == 130, err
    assert "returning to launch" not in err and "return to launch" not in err
    assert "before take-off" in err.strip().splitlines()[-1]


@pytest.mark.parametrize(
    "args, field",
    [
        (["--rss-source", "foo"], "--rss-source"),
        (["--rss-source", "aerpaw-fifo:/no/such/Power"], "--rss-source"),
        (["--rss-source", "udp:99999"], "--rss-source"),
        (["--connect", "foo://bar"], "--connect"),
        (["--connect", "tcpout://127.0.0.1"], "--connect"),
        (["--out", "FILE"], "--out"),
    ],
)
def test_bad_options_refused_before_anything_starts(tmp_path, capsys, args, field):
    """Exit 2 and one line naming the option, before any vehicle is started (no vehicle, no log).
    The first case runs the console entry point in a subprocess; the others call it in-process
    (same code path after the interpreter starts, without a fresh Python importing the package
    each time)."""
    f = tmp_path / "a_file"
    f.write_text("x")
    args = [str(f) if a == "FILE" else a for a in args]
    argv = [str(SPIRAL), *args] + ([] if "--out" in args else ["--out", str(tmp_path / "flights")])
    if args[:2] == ["--rss-source", "foo"]:
        p = _fly(argv)
        _, err = p.communicate(timeout=60)
        code = p.returncode
    else:
        code, err = main(argv), capsys.readouterr().err
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and field in lines[0] and "Traceback" not in err, err
    assert not (tmp_path / "flights").exists()


def test_kill_9_does_not_leave_the_vehicle_running(tmp_path):
    p = _fly([str(SPIRAL), "--speedup", "20", "--out", str(tmp_path), "--no-localize"])
    try:
        _wait_rows(tmp_path, 200, 60)
    finally:
        p.kill()
    _, err = p.communicate(timeout=30)
    vehicle = int(re.search(r"simulated vehicle started \(pid (\d+)\)", err).group(1))
    # the log it left: the sidecar still says flying, and reading it says so in one line
    log = read_flight_log(_log_of(tmp_path))
    assert log.meta["status"] == "flying" and len(log) >= 200
    (said,) = [n for n in log.notes if "ended without closing" in n]
    assert len(said) <= 80, said
    end = time.monotonic() + 10
    while time.monotonic() < end:
        try:
            os.kill(vehicle, 0)
        except ProcessLookupError:
            return
        time.sleep(0.2)
    os.kill(vehicle, signal.SIGKILL)
    raise AssertionError("the simulated vehicle outlived fly-mission's kill -9")


def _fly_px4_like(mfile: Path, speedup: float, out: Path, *extra: str) -> tuple[int, str]:
    """Fly ``mfile`` with ``--no-localize`` on the built-in vehicle with the PX4-like profile
    (vehicle options ``extra``), started apart at the mission's home on a free UDP port; (exit code,
    stderr)."""
    spec = load_mission(mfile)
    lat, lon, alt = spec.field.origin.to_geodetic(np.asarray(spec.home_enu, dtype=float))
    port = free_udp_port()
    veh = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "sitl.vehicle",
            "--port",
            str(port),
            "--speedup",
            f"{speedup:g}",
            "--profile",
            "px4",
            "--home",
            f"{float(lat):.9f},{float(lon):.9f},{float(alt):.3f}",
            *extra,
        ],
        cwd=ROOT,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        p = _fly(
            [
                str(mfile),
                "--connect",
                f"udpin://127.0.0.1:{port}",
                "--speedup",
                f"{speedup:g}",
                "--out",
                str(out),
                "--no-localize",
            ]
        )
        _, err = p.communicate(timeout=150)
    finally:
        veh.terminate()
        veh.wait(5)
        p.kill()
    return p.returncode, err


def test_px4_like_vehicle_at_10x_keeps_every_text_and_warns_the_budget(tmp_path):
    """Budget and autopilot texts on the PX4-like vehicle (legs 7 % slower than asked, return at its
    own MPC_XY_CRUISE, STATUSTEXT only while a GCS heartbeat arrived within 2.5 simulated s) at
    speed-up 10, a short spiral with a budget 3 % above its plan: every text the vehicle sent is in
    the sidecar (tab stripped, none after "landed and disarmed"), the overrun is warned during the
    flight and recorded, MPC_XY_CRUISE is restored, "armed" comes before "mission started" and the
    duration line shows with --connect."""

    d = yaml.safe_load(SPIRAL.read_text())
    d["trajectory"]["params"]["spacing_m"] = (
        200  # one ring: 223 s of flight, 22 s of wall clock at 10x
    )
    d["budget_policy"] = "warn"  # this test is about the warning (the default, trim, acts on it)
    mfile = tmp_path / "short.yaml"
    mfile.write_text(yaml.safe_dump(d))
    # planned with the PX4-like vehicle's climb and landing speeds, as the runner reads them from
    # it; over --connect the runner knows it for the built-in vehicle (its AUTOPILOT_VERSION): no
    # PX4 pace or touchdown-to-disarm delay
    base = plan_times(load_mission(mfile), vertical=VerticalSpeeds(1.5, 1.5, 0.7, 5.0)).duration_s
    plan = base
    # the built-in vehicle disarms at touchdown: 3 % above its flight
    d["time_budget_s"] = round(base * 1.03)
    mfile.write_text(yaml.safe_dump(d))
    texts = tmp_path / "texts.jsonl"
    rc, err = _fly_px4_like(mfile, 10, tmp_path / "f", "--statustext-log", str(texts))
    assert rc == 0, err[-3000:]
    # duration line, --connect
    assert "of wall-clock time at speed-up 10" in err and "add --speedup" not in err
    log = read_flight_log(_log_of(tmp_path / "f"))
    ev = log.meta["events"]
    kinds = [e["kind"] for e in ev]
    sent = [json.loads(line) for line in texts.read_text().splitlines()]
    assert len(sent) >= 6 and all(r["sent"] for r in sent)  # the vehicle dropped none
    got = [e["text"] for e in ev if e["kind"] == "statustext"]
    # every text, in order, tab stripped
    assert got == ["autopilot: " + r["text"].rstrip() for r in sent]
    assert max(i for i, k in enumerate(kinds) if k == "statustext") < kinds.index("landed")
    assert kinds.index("armed") < kinds.index("start")
    b = log.meta["budget"]
    assert b["planned_s"] == pytest.approx(plan, abs=1) and b["overrun"] and b["overrun_s"] > 0
    assert b["used_s"] == pytest.approx(b["budget_s"] + b["overrun_s"])
    # warned early, not at the end
    assert b["warned_at_s"] is not None and b["warned_at_s"] < 0.6 * b["used_s"]
    assert "WARNING: budget will not hold" in err and f"{b['overrun_s']:.0f} s over" in err
    assert any(e["kind"] == "params" and e["text"] == "restored MPC_XY_CRUISE=4.8" for e in ev)


def _fly_group(args: list[str]) -> subprocess.Popen:
    """``fly-mission`` as the leader of its own process group, as a terminal starts it."""
    return _fly(args, start_new_session=True)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGHUP], ids=["SIGINT", "SIGHUP"])
def test_terminal_signal_to_the_whole_group_returns_to_launch(tmp_path, sig):
    """A terminal's Ctrl-C (or a lost SSH session's SIGHUP) reaches every process of the group, the
    live-estimate worker included: the flight still returns to launch and lands, exits 130 with no
    traceback, and the sidecar says aborted with the rows it holds.  The moment is picked on the
    log's rows."""
    p = _fly_group([str(SPIRAL), "--speedup", "20", "--out", str(tmp_path), "--no-localize"])
    err = signal_group_at_rows(p, tmp_path, 1500, sig, 90, 120)
    assert p.returncode == 130, err[-3000:]
    assert "Traceback" not in err, err[-3000:]
    assert "return to launch commanded" in err
    log = read_flight_log(_log_of(tmp_path))
    assert (
        log.meta["status"].startswith(f"aborted ({sig.name})")
        and "completed" not in log.meta["status"]
    )
    assert log.meta["rows"] == len(log)
    assert any(e["kind"] == "landed" for e in log.meta["events"])
    assert log["rel_alt_m"][-1] < 0.5


def test_ctrl_c_twice_says_the_vehicle_was_left_in_flight(tmp_path):
    """Two Ctrl-Cs 0.3 s apart to the whole group: the second stops waiting for the landing; the
    status and the sidecar say the vehicle was left in flight (altitude, phase) and name the
    parameters left changed (the PX4-like vehicle's MPC_XY_CRUISE, 4.8 m/s, set to the mission's 5.5
    and not restored under a flying vehicle)."""
    spec = load_mission(SPIRAL)
    lat, lon, alt = spec.field.origin.to_geodetic(np.asarray(spec.home_enu, dtype=float))
    port = free_udp_port()
    veh = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "sitl.vehicle",
            "--port",
            str(port),
            "--speedup",
            "20",
            "--profile",
            "px4",
            "--home",
            f"{float(lat):.9f},{float(lon):.9f},{float(alt):.3f}",
        ],
        cwd=ROOT,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    p = _fly_group(
        [
            str(SPIRAL),
            "--connect",
            f"udpin://127.0.0.1:{port}",
            "--speedup",
            "20",
            "--out",
            str(tmp_path),
            "--no-localize",
        ]
    )
    try:
        _wait_rows(tmp_path, 1500, 90)
        os.killpg(p.pid, signal.SIGINT)
        time.sleep(0.3)
        os.killpg(p.pid, signal.SIGINT)
        _, err = p.communicate(timeout=90)
    finally:
        veh.kill()
        with contextlib.suppress(ProcessLookupError):
            os.killpg(p.pid, signal.SIGKILL)
    assert p.returncode == 130, err[-3000:]
    assert "Traceback" not in err, err[-3000:]
    m = read_flight_log(_log_of(tmp_path)).meta
    assert "vehicle left in flight at" in m["status"] and " m in " in m["status"], m["status"]
    assert "returned to launch" not in m["status"] and "completed" not in m["status"]
    assert m["vehicle_state"] == "in flight" and m["params_left_changed"] == {
        "MPC_XY_CRUISE": pytest.approx(4.8)
    }
    assert "parameters left changed: MPC_XY_CRUISE" in m["status"]
    assert "autopilot parameters left changed: MPC_XY_CRUISE (was 4.8)" in err
    assert m["budget"]["used_s"] is None  # never disarmed: no time is made up
    last = err.strip().split("\nerror: ")[-1]  # the closing error, wrapped at 80 columns
    assert last.startswith("aborted (SIGINT), vehicle left in flight at ")
    assert max(len(ln) for ln in ("error: " + last).splitlines()) <= 80


def test_full_disk_in_flight_is_said_returns_and_exits_4(tmp_path):
    """A file-size limit (as a full disk) that the log passes mid-mission: said at once, the vehicle
    returns to launch and lands, the CSV holds whole rows only and the sidecar says how many; exit
    4, no traceback."""
    limit = 400 * 1024  # about 4 500 rows: the log passes it on the first legs

    def full_disk() -> None:
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    p = _fly(
        [str(SPIRAL), "--speedup", "20", "--out", str(tmp_path), "--no-localize"],
        preexec_fn=full_disk,
    )
    try:
        _, err = p.communicate(timeout=150)
    finally:
        p.kill()
    assert p.returncode == 4, err[-3000:]
    assert "Traceback" not in err, err[-3000:]
    assert "log write failed (File too large)" in err and "returning to launch" in err
    log = read_flight_log(_log_of(tmp_path))
    m = log.meta
    assert (
        m["rows"] == len(log) == m["log_error"]["rows_kept"]
        and m["log_error"]["policy"] == "return"
    )
    assert m["status"].startswith(
        "aborted (log write failed), returned to launch; log incomplete"
    ), m["status"]
    assert m["vehicle_state"] == "landed" and any(e["kind"] == "rtl" for e in m["events"])
    assert _log_of(tmp_path).stat().st_size <= limit


def test_trim_lands_inside_a_tight_budget_on_the_px4_like_vehicle(tmp_path):
    """The default ``budget_policy: trim`` on the PX4-like vehicle (legs 7 % slower than asked) at
    speed-up 20, a one-ring spiral with a budget 3 % above its kinematic plan (flown whole, 7 %
    slow, it would not fit): the tail is dropped in flight with one line, the vehicle lands inside
    the budget (arm to disarm, measured), and the sidecar names what was dropped."""
    d = yaml.safe_load(SPIRAL.read_text())
    d["trajectory"]["params"]["spacing_m"] = 200  # one ring: about 12 s of wall clock at 20x
    mfile = tmp_path / "tight.yaml"
    mfile.write_text(yaml.safe_dump(d))
    plan = plan_times(load_mission(mfile), vertical=VerticalSpeeds(1.5, 1.5, 0.7, 5.0)).duration_s
    budget = round(plan * 1.03)
    d["time_budget_s"] = budget
    mfile.write_text(yaml.safe_dump(d))

    spec = load_mission(mfile)
    rc, err = _fly_px4_like(mfile, 20, tmp_path / "f")
    assert rc == 0, err[-3000:]
    log = read_flight_log(_log_of(tmp_path / "f"))
    b = log.meta["budget"]
    n = len(spec.waypoints_enu())
    assert b["policy"] == "trim" and b["dropped_waypoints"] and b["dropped_waypoints"][-1] == n, b
    # the tail, whole
    assert b["dropped_waypoints"] == list(range(b["dropped_waypoints"][0], n + 1))
    assert b["arm_to_disarm_s"] is not None and b["arm_to_disarm_s"] <= budget, b
    assert not b["overrun"]
    dropped_lines = [ln for ln in err.splitlines() if "budget: dropped waypoint" in ln]
    assert 1 <= len(dropped_lines) <= 3 and all(
        len(ln) <= 80 for ln in err.splitlines() if len(ln.split()) > 1
    ), err
    items = log.columns["mission_item"][log.columns["phase"] == "mission"]
    # waypoints after the last kept one were not flown
    assert items.max() == b["dropped_waypoints"][0] - 2

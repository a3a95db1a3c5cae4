"""What ``fly-mission`` says and checks before flying: lines within 80 columns, repeated autopilot
texts folded with a count, a failed upload in one line, home far enough inside the fence, the
simulated transmitter of a seed in one place for ``rfsl simulate`` and ``fly-mission --seed``, an
adaptive block that is not enabled."""

from __future__ import annotations

import asyncio
import dataclasses
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from _localize_helpers import write_synthetic_log
from hypothesis import given, settings
from hypothesis import strategies as st
from mavsdk.plugins.mission_raw import MissionRawError, MissionRawResult

from mission.adaptive.rounds import AdaptiveRounds, autopilot_returns
from mission.cli.fly import choose_adaptive, main
from mission.cli.main import main as rfsl
from mission.flight.budget import start_budget
from mission.flight.context import EXIT_LINK, FlightError
from mission.flight.plan import UploadFailed, upload_with_retries
from mission.flight.progress import PLAIN_WIDTH, FoldedTexts, fit_width
from mission.flight.runner import FlyOptions, make_source, new_context, print_result
from mission.flight.vehicle_process import free_udp_port
from mission.flightlog import read_flight_log
from mission.localize.api import localize_log
from mission.localize.methods import ADAPTIVE_METHOD
from mission.localize.render import Shown
from mission.spec import load_mission, parse_mission
from mission.trajectory.autopilot import ReturnModel
from mission.trajectory.checks import RETURN_OVERSHOOT_M, check_mission
from mission.trajectory.items import build_items

ROOT = Path(__file__).resolve().parents[1]
SPIRAL = ROOT / "missions" / "spiral.yaml"

words = st.text(st.characters(min_codepoint=33, max_codepoint=126), min_size=1, max_size=30)


@given(st.lists(st.lists(words, min_size=1, max_size=25).map(" ".join), min_size=1, max_size=4))
@settings(max_examples=80, deadline=None)
def test_fit_width_keeps_every_word_and_each_line_within_80_columns(paragraphs):
    text = "\n".join(paragraphs)
    out = fit_width(text)
    assert out.split() == text.split()  # nothing lost, nothing reordered
    for line in out.splitlines():  # a line over 80 columns is one word alone (a path)
        assert len(line) <= PLAIN_WIDTH or len(line.split()) == 1


@given(
    st.lists(
        st.sampled_from(
            [
                "Auto mission changed, restarted command",
                "Mission: 9 WP",
                "Reached command #9",
                "x" * 120,
            ]
        ),
        min_size=1,
        max_size=60,
    )
)
@settings(max_examples=60, deadline=None)
def test_repeated_texts_are_shown_once_and_counted(texts):
    f = FoldedTexts()
    shown = [t for t in texts if f.show(t)]
    assert shown == list(dict.fromkeys(texts))  # each text once, in order of first appearance
    summary = f.summary()
    counts = {t: texts.count(t) for t in set(texts)}
    assert len(summary) == sum(n > 1 for n in counts.values())
    for line in summary:
        assert len(line) <= PLAIN_WIDTH and any(
            line.endswith(f"(x{n}, shown once)") for n in counts.values()
        )


def test_a_failed_upload_is_one_line_with_the_result_name_and_item_count():
    class Refusing:
        calls = 0

        async def upload_mission(self, items):
            Refusing.calls += 1
            # reprs
            raise MissionRawError(MissionRawResult.TIMEOUT, "upload_mission()", *([object()] * 25))

    spec = load_mission(SPIRAL)
    items = build_items(spec, (35.72737, -78.69622, 0.0), True)
    ctx = new_context(spec, FlyOptions())
    with pytest.raises(UploadFailed) as ei:
        asyncio.run(upload_with_retries(ctx, Refusing(), items))
    assert (
        str(ei.value) == f"mission upload failed: TIMEOUT, {len(items)} items"
        and ei.value.code == EXIT_LINK
    )
    retried = [e["text"] for e in ctx.st.events if e["kind"] == "upload"]
    assert Refusing.calls == 3 and retried == ["mission upload failed (TIMEOUT); retrying"] * 2


@given(st.floats(-5.0, 12.0), st.floats(0.0, 6.0))
@settings(max_examples=40, deadline=None)
def test_home_must_keep_the_return_overshoot_plus_the_margin_from_the_fence(inside_m, margin):
    """A home ``inside_m`` west of the AFAR flight area's east edge: refused exactly when it is
    closer than the known return overshoot plus ``home_margin_m``, naming the key ``home``."""
    base = parse_mission({})
    area = base.field.flight_area
    east = 300.65  # the east edge near the AFAR launch point (x = 300.21 m is 0.44 m inside)
    home = [east - inside_m, 54.1]
    spec = parse_mission({"home": home, "home_margin_m": margin})
    clear = float(area.signed_distance(np.array([home]))[0])
    bad = [
        v
        for v in check_mission(spec).violations
        if v.key == "home" and v.message.startswith("home at")
    ]
    assert bool(bad) == (clear < RETURN_OVERSHOOT_M + margin - 1e-6), (clear, bad)


def test_shipped_missions_keep_their_home_inside_the_margin():
    for f in sorted((ROOT / "missions").glob("*.yaml")):
        spec = load_mission(f)
        rep = check_mission(spec)
        assert rep.ok, (f.name, [v.message for v in rep.violations])
        clear = float(spec.field.flight_area.signed_distance(spec.home_enu[None, :2])[0])
        assert clear >= RETURN_OVERSHOOT_M + spec.home_margin_m


@pytest.mark.parametrize("seed", [0, 1, 7])
def test_fly_mission_seed_puts_the_transmitter_where_simulate_does(tmp_path, seed):
    """``fly-mission --seed N``'s truth (the runner's simulated source) is ``rfsl simulate --seed
    N``'s."""
    spec = load_mission(SPIRAL)
    spec = dataclasses.replace(spec, source=dataclasses.replace(spec.source, seed=seed))
    _, truth = make_source(spec, "sim")
    assert rfsl(["simulate", str(SPIRAL), "--seed", str(seed), "--out", str(tmp_path)]) == 0
    log = read_flight_log(next(tmp_path.glob("*.csv")))
    np.testing.assert_allclose([truth["x_m"], truth["y_m"], truth["z_m"]], log.truth_enu, atol=1e-6)


def test_fly_mission_refuses_a_negative_seed_in_one_line(capsys):
    assert main([str(SPIRAL), "--seed", "-3"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--seed" in err[0] and "-3" in err[0], err


@pytest.mark.parametrize(
    "block, flag, flown, said",
    [
        ("adaptive: {}", False, False, True),
        ("adaptive: null", False, False, True),
        ("adaptive: {enabled: false}", False, False, True),
        ("adaptive: {enabled: true}", False, True, False),
        ("adaptive: {}", True, True, False),
        ("", False, False, False),
        ("", True, True, False),
    ],
)
def test_an_adaptive_block_that_is_not_enabled_says_the_fixed_mission_is_flown(
    block, flag, flown, said
):
    spec = parse_mission(yaml.safe_load(SPIRAL.read_text() + "\n" + block + "\n"))
    a, note = choose_adaptive(spec, flag)
    assert (a is not None) == flown and (note is not None) == said
    if said:
        assert (
            note == "adaptive: not enabled (enabled: true or --adaptive): flying the fixed mission"
        )


@pytest.mark.slow
def test_the_fixed_mission_line_comes_first_in_a_real_run(tmp_path):
    """``adaptive: null``: the one line, before anything starts (then no autopilot answers: its own
    line)."""
    m = tmp_path / "m.yaml"
    m.write_text(SPIRAL.read_text() + "\nadaptive: null\n")
    p = subprocess.run(
        [
            sys.executable,
            "-m",
            "mission.cli.fly",
            str(m),
            "--connect",
            f"udpin://127.0.0.1:{free_udp_port()}",
            "--link-timeout",
            "1",
            "--out",
            str(tmp_path / "f"),
        ],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )
    lines = p.stderr.strip().splitlines()
    assert p.returncode == 3 and lines[0].startswith("adaptive: not enabled"), p.stderr
    assert sum("adaptive" in ln for ln in lines) == 1


@pytest.mark.parametrize("return_mps, refused", [(None, False), (0.3, True)])
def test_the_adaptive_budget_is_checked_again_with_the_autopilots_return(return_mps, refused):
    """Once the autopilot's return speed is known (its budget plan), an adaptive mission whose
    rounds no longer fit is refused before the upload with exit 2 naming the field; the mission's
    own return passes."""
    spec = load_mission(ROOT / "missions" / "spiral_adaptive.yaml")
    ext = AdaptiveRounds(spec, spec.adaptive)
    ctx = new_context(spec, FlyOptions(), ext)
    ctx.budget = start_budget(ctx, return_mps, None)
    end = ctx.spec.waypoints_enu()[-1]
    extra = autopilot_returns(ctx).seconds(end) - ReturnModel.of(ctx.spec).seconds(end)
    assert (extra > 100) == refused, extra
    if not refused:
        ext.check(ctx)
        return
    with pytest.raises(FlightError) as ei:
        ext.check(ctx)
    assert ei.value.code == 2 and "spiral_adaptive.yaml, field '" in str(ei.value)
    assert len(str(ei.value).splitlines()) == 1


def test_both_kinds_of_flight_end_with_the_renderers_lines(tmp_path, capsys):
    """A fixed flight's last lines are ``localize``'s answer on its log, an adaptive flight's the
    in-flight final entry; both through ``render.Shown`` (same shape, each within 80 columns)."""
    spec = load_mission(ROOT / "missions" / "spiral_adaptive.yaml")
    ext = AdaptiveRounds(spec, spec.adaptive)
    ctx = new_context(spec, FlyOptions(), ext)
    ctx.truth = {"x_m": 10.0, "y_m": 20.0}
    assert ext.result_lines(ctx) == ["no final estimate (too few samples)"]
    ctx.live.final = {"t_s": 412.0, "x_m": 13.0, "y_m": 24.0, "area_m2": 1500.0}
    adaptive = ext.result_lines(ctx)
    assert adaptive == (
        Shown.of_entry(ctx.live.final, ctx.truth, ADAPTIVE_METHOD, spec.field.origin).lines()
    )
    # where a field team walks to: the WGS84 point, as a fixed flight's first line gives it
    lat, lon, _ = spec.field.origin.to_geodetic([13.0, 24.0, 0.0])
    assert adaptive[0] == f"estimate: x=13.0 m, y=24.0 m (lat {lat:.7f}, lon {lon:.7f})"
    assert adaptive[1:] == [
        f"  method: {ADAPTIVE_METHOD}, in flight at t=412 s",
        "  (`localize LOG --at 412` gives it back)",
        "  90 % region: 1500 m^2",
        "  error: 5.0 m (true transmitter at 10.0, 20.0 m)",
    ]
    fixed = new_context(spec, FlyOptions(), None)
    fixed.log_path = write_synthetic_log(tmp_path / "f.csv", (150.0, 120.0, 1.5), n=3000)
    fixed.truth = {"x_m": 150.0, "y_m": 120.0}
    print_result(fixed)
    out = capsys.readouterr().out.strip().splitlines()
    assert out == Shown.of(localize_log(fixed.log_path), fixed.truth).lines()
    assert out[0].startswith("estimate: x=") and out[-1].startswith("  error: ")
    assert max(len(ln) for ln in out + adaptive) <= 80

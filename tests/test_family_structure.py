"""A family with per-flight structure: the drawn time drift, its fit on a flight, the nuisance field
of a family record, and the one loss that weighs the loop check and the predictive checks."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import mission.gap.familyrun as fr
from mission.errors import InputError
from mission.gap.familyfit import (
    nuisance_stds,
    offset_distribution,
    structure_kinds,
    structure_of,
    time_drift_std,
)
from mission.gap.familyloss import family_loss, interval_miss, ppc_miss
from mission.gap.fit import FitConfig
from mission.physics.family import (
    DRIFT_ORDER,
    FamilyDraw,
    PhysicsFamily,
    azimuth_coordinate,
    azimuth_ripple,
    load_family,
    log_distance_unit,
    radial_profile,
    simulate_rss,
    time_drift,
)
from mission.samples import FlightSamples


def _with_nuisance(nuis: object) -> dict:
    d = load_family("afar").to_dict()
    d["nuisance"] = nuis
    return d


@pytest.mark.parametrize("std", [0.5, 3.0, 9.0])
def test_time_drift_has_its_std_and_is_smooth(std: float) -> None:
    g = time_drift(900, std, np.random.default_rng(4))
    assert np.std(g) == pytest.approx(std, rel=1e-9)
    # a combination of P_1..P_4 of the sample order: a degree-4 fit leaves nothing
    u = np.linspace(-1.0, 1.0, 900)
    fit = np.polynomial.legendre.legval(u, np.polynomial.legendre.legfit(u, g, DRIFT_ORDER))
    assert np.max(np.abs(fit - g)) < 1e-9 * std
    # reproducible from the generator; another seed, another drift
    assert np.array_equal(g, time_drift(900, std, np.random.default_rng(4)))
    assert not np.allclose(g, time_drift(900, std, np.random.default_rng(5)))


def test_time_drift_zero_cases() -> None:
    assert not time_drift(100, 0.0, np.random.default_rng(0)).any()
    assert not time_drift(2, 5.0, np.random.default_rng(0)).any()


def test_a_family_without_nuisance_draws_as_before() -> None:
    """The nuisance is drawn last: the rest of a draw, and the simulated RSS without drift, are
    those of the family without it."""
    old = load_family("afar")
    new = PhysicsFamily.from_dict(_with_nuisance({"time_drift_db": 2.0}))
    for seed in range(5):
        a, b = old.draw(np.random.default_rng(seed)), new.draw(np.random.default_rng(seed))
        assert a.to_dict() == {k: v for k, v in b.to_dict().items() if k != "time_drift_db"}
        assert a.time_drift_db == 0.0 and b.time_drift_db == 2.0
    rx = np.column_stack([np.linspace(0, 200, 300), np.zeros(300), np.full(300, 30.0)])
    att = np.zeros((300, 3))
    tx = np.array([50.0, 60.0, 1.5])
    d0 = FamilyDraw({"base": "free-space"}, 3.0, 30.0, 1.0, 0.0)
    d1 = FamilyDraw({"base": "free-space"}, 3.0, 30.0, 1.0, 0.0, 4.0)
    r0 = simulate_rss(d0, tx, rx, att, np.random.default_rng(7))
    r1 = simulate_rss(d1, tx, rx, att, np.random.default_rng(7))
    # the same shadowing and noise, plus a drift of 4 dB std drawn after them
    assert np.std(r1 - r0) == pytest.approx(4.0, rel=1e-9)


@settings(max_examples=60, deadline=None)
@given(
    key=st.sampled_from(["time_drift_db", "radial_db", "drift", "shadowing_db"]),
    value=st.one_of(
        st.floats(allow_nan=True, allow_infinity=True),
        st.text(max_size=3),
        st.none(),
        st.fixed_dictionaries(
            {
                "dist": st.sampled_from(["normal", "uniform", "bogus"]),
                "mean": st.floats(-5, 5),
                "sd": st.floats(0, 3),
                "lo": st.floats(-5, 5),
                "hi": st.floats(-5, 5),
            }
        ),
    ),
)
def test_generated_bad_nuisance_is_refused_naming_the_field(key: str, value: object) -> None:
    """Any nuisance either loads and draws a drift >= 0, or raises InputError naming the field."""
    try:
        fam = PhysicsFamily.from_dict(_with_nuisance({key: value}), source="gen.json")
    except InputError as e:
        assert "nuisance" in str(e) and "gen.json" in str(e)
    else:
        draw = fam.draw(np.random.default_rng(0))
        assert draw.time_drift_db >= 0 and draw.radial_db >= 0


def test_time_drift_std_finds_a_drift_over_time() -> None:
    rng = np.random.default_rng(2)
    t = np.arange(0.0, 600.0, 0.5)
    u = 2.0 * t / t[-1] - 1.0
    drift = 3.0 * (1.5 * u * u - 0.5) / np.std(1.5 * u * u - 0.5)  # P_2, 3 dB std
    flight = FlightSamples(
        enu_m=np.zeros((len(t), 3)), rss_dbm=np.zeros(len(t)), t_s=t, name="synthetic"
    )
    r = drift + rng.normal(0.0, 2.0, len(t))
    r[::7] = np.nan  # held-out residuals have gaps
    assert time_drift_std(flight, r) == pytest.approx(3.0, abs=0.25)
    # white noise alone: little drift (4 columns on 1200 samples)
    assert time_drift_std(flight, rng.normal(0.0, 2.0, len(t))) < 0.3


@pytest.mark.parametrize(
    ("p", "miss"),
    [(0.5, 0.0), (0.05, 0.0), (0.95, 0.0), (0.0, 1.0), (1.0, 1.0), (0.025, 0.5), (0.99, 0.8)],
)
def test_ppc_miss_table(p: float, miss: float) -> None:
    assert ppc_miss(p) == pytest.approx(miss)


@pytest.mark.parametrize(
    ("v", "iv", "miss"),
    [(5.0, (0.0, 10.0), 0.0), (-2.0, (0.0, 10.0), 0.2), (13.0, (0.0, 10.0), 0.3)],
)
def test_interval_miss_table(v: float, iv: tuple[float, float], miss: float) -> None:
    assert interval_miss(v, iv) == pytest.approx(miss)


def _loop(p90_sim: float, slope_mean: float) -> dict:
    return {
        "heldout_p90_db": {"real": 20.0, "sim": p90_sim},
        "params": {"path_gain_slope": {"refit_mean": slope_mean, "interval": [0.0, 2.0]}},
        "sill_db": {"sim": 10.0, "interval": [8.0, 12.0]},
        "range_m": {"sim": 30.0, "interval": [5.0, 75.0]},
        "passed": abs(p90_sim - 20.0) <= 1.0 and 0.0 <= slope_mean <= 2.0,
    }


def _ppc(ps: list[float]) -> dict:
    return {f"c{k}": {"p": p, "passes": 0.05 <= p <= 0.95} for k, p in enumerate(ps)}


def test_family_loss_weighs_both_groups() -> None:
    ok = family_loss(_loop(20.5, 1.0), _ppc([0.5] * 13))
    assert ok["loss"] == 0.0 and ok["ppc_failed"] == 0 and ok["loop_passed"] is True
    # one predictive check at p = 0 of 13: half the weight over 13 checks
    one = family_loss(_loop(20.5, 1.0), _ppc([0.0] + [0.5] * 12))
    assert one["loss"] == pytest.approx(0.5 / 13) and one["ppc_failed"] == 1
    # the p90 2 dB off (1 dB beyond the tolerance) among the 4 loop rules
    off = family_loss(_loop(22.0, 1.0), _ppc([0.5] * 13))
    assert off["loss"] == pytest.approx(0.5 * 1.0 / 4) and off["loop_passed"] is False
    # a missing group: the other carries the whole weight
    assert family_loss(None, _ppc([0.0, 0.5]))["loss"] == pytest.approx(0.5)
    assert family_loss(_loop(22.0, 1.0), None)["loss"] == pytest.approx(0.25)


def test_offset_is_drawn_from_the_real_flights_with_structure() -> None:
    off = {"mean": 68.8, "sd": 16.5, "per_flight": [77.0, 59.9, 56.9, 56.3, 94.1]}
    emp = offset_distribution(off, per_flight=True)
    assert emp == {"dist": "empirical", "values": [77.0, 59.9, 56.9, 56.3, 94.1]}
    fam = PhysicsFamily.from_dict({**load_family("afar").to_dict(), "offset_db": emp})
    drawn = {fam.draw(np.random.default_rng(s)).offset_db for s in range(60)}
    assert drawn == set(emp["values"])  # never beyond the real flights' offsets
    assert offset_distribution(off)["dist"] == "normal"


def _recalibration_steps(monkeypatch, sims: list[float], real: float) -> list:
    """The recalibration's (scale, simulated p90) steps when the loop checks read ``sims`` in turn
    against the real held-out p90 ``real`` (the family fit and the loop check stubbed)."""
    it = iter(sims)

    def fake_loop(rec, used, cfg, seed=0, repeats=1):
        p = next(it)
        return {
            "heldout_p90_db": {"real": real, "sim": p, "within_1db": abs(p - real) <= 1.0},
            "passed": False,
        }

    def fake_fit(flights, effects, cfg, **kw):
        return {"residual": {"shadowing_db": 10.0, "noise_db": 3.0}, "checks": {}}, []

    monkeypatch.setattr(fr, "loop_check", fake_loop)
    monkeypatch.setattr(fr, "fit_family", fake_fit)
    d = SimpleNamespace(flights=[], rungs=[SimpleNamespace(added=None)])
    return fr.family_from_diagnosis(d, FitConfig(), repeats=1)["residual_calibration"]["steps"]


def test_recalibration_never_steps_against_the_p90(monkeypatch) -> None:
    """Two noisy checks whose p90 falls as the shadowing grows: the next scale is the ratio step
    (more shadowing), not the secant's leap (it had reached -17.3 on the real flights)."""
    steps = _recalibration_steps(monkeypatch, [20.0, 19.99, 21.4], 21.5)
    k1 = 21.5 / 20.0
    assert steps[1][0] == pytest.approx(k1)
    assert steps[2][0] == pytest.approx(k1 * 21.5 / 19.99)  # up, by the ratio
    assert 0 < steps[2][0] <= k1 * fr.SECANT_LIMIT


@pytest.mark.parametrize(
    ("second", "ratio"),
    [(20.004, True), (21.5, False)],  # a rise of 0.004 dB is noise; one of 1.5 dB is a slope
)
def test_recalibration_takes_a_secant_only_from_a_rise_the_check_can_tell(
    monkeypatch, second: float, ratio: bool
) -> None:
    """Two checks whose p90 differ by less than the loop check's tolerance give no slope: a nearly
    flat secant leapt to the x1.5 limit (held-out p90 33.4 dB against the real 22.0 on the real
    flights), so the ratio step is taken; a rise the check can tell keeps the secant."""
    steps = _recalibration_steps(monkeypatch, [20.0, second, 21.4], 24.0)
    k0, k1 = 1.0, 24.0 / 20.0
    want = k1 * 24.0 / second if ratio else k1 + (24.0 - second) * (k1 - k0) / (second - 20.0)
    assert steps[2][0] == pytest.approx(want)
    assert steps[2][0] < k1 * fr.SECANT_LIMIT


def _ring_track(n: int = 1200) -> tuple[np.ndarray, np.ndarray]:
    """A track that goes out from near the rover to 400 m and back in six times, turning as it
    goes: every distance flown twelve times, at different times and headings."""
    k = np.linspace(0.0, 1.0, n)
    r = 15.0 + 385.0 * (0.5 - 0.5 * np.cos(12.0 * np.pi * k))
    a = 40.0 * np.pi * k
    rx = np.column_stack([r * np.cos(a), r * np.sin(a), np.full(n, 30.0)])
    return np.array([0.0, 0.0, 1.5]), rx


@pytest.mark.parametrize("std", [0.7, 4.0])
def test_radial_profile_has_its_std_and_depends_on_the_distance_only(std: float) -> None:
    """The profile is a function of the distance to the transmitter alone (the same at the same
    distance, whatever the heading or time), smooth in log distance, of the drawn std."""
    tx, rx = _ring_track()
    g = radial_profile(tx, rx, std, np.random.default_rng(3))
    assert np.std(g) == pytest.approx(std, rel=1e-9)
    # symmetric about the transmitter: the track's mirror image (out and back) gives the same values
    mirror = rx * np.array([-1.0, 1.0, 1.0])
    assert np.allclose(radial_profile(tx, mirror, std, np.random.default_rng(3)), g)
    u = log_distance_unit(np.hypot(rx[:, 0], rx[:, 1]))
    fit = np.polynomial.legendre.legval(u, np.polynomial.legendre.legfit(u, g, DRIFT_ORDER))
    assert np.max(np.abs(fit - g)) < 1e-9 * std
    assert not np.allclose(g, radial_profile(tx, rx, std, np.random.default_rng(4)))
    assert not radial_profile(tx, rx, 0.0, np.random.default_rng(3)).any()
    # all at one distance: nothing to vary over
    circle = np.column_stack(
        [100 * np.cos(np.arange(50)), 100 * np.sin(np.arange(50)), 30 * np.ones(50)]
    )
    assert not radial_profile(tx, circle, 3.0, np.random.default_rng(3)).any()


def test_log_distance_unit_spans_10_to_500_m() -> None:
    assert log_distance_unit(np.array([1.0, 10.0, 70.7, 500.0, 9e3])) == pytest.approx(
        [-1.0, np.log10(10 / 70.7) / 0.85, 0.0, 1.0, 1.0], abs=0.01
    )


def test_a_radial_draw_is_added_after_the_drift() -> None:
    """A draw with a radial std adds exactly ``radial_profile`` after the shadowing, noise and
    drift of the same draw without it."""
    tx, rx = _ring_track(400)
    att = np.zeros((400, 3))
    d0 = FamilyDraw({"base": "free-space"}, 3.0, 30.0, 1.0, 0.0, 2.0)
    d1 = FamilyDraw({"base": "free-space"}, 3.0, 30.0, 1.0, 0.0, 2.0, 5.0)
    r0 = simulate_rss(d0, tx, rx, att, np.random.default_rng(7))
    rng = np.random.default_rng(7)
    r1 = simulate_rss(d1, tx, rx, att, rng)
    assert np.std(r1 - r0) == pytest.approx(5.0, rel=1e-9)
    assert d1.to_dict()["radial_db"] == 5.0 and "radial_db" not in d0.to_dict()


def test_nuisance_stds_tell_distance_from_time() -> None:
    """On a track that flies every distance twice, a residual that follows the distance is given
    to the radial part, one that follows the time to the time part; fitted together, neither takes
    the other's; the time part alone is ``time_drift_std``."""
    tx, rx = _ring_track()
    t = np.arange(len(rx)) * 0.5
    flight = FlightSamples(
        enu_m=rx, rss_dbm=np.zeros(len(rx)), t_s=t, tx_enu_m=tx, name="synthetic"
    )
    rng = np.random.default_rng(5)
    radial = radial_profile(tx, rx, 4.0, np.random.default_rng(1))
    drift = time_drift(len(t), 3.0, np.random.default_rng(2))
    both = nuisance_stds(flight, radial + rng.normal(0, 2.0, len(t)), ("time", "radial"))
    assert both["radial_db"] == pytest.approx(4.0, abs=0.4) and both["time_drift_db"] < 0.8
    both = nuisance_stds(flight, drift + rng.normal(0, 2.0, len(t)), ("time", "radial"))
    assert both["time_drift_db"] == pytest.approx(3.0, abs=0.4) and both["radial_db"] < 0.8
    r = drift + radial
    assert nuisance_stds(flight, r, ("time",))["time_drift_db"] == time_drift_std(flight, r)
    assert nuisance_stds(flight, r, ()) == {}


def test_structure_kinds() -> None:
    assert structure_kinds(True) == ("time",) and structure_kinds(False) == ()
    assert structure_kinds(("time", "radial")) == ("time", "radial")
    with pytest.raises(ValueError, match="nuisance kind"):
        structure_kinds(("ground",))


def test_the_body_azimuth_of_the_rover_has_its_closed_form() -> None:
    """Level flight, nose north (yaw 0): a rover due north is at body azimuth 0, due east at 90
    deg (right), due west at 270; yawing the nose east by 90 deg turns the north rover to 270."""
    tx = np.array([0.0, 0.0, 0.0])
    rx = np.array([[0.0, -100.0, 30.0], [-100.0, 0.0, 30.0], [100.0, 0.0, 30.0]])
    level = np.zeros((3, 3))
    az = np.degrees(azimuth_coordinate(tx, rx, level))
    np.testing.assert_allclose(az, [0.0, 90.0, 270.0], atol=1e-9)
    east = np.tile([0.0, 0.0, np.pi / 2], (3, 1))
    np.testing.assert_allclose(np.degrees(azimuth_coordinate(tx, rx, east))[0], 270.0, atol=1e-9)


@pytest.mark.parametrize("std", [0.7, 4.0])
def test_azimuth_ripple_has_its_std_and_follows_the_body_azimuth_only(std: float) -> None:
    """The ripple is a function of the rover's body azimuth alone (equal wherever that azimuth is
    equal, whatever the distance), of the drawn std; zero std or one azimuth draws nothing."""
    tx, rx = _ring_track()
    att = np.zeros((len(rx), 3))
    att[:, 2] = np.linspace(0.0, 6 * np.pi, len(rx))
    g = azimuth_ripple(tx, rx, att, std, np.random.default_rng(3))
    assert np.std(g) == pytest.approx(std)
    az = azimuth_coordinate(tx, rx, att)
    order = np.argsort(az)
    assert np.max(np.abs(np.diff(g[order]))) < 0.1 * std * 40  # smooth in the azimuth
    assert not azimuth_ripple(tx, rx, att, 0.0, np.random.default_rng(3)).any()
    same = np.tile(rx[:1], (50, 1))
    assert not azimuth_ripple(tx, same, att[:50] * 0, 2.0, np.random.default_rng(3)).any()


def test_nuisance_stds_tell_the_body_azimuth_from_time_and_distance() -> None:
    """A ripple over the body azimuth is given to the azimuth part, not to the drift or the
    radial profile, on a track that turns its nose as it goes."""
    tx, rx = _ring_track()
    t = np.arange(len(rx)) * 0.5
    att = np.zeros((len(rx), 3))
    att[:, 2] = np.linspace(0.0, 14 * np.pi, len(rx))
    flight = FlightSamples(
        enu_m=rx, rss_dbm=np.zeros(len(rx)), t_s=t, tx_enu_m=tx, attitude_rad=att, name="s"
    )
    rng = np.random.default_rng(5)
    ripple = azimuth_ripple(tx, rx, att, 3.0, np.random.default_rng(4))
    kinds = ("time", "radial", "azimuth")
    got = nuisance_stds(flight, ripple + rng.normal(0, 2.0, len(t)), kinds)
    assert got["azimuth_db"] == pytest.approx(3.0, abs=0.4)
    assert got["time_drift_db"] < 0.8 and got["radial_db"] < 0.8
    no_att = FlightSamples(enu_m=rx, rss_dbm=np.zeros(len(rx)), t_s=t, tx_enu_m=tx, name="s")
    assert nuisance_stds(no_att, ripple, kinds)["azimuth_db"] == 0.0


def test_structure_of_the_command_line_flags() -> None:
    assert structure_of(False) is False and structure_of(True) is True
    assert structure_of(False, radial=True) == ("time", "radial")
    assert structure_of(False, azimuth=True) == ("time", "azimuth")
    assert structure_kinds(structure_of(False, True, True)) == ("time", "radial", "azimuth")

"""Shadowing drawn along the flight's path (``physics.shadowing.path_shadowing``) and families
that say ``shadowing_over: "path"``: the closed-form correlation along the track, independence on
a second pass over the same ground (where a ground field repeats), and the family plumbing."""

from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.stats import norm

from mission.adaptive.simflight import FlightWorld
from mission.errors import InputError
from mission.gap import familyfit, loopcheck
from mission.gap.familyfit import heldout_marginal
from mission.gap.fit import FitConfig
from mission.physics.family import FamilyDraw, PhysicsFamily, load_family, simulate_rss
from mission.physics.shadowing import (
    draw_shadowing,
    path_length,
    path_shadowing,
    quantile_mapped,
    shadowing_field,
    standardized_marginal,
)
from mission.samples import FlightSamples
from mission.spec import load_mission
from mission.workshop.suite import draw_flight
from mission.workshop.suite_family import resolve_family


def _line(n: int, step_m: float) -> np.ndarray:
    return np.column_stack([np.arange(n) * step_m, np.zeros(n), np.full(n, 30.0)])


def _circle_twice(n: int = 2000, radius_m: float = 100.0) -> np.ndarray:
    """A circle flown twice: sample k and k + n / 2 are at the same place, 628 m of path apart."""
    a = np.linspace(0.0, 4 * np.pi, n, endpoint=False)
    return np.column_stack([radius_m * np.cos(a), radius_m * np.sin(a), np.full(n, 30.0)])


def test_path_length_is_the_distance_flown() -> None:
    pos = np.array([[0.0, 0.0, 30.0], [3.0, 4.0, 31.0], [3.0, 4.0, 40.0], [0.0, 0.0, 30.0]])
    # horizontal only: a climb adds nothing
    assert path_length(pos).tolist() == [0.0, 5.0, 5.0, 10.0]
    assert path_length(np.zeros((0, 3))).size == 0


@pytest.mark.parametrize("corr_m", [10.0, 30.0])
def test_path_shadowing_has_the_gaussian_correlation_along_the_track(corr_m: float) -> None:
    """Over many draws, samples s metres apart along the track correlate by exp(-s^2 / L^2), and
    the std is sigma (the closed form of the Gaussian covariance the ground field also draws)."""
    pos = _line(400, 1.0)
    rng = np.random.default_rng(3)
    x = np.stack([path_shadowing(pos, 6.0, corr_m, rng) for _ in range(1500)])
    assert x.std() == pytest.approx(6.0, rel=0.05)
    i = 150
    for lag in (0.5 * corr_m, corr_m, 2.0 * corr_m):
        r = np.corrcoef(x[:, i], x[:, i + int(lag)])[0, 1]
        assert r == pytest.approx(np.exp(-((lag / corr_m) ** 2)), abs=0.06)


def test_a_second_pass_over_the_same_ground_is_independent_along_the_path() -> None:
    """The ground field repeats on the second lap; the path field does not (628 m >> L)."""
    pos = _circle_twice()
    n = len(pos) // 2
    rng = np.random.default_rng(5)
    ground = [shadowing_field(pos[:, :2], 8.0, 30.0, rng) for _ in range(40)]
    path = [path_shadowing(pos, 8.0, 30.0, rng) for _ in range(40)]
    lap = [np.corrcoef(g[:n], g[n:])[0, 1] for g in ground]
    assert np.mean(lap) > 0.95
    lap = [np.corrcoef(p[:n], p[n:])[0, 1] for p in path]
    assert abs(np.mean(lap)) < 0.1
    # within a lap the path field is correlated over its length as the ground field is
    step = float(np.hypot(*(pos[1, :2] - pos[0, :2])))
    k = int(round(15.0 / step))
    near = np.mean([np.corrcoef(p[:-k], p[k:])[0, 1] for p in path])
    assert near == pytest.approx(np.exp(-0.25), abs=0.1)


def test_draw_shadowing_dispatches_and_refuses_an_unknown_frame() -> None:
    pos = _circle_twice(300)
    g = draw_shadowing(pos, 5.0, 20.0, "ground", np.random.default_rng(1))
    assert np.array_equal(g, shadowing_field(pos[:, :2], 5.0, 20.0, np.random.default_rng(1)))
    p = draw_shadowing(pos, 5.0, 20.0, "path", np.random.default_rng(1))
    assert np.array_equal(p, path_shadowing(pos, 5.0, 20.0, np.random.default_rng(1)))
    with pytest.raises(ValueError, match="sky"):
        draw_shadowing(pos, 5.0, 20.0, "sky", np.random.default_rng(1))
    rng = np.random.default_rng(2)
    assert not path_shadowing(pos, 0.0, 20.0, rng).any()
    assert rng.standard_normal() == np.random.default_rng(2).standard_normal()  # none taken
    with pytest.raises(ValueError, match="> 0"):
        path_shadowing(pos, 5.0, 0.0, rng)


def _path_family() -> dict:
    d = load_family("afar").to_dict()
    d["shadowing_over"] = "path"
    return d


def test_a_path_family_draws_as_the_ground_family_but_for_where_the_shadowing_lives() -> None:
    ground = load_family("afar")
    path = PhysicsFamily.from_dict(_path_family())
    assert path.to_dict()["shadowing_over"] == "path" and "shadowing_over" not in ground.to_dict()
    for seed in range(4):
        a, b = ground.draw(np.random.default_rng(seed)), path.draw(np.random.default_rng(seed))
        assert b.shadowing_over == "path" and a.shadowing_over == "ground"
        assert a.to_dict() == {k: v for k, v in b.to_dict().items() if k != "shadowing_over"}
    # simulated RSS: the same model, offset and noise; only the shadowing term differs
    pos, att, tx = _circle_twice(400), np.zeros((400, 3)), np.array([10.0, 20.0, 1.5])
    d_g = FamilyDraw({"base": "free-space"}, 6.0, 30.0, 0.0, 0.0)
    d_p = FamilyDraw({"base": "free-space"}, 6.0, 30.0, 0.0, 0.0, shadowing_over="path")
    flat = FamilyDraw({"base": "free-space"}, 0.0, 30.0, 0.0, 0.0)
    base = simulate_rss(flat, tx, pos, att, np.random.default_rng(0))
    diff_g = simulate_rss(d_g, tx, pos, att, np.random.default_rng(9)) - base
    diff_p = simulate_rss(d_p, tx, pos, att, np.random.default_rng(9)) - base
    assert np.allclose(diff_g, shadowing_field(pos[:, :2], 6.0, 30.0, _after_noise(9, 400)))
    assert np.allclose(diff_p, path_shadowing(pos, 6.0, 30.0, _after_noise(9, 400)))


def _after_noise(seed: int, n: int) -> np.random.Generator:
    """The generator ``simulate_rss`` hands the shadowing: after its white noise of ``n`` draws."""
    rng = np.random.default_rng(seed)
    rng.normal(0.0, 0.0, size=n)
    return rng


@settings(max_examples=40, deadline=None)
@given(value=st.one_of(st.text(max_size=6), st.integers(), st.none(), st.booleans()))
def test_generated_bad_shadowing_frames_are_refused_naming_the_field(value: object) -> None:
    d = _path_family()
    d["shadowing_over"] = value
    if value in ("ground", "path"):
        assert PhysicsFamily.from_dict(d).shadowing_over == value
        return
    with pytest.raises(InputError) as e:
        PhysicsFamily.from_dict(d, source="gen.json")
    assert "shadowing_over" in str(e.value) and "gen.json" in str(e.value)


def test_the_benchmark_cache_draws_a_path_family_along_the_path(tmp_path) -> None:
    f = tmp_path / "path.json"
    f.write_text(json.dumps(_path_family()))
    d, _ = draw_flight(2026, 3, str(f))
    assert d["shadowing_over"] == "path"
    d0, _ = draw_flight(2026, 3, "afar")
    assert "shadowing_over" not in d0


def test_the_fast_simulator_refuses_a_path_family() -> None:
    spec = load_mission("missions/spiral.yaml")
    fam = PhysicsFamily.from_dict(_path_family())
    with pytest.raises(InputError, match="along the path"):
        FlightWorld(spec, fam, np.random.default_rng(0))


# --- the shadowing's shape (``shadowing_marginal``) ---------------------------------------------


def _gaussian_marginal(levels: int = 41):
    p = np.linspace(0.005, 0.995, levels)
    return tuple(p.tolist()), tuple(norm.ppf(p).tolist())


def test_a_gaussian_marginal_maps_a_gaussian_draw_to_itself() -> None:
    x = np.random.default_rng(0).normal(0.0, 7.0, 5000)
    y = quantile_mapped(x, 7.0, _gaussian_marginal(201))
    inner = np.abs(x) < 7.0 * norm.ppf(0.99)  # held beyond the last level
    assert np.allclose(y[inner], x[inner], atol=0.05)  # linear between levels


def test_quantile_mapping_keeps_the_ranks_and_takes_the_marginal() -> None:
    """A Gaussian draw mapped to a skewed marginal: the same order of samples, and the quantiles
    of the marginal times sigma."""
    rng = np.random.default_rng(1)
    fades = np.concatenate([rng.normal(0, 1, 20000), -rng.exponential(3.0, 4000)])
    p, q = standardized_marginal(fades)
    assert np.mean(q) == pytest.approx(0.0, abs=0.05) and q[0] < -2 * q[-1] < 0
    x = rng.normal(0.0, 5.0, 20000)
    y = quantile_mapped(x, 5.0, (p, q))
    assert np.all(np.diff(y[np.argsort(x)]) >= 0)  # the order of the samples is kept
    for level in (0.05, 0.25, 0.5, 0.75, 0.95):
        assert np.quantile(y, level) == pytest.approx(
            5.0 * np.interp(level, p, q), rel=0.05, abs=0.1
        )


def test_standardized_marginal_has_mean_0_and_std_1() -> None:
    r = np.random.default_rng(2).gamma(2.0, 3.0, 50000) + 40.0
    p, q = standardized_marginal(np.append(r, np.nan))
    assert len(p) == len(q) == 41 and p[0] == 0.005 and p[-1] == 0.995
    z = (r - r.mean()) / r.std()
    assert q[20] == pytest.approx(np.median(z), abs=1e-3)
    assert np.all(np.diff(q) >= 0)


def test_a_family_with_a_marginal_draws_the_same_and_maps_its_shadowing() -> None:
    d = _path_family()
    d["shadowing_marginal"] = {"p": [0.01, 0.5, 0.99], "q": [-3.0, 0.1, 1.0]}
    fam = PhysicsFamily.from_dict(d)
    a = fam.draw(np.random.default_rng(4))
    b = PhysicsFamily.from_dict(_path_family()).draw(np.random.default_rng(4))
    assert a.shadowing_marginal == ((0.01, 0.5, 0.99), (-3.0, 0.1, 1.0))
    assert {k: v for k, v in a.to_dict().items() if k != "shadowing_marginal"} == b.to_dict()
    assert PhysicsFamily.from_dict(fam.to_dict()).shadowing_marginal == a.shadowing_marginal
    pos, att, tx = _circle_twice(400), np.zeros((400, 3)), np.array([10.0, 20.0, 1.5])
    flat = FamilyDraw({"base": "free-space"}, 0.0, 30.0, 0.0, 0.0)
    base = simulate_rss(flat, tx, pos, att, np.random.default_rng(0))
    m = a.shadowing_marginal
    drawn = FamilyDraw({"base": "free-space"}, 6.0, 30.0, 0.0, 0.0, shadowing_marginal=m)
    got = simulate_rss(drawn, tx, pos, att, np.random.default_rng(9)) - base
    want = quantile_mapped(shadowing_field(pos[:, :2], 6.0, 30.0, _after_noise(9, 400)), 6.0, m)
    assert np.allclose(got, want)
    assert got.max() <= 6.0 * 1.0 + 1e-9 and got.min() >= -18.0 - 1e-9


@settings(max_examples=60, deadline=None)
@given(
    value=st.one_of(
        st.none(),
        st.text(max_size=4),
        st.lists(st.floats(allow_nan=True, allow_infinity=True), max_size=4),
        st.fixed_dictionaries(
            {
                "p": st.lists(st.floats(allow_nan=True, allow_infinity=True), max_size=5),
                "q": st.lists(st.floats(allow_nan=True, allow_infinity=True), max_size=5),
            }
        ),
    )
)
def test_generated_bad_marginals_are_refused_naming_the_field(value: object) -> None:
    """A marginal either loads as an increasing p in (0, 1) with a non-decreasing q, or raises
    ``InputError`` naming ``shadowing_marginal`` and the file."""
    d = _path_family()
    d["shadowing_marginal"] = value
    try:
        fam = PhysicsFamily.from_dict(d, source="gen.json")
    except InputError as e:
        assert "shadowing_marginal" in str(e) and "gen.json" in str(e)
        return
    if value is None:
        assert fam.shadowing_marginal is None
        return
    p, q = (np.asarray(x) for x in fam.shadowing_marginal)
    assert len(p) >= 3 and 0 < p[0] and p[-1] < 1 and (np.diff(p) > 0).all()
    assert (np.diff(q) >= 0).all() and np.isfinite(q).all()


def test_the_fitted_marginal_pools_the_flights_standardized(tmp_path) -> None:
    rng = np.random.default_rng(3)
    fits = [
        SimpleNamespace(heldout=np.append(-rng.exponential(s, 3000) + 9.0, np.nan), excluded="")
        for s in (2.0, 8.0)
    ]
    m = heldout_marginal(fits)
    # both flights are one shape (an exponential's mirror image) at two scales
    p, q = standardized_marginal(-rng.exponential(1.0, 200000))
    assert np.allclose(m["q"], q, atol=0.08) and m["p"] == list(p)


def test_the_benchmark_cache_and_the_fast_simulator_take_the_marginal(tmp_path) -> None:
    d = load_family("afar").to_dict()
    d["shadowing_marginal"] = {"p": [0.01, 0.5, 0.99], "q": [-3.0, 0.1, 1.0]}
    f = tmp_path / "fades.json"
    f.write_text(json.dumps(d))
    flight, _ = draw_flight(2026, 3, str(f))
    assert flight["shadowing_marginal"] == d["shadowing_marginal"]
    assert "shadowing_over" not in flight
    world = FlightWorld(load_mission("missions/spiral.yaml"), PhysicsFamily.from_dict(d), _rng())
    plain = FlightWorld(load_mission("missions/spiral.yaml"), load_family("afar"), _rng())
    sigma = world.draw.shadowing_db
    grid = plain._shadow.values
    assert np.allclose(
        world._shadow.values, quantile_mapped(grid, sigma, world.draw.shadowing_marginal)
    )


def _rng() -> np.random.Generator:
    return np.random.default_rng(11)


def test_copy_parts_adds_up_to_the_family_copy(repo_dir, monkeypatch) -> None:
    """``benchmarks/copy_parts.py``: the parts of a draw, with every part in, are ``simulate_rss``'s
    copy bit for bit (path, fades and a drift included), and each part is what it says."""
    monkeypatch.syspath_prepend(str(repo_dir / "benchmarks"))
    # a script, importable once its folder is on sys.path (the line above)
    import copy_parts  # noqa: PLC0415

    d = _path_family()
    d["shadowing_marginal"] = {"p": [0.01, 0.5, 0.99], "q": [-3.0, 0.1, 1.0]}
    d["nuisance"] = {"time_drift_db": 3.0}
    draw = PhysicsFamily.from_dict(d).draw(np.random.default_rng(1))
    pos, tx = _circle_twice(500), np.array([10.0, 20.0, 1.5])
    att = np.zeros((500, 3))
    parts = copy_parts.family_parts(draw, tx, pos, att, np.random.default_rng(5))
    assert np.array_equal(
        parts["family: all"], simulate_rss(draw, tx, pos, att, np.random.default_rng(5))
    )
    drift = parts["family: + drift"] - parts["family: model + noise"]
    shadow = parts["family: + shadowing"] - parts["family: model + noise"]
    assert np.std(drift) == pytest.approx(3.0, rel=1e-6)
    assert np.allclose(parts["family: all"] - parts["family: model + noise"], drift + shadow)
    assert np.max(shadow) <= draw.shadowing_db * 1.0 + 1e-9  # the fades' top quantile


# --- the shadowing's covariance (``shadowing_covariance``) ---------------------------------------


def test_an_exponential_field_has_its_closed_form_correlation_on_the_ground() -> None:
    """Over many draws, points h apart correlate by exp(-h / L) (rough), where the Gaussian field
    gives exp(-h^2 / L^2) (smooth): at h = L / 4 the two differ by 0.16."""
    L = 40.0
    pts = np.array([[0.0, 0.0, 30.0], [L / 4, 0.0, 30.0], [L, 0.0, 30.0], [3 * L, 0.0, 30.0]])
    rng = np.random.default_rng(12)
    x = np.stack(
        [draw_shadowing(pts, 5.0, L, "ground", rng, covariance="exponential") for _ in range(3000)]
    )
    assert x.std() == pytest.approx(5.0, rel=0.06)
    for j, h in ((1, L / 4), (2, L), (3, 3 * L)):
        assert np.corrcoef(x[:, 0], x[:, j])[0, 1] == pytest.approx(np.exp(-h / L), abs=0.06)


def test_an_exponential_path_is_a_first_order_autoregression_along_the_track() -> None:
    pos = _line(400, 1.0)
    rng = np.random.default_rng(13)
    x = np.stack(
        [path_shadowing(pos, 4.0, 20.0, rng, covariance="exponential") for _ in range(1500)]
    )
    for lag in (5, 20, 40):
        r = np.corrcoef(x[:, 100], x[:, 100 + lag])[0, 1]
        assert r == pytest.approx(np.exp(-lag / 20.0), abs=0.07)


def test_a_family_with_an_exponential_covariance_draws_the_same_and_refuses_others() -> None:
    d = load_family("afar").to_dict()
    d["shadowing_covariance"] = "exponential"
    fam = PhysicsFamily.from_dict(d)
    a, b = fam.draw(np.random.default_rng(3)), load_family("afar").draw(np.random.default_rng(3))
    assert a.shadowing_covariance == "exponential" and b.shadowing_covariance == "gaussian"
    assert {k: v for k, v in a.to_dict().items() if k != "shadowing_covariance"} == b.to_dict()
    assert PhysicsFamily.from_dict(fam.to_dict()).shadowing_covariance == "exponential"
    flight, _ = draw_flight(2026, 1, fam)
    assert flight["shadowing_covariance"] == "exponential"
    for bad in ("matern", 1, None, ["exponential"]):
        d["shadowing_covariance"] = bad
        with pytest.raises(InputError) as e:
            PhysicsFamily.from_dict(d, source="bad.json")
        assert "shadowing_covariance" in str(e.value) and "bad.json" in str(e.value)
    with pytest.raises(ValueError, match="covariance"):
        draw_shadowing(
            _line(10, 1.0), 1.0, 5.0, "ground", rng=np.random.default_rng(0), covariance="matern"
        )


def test_the_family_fit_and_its_loop_check_use_the_family_s_covariance(monkeypatch) -> None:
    """The variogram of every per-flight fit, the family's and the loop check's re-fit alike, is of
    the covariance the family records (else the loop check compares two kinds of range)."""
    seen = []
    real = familyfit.fit_variogram

    def spy(*args, **kw):
        seen.append(kw["kind"])
        return real(*args, **kw)

    monkeypatch.setattr(familyfit, "fit_variogram", spy)
    rng = np.random.default_rng(0)
    n = 400
    t = np.arange(n) * 0.5
    enu = np.column_stack([60 * np.cos(t / 20), 60 * np.sin(t / 20), np.full(n, 30.0)])
    flight = FlightSamples(
        enu, rng.normal(-60, 4, n), np.zeros((n, 3)), t, tx_enu_m=np.array([0.0, 0.0, 1.5])
    )
    vg = familyfit.residual_variogram(flight, rng.normal(0, 3, n), rng, "exponential")
    assert seen == ["exponential"] and vg["shadowing_corr_m"] > 0

    asked = []

    def stop(*args, **kw):
        asked.append(kw.get("covariance"))
        raise RuntimeError("stop here")

    monkeypatch.setattr(loopcheck, "fit_family", stop)
    record = load_family("afar").to_dict() | {"shadowing_covariance": "exponential"}
    with pytest.raises(RuntimeError, match="stop here"):
        loopcheck.loop_check(record, [flight], FitConfig(), seed=0, repeats=1)
    assert asked == ["exponential"]


def test_the_shipped_fades_family_is_the_rough_fades_fit() -> None:
    """``afar-fades`` (issue 34's family, mission/gap/README.md "Rough fades on the ground"): on
    the ground, exponential, with the fades' shape (a long lower tail), its loop check passed; the
    benchmark cache and ``load_family`` both know it by name, and ``afar`` is unchanged."""
    fam = load_family("afar-fades")
    assert fam.shadowing_over == "ground" and fam.shadowing_covariance == "exponential"
    p, q = fam.shadowing_marginal
    assert q[0] < -3.0 < -1.5 * q[-1] and abs(np.mean(q)) < 0.1
    assert fam.record["checks"]["loop"]["passed"] is True
    assert fam.nuisance["time_drift_db"]["mean"] > 0
    assert isinstance(resolve_family("afar-fades"), PhysicsFamily)
    flight, _ = draw_flight(2026, 0, "afar-fades")
    assert flight["shadowing_covariance"] == "exponential" and "shadowing_marginal" in flight
    shipped = load_family("afar")
    assert shipped.shadowing_covariance == "gaussian" and shipped.shadowing_marginal is None

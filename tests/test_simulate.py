"""Fast flight simulator: reproducible from a seed, consistent with the model, and its CLI."""

from __future__ import annotations

import numpy as np
import pytest

from mission.cli.main import main
from mission.flightlog import read_flight_log
from mission.physics import make_model
from mission.physics.shadowing import pdist
from mission.simulate import SimConfig, shadowing_field, simulate_flight
from mission.spec import load_mission


@pytest.fixture(scope="module")
def spiral(repo_dir):
    return load_mission(repo_dir / "missions" / "spiral.yaml")


def test_same_seed_same_bytes_and_other_seed_differs(spiral):
    model = make_model("e2r")
    tx = np.array([100.0, 200.0, 1.5])
    a = simulate_flight(spiral.waypoints_enu(), tx, model, SimConfig(), np.random.default_rng(7))
    b = simulate_flight(spiral.waypoints_enu(), tx, model, SimConfig(), np.random.default_rng(7))
    c = simulate_flight(spiral.waypoints_enu(), tx, model, SimConfig(), np.random.default_rng(8))
    assert a.rss_dbm.tobytes() == b.rss_dbm.tobytes()
    assert a.attitude_rad.tobytes() == b.attitude_rad.tobytes()
    assert not np.array_equal(a.rss_dbm, c.rss_dbm)


def test_sampling_period_and_perturbation_range(spiral):
    cfg = SimConfig(dt_s=0.03)
    f = simulate_flight(
        spiral.waypoints_enu(),
        np.array([50.0, 150.0, 1.5]),
        make_model("two-ray"),
        cfg,
        np.random.default_rng(1),
    )
    assert np.allclose(np.diff(f.t_s), 0.03)
    assert len(f.t_s) == pytest.approx(f.profile.duration_s / 0.03, abs=2)
    # roll in steady cruise is the perturbation alone: uniform in +-5 deg, all of that range used
    roll = np.rad2deg(f.attitude_rad[:, 0])
    assert roll.max() > 4.0 and roll.min() < -4.0
    assert np.percentile(np.abs(roll), 50) < 5.0


def test_noise_free_rss_equals_model_at_logged_geometry(spiral):
    cfg = SimConfig(noise_db=0.0)
    tx = np.array([120.0, 180.0, 1.5])
    model = make_model("e2r")
    f = simulate_flight(spiral.waypoints_enu(), tx, model, cfg, np.random.default_rng(2))
    again = model.rss_dbm(tx, f.enu_m, f.attitude_rad)
    assert np.max(np.abs(again - f.rss_dbm)) < 1e-9
    # noise is zero-mean with the configured standard deviation
    g = simulate_flight(
        spiral.waypoints_enu(), tx, model, SimConfig(noise_db=1.0), np.random.default_rng(2)
    )
    resid = g.rss_dbm - f.rss_dbm
    assert abs(resid.mean()) < 0.05 and resid.std() == pytest.approx(1.0, abs=0.05)


@pytest.mark.parametrize("name", ["free-space", "two-ray"])
def test_noise_free_rss_equals_closed_form(spiral, name):
    """Independent reference: Friis / paper eq. 1 written out here (vertical dipoles at both ends,
    Fresnel Gamma for vertical polarisation over eps_r = 2 ground) at the logged positions, not the
    library's kernel."""
    tx = np.array([120.0, 180.0, 1.5])
    f = simulate_flight(
        spiral.waypoints_enu(),
        tx,
        make_model(name),
        SimConfig(noise_db=0.0),
        np.random.default_rng(3),
    )
    lam = 299_792_458.0 / 3.32e9
    k = 2.0 * np.pi / lam
    h_t, h_r = tx[2], f.enu_m[:, 2]
    d = np.hypot(f.enu_m[:, 0] - tx[0], f.enu_m[:, 1] - tx[1])
    d_los, d_ref = np.hypot(d, h_r - h_t), np.hypot(d, h_r + h_t)

    # G_0 (cos(pi/2 sin el) / cos el)^2, floor -40 dBi
    def dipole(
        sin_el: np.ndarray,
    ) -> np.ndarray:
        return np.maximum(1.641 * (np.cos(0.5 * np.pi * sin_el) ** 2 / (1.0 - sin_el**2)), 1e-4)

    # both ends see the same |elevation|, so sqrt(G_t G_r) = G(el)
    field = dipole((h_r - h_t) / d_los) / d_los * np.exp(-1j * k * d_los)
    if name == "two-ray":
        s = (h_r + h_t) / d_ref  # sin of the grazing angle
        root = np.sqrt(2.0 - (1.0 - s**2))
        gamma = (2.0 * s - root) / (2.0 * s + root)
        field = field + gamma * dipole(s) / d_ref * np.exp(-1j * k * d_ref)
    want = 41.0 + 20.0 * np.log10(lam / (4.0 * np.pi) * np.abs(field))
    assert np.max(np.abs(f.rss_dbm - want)) < 2e-3  # float32 kernel: ~5e-4 dB at worst


def test_strongest_sample_lies_near_the_transmitter(spiral):
    tx = np.array([150.0, 150.0, 1.5])
    f = simulate_flight(
        spiral.waypoints_enu(),
        tx,
        make_model("free-space", pattern="isotropic"),
        SimConfig(noise_db=0.0, attitude_perturbation_deg=0.0),
        np.random.default_rng(0),
    )
    best = f.enu_m[np.argmax(f.rss_dbm)]
    # the spiral's rings are ~20 m apart: its closest pass is within half that of any point of the
    # overlap
    assert np.linalg.norm(best[:2] - tx[:2]) < 15.0


def test_cli_writes_a_readable_log_with_truth(tmp_path, repo_dir):
    rc = main(
        [
            "simulate",
            str(repo_dir / "missions" / "spiral.yaml"),
            "--source",
            "60,200",
            "--seed",
            "5",
            "--cruise-only",
            "--out",
            str(tmp_path),
        ]
    )
    assert rc == 0
    (csv,) = tmp_path.glob("*.csv")
    log = read_flight_log(csv)
    assert np.allclose(log.truth_enu, [60, 200, 1.5], atol=1e-3)
    assert log.meta["rss_source"] == {
        **log.meta["rss_source"],
        "kind": "sim",
        "model": "e2r",
        "seed": 5,
    }
    assert np.allclose(log.enu()[:, 2], 30.0, atol=1e-3)  # cruise only: all at 30 m
    # writing the same flight again would overwrite it: refused
    assert (
        main(
            [
                "simulate",
                str(repo_dir / "missions" / "spiral.yaml"),
                "--source",
                "60,200",
                "--seed",
                "5",
                "--cruise-only",
                "--out",
                str(tmp_path),
            ]
        )
        == 2
    )


def test_cli_bad_source_is_one_line_exit_2(tmp_path, repo_dir, capsys):
    """In process (the exit code of ``rfsl`` is what ``main`` returns: test_cli_main runs the
    subprocess)."""
    mission = str(repo_dir / "missions" / "spiral.yaml")
    assert main(["simulate", mission, "--source", "1,x", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "--source" in err and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1 and not list(tmp_path.iterdir())


def test_shadowing_field_statistics_and_revisits():
    """The shadowing field has the asked std, correlation exp(-d^2/corr^2) (1/e at corr), the same
    value when a place is revisited, a fresh field per draw, and nothing at sigma 0."""
    rng = np.random.default_rng(3)
    corr = 30.0
    x = np.linspace(0.0, 300.0, 301)
    xy = np.stack([x, np.full_like(x, 150.0)], axis=1)
    fields = np.array([shadowing_field(xy, 6.0, corr, rng) for _ in range(300)])
    assert fields.std() == pytest.approx(6.0, rel=0.1)
    z = (fields - fields.mean()) / fields.std()
    for lag, want in ((15, np.exp(-0.25)), (30, np.exp(-1.0)), (90, 0.0)):
        got = float(np.mean(z[:, :-lag] * z[:, lag:]))
        assert got == pytest.approx(want, abs=0.08), lag
    twice = np.concatenate([xy[:50], xy[:50]])
    f = shadowing_field(twice, 6.0, corr, np.random.default_rng(1))
    assert np.array_equal(f[:50], f[50:])
    assert not np.array_equal(f, shadowing_field(twice, 6.0, corr, np.random.default_rng(2)))
    assert np.all(shadowing_field(xy, 0.0, corr, rng) == 0.0)
    with pytest.raises(ValueError):
        shadowing_field(xy, 6.0, 0.0, rng)


def test_shadowing_off_keeps_the_bytes_of_the_plain_simulator(spiral):
    model = make_model("e2r")
    tx = np.array([100.0, 200.0, 1.5])
    a = simulate_flight(spiral.waypoints_enu(), tx, model, SimConfig(), np.random.default_rng(7))
    b = simulate_flight(
        spiral.waypoints_enu(),
        tx,
        model,
        SimConfig(shadowing_db=0.0, shadowing_corr_m=5.0),
        np.random.default_rng(7),
    )
    c = simulate_flight(
        spiral.waypoints_enu(), tx, model, SimConfig(shadowing_db=6.0), np.random.default_rng(7)
    )
    assert a.rss_dbm.tobytes() == b.rss_dbm.tobytes()
    d = c.rss_dbm - a.rss_dbm
    # smooth along the path, not white noise
    assert 3.0 < d.std() < 9.0 and np.abs(np.diff(d)).max() < 1.0


def test_pdist_is_the_euclidean_distance_bit_for_bit() -> None:
    """``pdist`` (the kriged fields' distances, column by column) gives each pair's Euclidean
    distance, exactly what the (N, M, D) broadcast gives, is symmetric and zero on the diagonal."""
    rng = np.random.default_rng(3)
    for dims in (2, 3):
        a, b = rng.normal(0.0, 300.0, (57, dims)), rng.normal(0.0, 300.0, (31, dims))
        d = a[:, None, :] - b[None, :, :]
        assert np.array_equal(pdist(a, b), np.sqrt((d * d).sum(-1)))
        np.testing.assert_allclose(pdist(a, b)[4, 7], np.linalg.norm(a[4] - b[7]), rtol=1e-15)
        aa = pdist(a, a)
        assert np.array_equal(aa, aa.T) and np.all(np.diag(aa) == 0.0)
    assert pdist(np.zeros((0, 2)), np.ones((3, 2))).shape == (0, 3)

"""Dataset generation: determinism (same seed, same bytes, any worker count or chunk size),
chunking, manifest, reading back, and the CLI's error handling."""

from __future__ import annotations

import hashlib
import json
from dataclasses import replace

import numpy as np
import pytest

from mission.cli.main import main
from mission.physics.presets import build_model, load_preset
from mission.workshop.dataset import (
    DatasetConfig,
    FlightSimulator,
    Randomisation,
    flight_rng,
    generate_dataset,
    load_dataset,
    read_manifest,
)
from mission.workshop.domain import training_attitude

# short flights (a random fifth of a random-waypoint cruise) keep the tests fast
FAST = Randomisation(
    trajectories=("random_waypoints", "spiral"),
    random_params=True,
    truncate=(0.15, 0.25),
    altitude_m=(20.0, 47.0),
    offset_db=(-20.0, 20.0),
    tx_height_m=(1.5, 5.0),
)


def _cfg(repo_dir, n=6, chunk=4, seed=5, randomisation=FAST, **kw) -> DatasetConfig:
    return DatasetConfig(
        str(repo_dir / "missions" / "spiral.yaml"),
        n,
        seed=seed,
        chunk=chunk,
        features=("clustering",),
        randomisation=randomisation,
        **kw,
    )


def _digest(d) -> dict[str, str]:
    arrays, _ = load_dataset(d, ("clustering", "tx_enu", "params", "n_samples", "index"))
    return {k: hashlib.sha256(v.tobytes()).hexdigest() for k, v in arrays.items()}


def test_same_seed_same_bytes_any_workers_and_chunks(tmp_path, repo_dir):
    a = generate_dataset(_cfg(repo_dir), tmp_path / "a", workers=1)
    b = generate_dataset(_cfg(repo_dir), tmp_path / "b", workers=2)
    assert [c["sha256"] for c in a["chunks"]] == [c["sha256"] for c in b["chunks"]]
    generate_dataset(_cfg(repo_dir, chunk=5), tmp_path / "c", workers=2)
    assert _digest(tmp_path / "a") == _digest(tmp_path / "c")
    generate_dataset(_cfg(repo_dir, seed=6), tmp_path / "d", workers=1)
    assert _digest(tmp_path / "a")["tx_enu"] != _digest(tmp_path / "d")["tx_enu"]


def test_chunks_manifest_and_contents(tmp_path, repo_dir):
    m = generate_dataset(_cfg(repo_dir, n=5, chunk=2), tmp_path / "ds", workers=1)
    assert [c["n"] for c in m["chunks"]] == [2, 2, 1]
    assert sorted(p.name for p in (tmp_path / "ds").glob("chunk_*.npz")) == [
        c["file"] for c in m["chunks"]
    ]
    mf = read_manifest(tmp_path / "ds")
    assert mf["config"]["seed"] == 5 and mf["config"]["randomisation"]["truncate"] == [0.15, 0.25]
    assert mf["feature_config"]["c_k"] == 20 and "lat_deg" in mf["field_origin"]
    json.dumps(mf)
    arrays, _ = load_dataset(
        tmp_path / "ds", ("clustering", "tx_enu", "params", "index"), verify=True
    )
    assert arrays["clustering"].shape == (5, 60) and arrays["clustering"].dtype == np.float32
    assert np.array_equal(arrays["index"], np.arange(5))
    spec_rover = (-30.0, 90.0, 260.0, 385.0)
    assert np.all(
        (arrays["tx_enu"][:, 0] > spec_rover[0]) & (arrays["tx_enu"][:, 1] > spec_rover[1])
    )
    assert np.all((arrays["tx_enu"][:, 2] >= 1.5) & (arrays["tx_enu"][:, 2] <= 5.0))
    alt = arrays["params"][:, mf["param_names"].index("altitude_m")]
    assert np.all((alt >= 20) & (alt <= 47))
    # offset invariance of the stored features: the RSS of the strongest cluster is relative (<= 0
    # dB)
    assert np.all(arrays["clustering"][:, 0] <= 0.0)
    with pytest.raises(ValueError, match="digest"):
        (tmp_path / "ds" / "chunk_00001.npz").write_bytes(b"x" * 10)
        load_dataset(tmp_path / "ds", ("clustering",), verify=True)


def test_flight_seed_is_the_spawned_child():
    child = np.random.SeedSequence(42).spawn(5)[3]
    assert np.array_equal(
        flight_rng(42, 3).integers(1 << 30, size=4),
        np.random.default_rng(child).integers(1 << 30, size=4),
    )


def test_cli_dataset_and_bad_input(tmp_path, repo_dir, capsys):
    mission = str(repo_dir / "missions" / "spiral.yaml")
    rc = main(
        [
            "dataset",
            mission,
            "--n",
            "2",
            "--seed",
            "1",
            "--out",
            str(tmp_path / "ds"),
            "--workers",
            "1",
            "--features",
            "clustering",
            "--trajectories",
            "random_waypoints",
            "--random-params",
            "--truncate",
            "0.1,0.2",
        ]
    )
    assert rc == 0 and (tmp_path / "ds" / "manifest.json").exists()
    # exists already
    assert main(["dataset", mission, "--n", "2", "--out", str(tmp_path / "ds")]) == 2
    assert (
        main(
            [
                "dataset",
                mission,
                "--n",
                "2",
                "--out",
                str(tmp_path / "x"),
                "--trajectories",
                "zigzag",
            ]
        )
        == 2
    )
    assert "zigzag" in capsys.readouterr().err


def test_new_randomisations_switched_off_keep_the_old_draws(repo_dir):
    """Items added later draw only when switched on: a zero-probability fixed heading, no speed
    range and no shadowing leave every flight's bytes as before."""
    base = FlightSimulator(_cfg(repo_dir)).draw(3).samples
    same = (
        FlightSimulator(_cfg(repo_dir, randomisation=replace(FAST, fixed_heading=0.0)))
        .draw(3)
        .samples
    )
    assert base.rss_dbm.tobytes() == same.rss_dbm.tobytes()
    assert np.array_equal(base.tx_enu_m, same.tx_enu_m)


def test_fixed_heading_speed_and_shadowing_reach_the_flight(repo_dir):
    r = replace(
        FAST,
        fixed_heading=1.0,
        speed_mps=(3.0, 3.0),
        shadowing_db=(6.0, 6.0),
        shadowing_corr_m=(20, 20),
    )
    fd = FlightSimulator(_cfg(repo_dir, randomisation=r)).draw(2)
    yaw = np.rad2deg(fd.samples.attitude_rad[:, 2])
    assert (
        np.ptp(np.rad2deg(np.angle(np.exp(1j * np.deg2rad(yaw - fd.params["fixed_heading_deg"])))))
        <= 10.01
    )
    assert fd.params["speed_mps"] == 3.0 and fd.params["shadowing_db"] == 6.0
    step = np.linalg.norm(np.diff(fd.samples.enu_m[:, :2], axis=0), axis=1) / 0.03
    assert step.max() <= 3.0 + 1e-6


def test_drag_pitch_tilts_the_cruise_and_is_recorded(repo_dir):
    """``drag_pitch_deg_per_mps`` reaches the vehicle: the steady cruise pitch follows
    atan(tan(k) v) nose down (about -28 deg for 5.6 deg per m/s at 5.5 m/s, as PX4 SITL flies), the
    flight records its draw, and switched off the flight keeps its old bytes."""
    spiral = Randomisation()  # the mission's own spiral at 5.5 m/s
    base = FlightSimulator(_cfg(repo_dir, randomisation=spiral)).draw(1)
    tilted = FlightSimulator(
        _cfg(repo_dir, randomisation=replace(spiral, drag_pitch_deg_per_mps=(5.6, 5.6)))
    ).draw(1)
    assert tilted.params["drag_pitch_deg_per_mps"] == 5.6
    assert base.params["drag_pitch_deg_per_mps"] == 0.6  # the vehicle's default, recorded
    want = -np.degrees(np.arctan(np.tan(np.radians(5.6)) * 5.5))
    for fd, k in ((tilted, want), (base, -np.degrees(np.arctan(np.tan(np.radians(0.6)) * 5.5)))):
        pitch = np.median(np.rad2deg(fd.samples.attitude_rad[:, 1]))
        assert abs(pitch - k) < 2.0, (pitch, k)
    same = FlightSimulator(
        _cfg(repo_dir, randomisation=replace(spiral, drag_pitch_deg_per_mps=None))
    ).draw(1)
    assert base.samples.rss_dbm.tobytes() == same.samples.rss_dbm.tobytes()
    drawn = [
        FlightSimulator(
            _cfg(repo_dir, randomisation=replace(FAST, drag_pitch_deg_per_mps=(1.0, 4.0)))
        )
        .draw(i)
        .params["drag_pitch_deg_per_mps"]
        for i in range(4)
    ]
    assert all(1.0 <= d <= 4.0 for d in drawn) and len(set(drawn)) == 4


def test_training_domain_of_a_drawn_pitch_spans_both_ends():
    """A network trained on spirals with the nose-down pitch drawn in a range claims the attitudes
    of both ends (the mission flown at each), so a PX4-like -28 deg cruise lies inside it."""
    level = {"mission": "missions/spiral.yaml", "randomisation": {}}
    tilt = {
        "mission": "missions/spiral.yaml",
        "randomisation": {"drag_pitch_deg_per_mps": [0.6, 6]},
    }
    (_, p_level) = training_attitude({"datasets": [level]})
    (_, p_tilt) = training_attitude({"datasets": [tilt]})
    assert p_level[0] > -20.0 and p_tilt[0] < -30.0
    assert p_tilt[1] == pytest.approx(p_level[1], abs=0.5)  # the level end is the default vehicle


def test_physics_preset_fold_is_the_simulated_model(repo_dir):
    """``physics="afar:fit328"`` flies the fold's fitted model: noise-free RSS equals that model at
    the logged geometry, with the heading jitter added to the preset's UAV-antenna heading."""
    r = replace(FAST, noise_db=(0.0, 0.0), offset_db=None, physics_heading_jitter_deg=5.0)
    sim = FlightSimulator(_cfg(repo_dir, randomisation=r, physics="afar:fit328"))
    fd = sim.draw(1)
    spec = load_preset("afar:fit328")
    assert fd.params["rx_heading_deg"] != spec["rx_heading_deg"]
    assert abs(fd.params["rx_heading_deg"] - spec["rx_heading_deg"]) <= 5.0
    model = build_model({**spec, "rx_heading_deg": fd.params["rx_heading_deg"]})
    s = fd.samples
    want = model.rss_dbm(s.tx_enu_m, s.enu_m, s.attitude_rad)
    assert np.allclose(s.rss_dbm, want, atol=1e-3)
    other = build_model(load_preset("afar:fit288")).rss_dbm(s.tx_enu_m, s.enu_m, s.attitude_rad)
    assert not np.allclose(s.rss_dbm, other, atol=1e-3)


@pytest.mark.parametrize(
    ("kw", "field"),
    [
        (
            {"physics": "afar:fit328", "randomisation": Randomisation(patterns=("dipole",))},
            "patterns",
        ),
        ({"physics": "afar:nofold"}, "preset"),
        (
            {"randomisation": Randomisation(physics_heading_jitter_deg=5.0)},
            "physics_heading_jitter_deg",
        ),
        ({"randomisation": Randomisation(fixed_heading=1.5)}, "fixed_heading"),
        ({"randomisation": Randomisation(speed_mps=(0.0, 3.0))}, "speed_mps"),
        (
            {"randomisation": Randomisation(drag_pitch_deg_per_mps=(-1.0, 3.0))},
            "drag_pitch_deg_per_mps",
        ),
        (
            {"randomisation": Randomisation(drag_pitch_deg_per_mps=(1.0, 50.0))},
            "drag_pitch_deg_per_mps",
        ),
    ],
)
def test_inconsistent_configs_are_refused(tmp_path, repo_dir, kw, field):
    cfg = DatasetConfig(str(repo_dir / "missions" / "spiral.yaml"), 2, **kw)
    with pytest.raises(ValueError, match=field):
        generate_dataset(cfg, tmp_path / "ds")
    assert not (tmp_path / "ds").exists()


def test_cli_physics_preset_and_its_errors(tmp_path, repo_dir, capsys):
    mission = str(repo_dir / "missions" / "spiral.yaml")
    args = [
        "dataset",
        mission,
        "--n",
        "2",
        "--workers",
        "1",
        "--features",
        "clustering",
        "--trajectories",
        "random_waypoints",
        "--random-params",
        "--truncate",
        "0.1,0.2",
    ]
    assert (
        main(
            [
                *args,
                "--physics",
                "afar:fit288",
                "--fixed-heading",
                "0.5",
                "--shadowing",
                "2,6",
                "--out",
                str(tmp_path / "ds"),
            ]
        )
        == 0
    )
    mf = read_manifest(tmp_path / "ds")
    assert mf["config"]["physics"] == "afar:fit288"
    assert mf["config"]["randomisation"]["shadowing_db"] == [2.0, 6.0]
    capsys.readouterr()
    assert (
        main(
            [
                *args,
                "--physics",
                "afar:fit288",
                "--patterns",
                "dipole",
                "--out",
                str(tmp_path / "x"),
            ]
        )
        == 2
    )
    err = capsys.readouterr().err
    assert "patterns" in err and "Traceback" not in err and len(err.strip().splitlines()) == 1

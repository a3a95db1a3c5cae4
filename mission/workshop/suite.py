"""The "unseen flight" benchmark: simulated flights that vary what real flights vary.

How to call it (the lead's entry points)::

    from mission.workshop.suite import unseen_flights, unseen_flight
    # list[SuiteFlight] (a NamedTuple)
    for log, truth_xy, draw in unseen_flights(200, seed=2026):
        est = localize_log(log, method="grid")  # log: a FlightLog like an imported one
        err = float(np.hypot(est.x_m - truth_xy[0], est.y_m - truth_xy[1]))
    f = unseen_flight(2026, 17)  # one flight, same bytes as in the list
    # the on-disk cache (write_suite / read_suite / check_current): mission.workshop.suite_cache

    # the cache
    rfsl dataset --suite unseen --logs --n 200 --seed 2026 --out /tmp/suite_unseen_2026
    rfsl evaluate --suite unseen --n 200 --seed 2026 \
        --methods strongest,centroid,grid,onnx:models/X.onnx
    # from the cache
    rfsl evaluate --suite-dir /tmp/suite_unseen_2026 --methods default,grid --workers 2
    rfsl evaluate --suite-dir /tmp/suite_unseen_2026 --methods default \
        --by tx_outside_flight_area,heading_habit
    # in Python: rows, secs = mission.workshop.evaluate_suite.evaluate_suite(["default", "grid"],
    #                                                                        200, suite_dir=...)
    #            breakdown(rows, suite_draws(200, suite_dir=...), "physics.rx_antenna")

Uncertainty regions: ``evaluate_suite`` counts the truth inside ``est.regions`` (typed
``mission.localize.region.Region``: on the posterior when there is one, else the region's ellipse),
or a composer's own layout in ``est.extras["regions"]`` (a dict keyed by level "50"/"90" or
0.5/0.9, or a list of dicts with "level"); each region a polygon
(``polygon`` [[x, y], ...], log ENU m) or an ellipse (``center_m`` + ``semi_axes_m`` + ``angle_deg``
ccw from east, or ``center_m`` + ``cov_m2`` + ``chi2``):
``mission.workshop.evaluate_suite.region_contains``.

Every flight is a deterministic function of ``(seed, i, family)``: all draws come from
``np.random.default_rng(np.random.SeedSequence([seed, SUITE_TAG], spawn_key=(i,)))`` (never the
worker count).  The benchmark seed is **2026** (``BENCHMARK_SEED``); training data drawn from the
same family (``rfsl dataset --suite unseen`` without ``--logs``) must use other seeds (``rfsl
dataset`` refuses 2026).

What a flight looks like to a method: a ``FlightLog`` in the form of an imported real log (AFAR
field origin, ``alt_m = rel_alt_m``, take-off, transit, cruise, return and landing in the rows;
sidecar ``rss_source.kind`` = ``"suite"``, *not* ``"sim"``, so ``localize``'s real-log default path
runs; ``rover_area`` as [lat, lon] vertices; **no truth** in the sidecar and nothing in it that
names the physics).  ``truth_xy`` (ENU m, log frame) and ``draw`` (every parameter, JSON-able)
travel beside it for scoring and analysis only.

Axes and ranges (``draw_flight``; one value per flight, draw order fixed):

- transmitter uniform in the part of the rover area outside the flight area (up to 110 m north of
  it) in a third of the flights (as in AFAR 2023: ``draw["tx_outside_flight_area"]``), else uniform
  in the overlap; height U(1, 2) m;
- cruise altitude U(15, 60) m, speed U(2, 10) m/s, sample period U(0.025, 0.045) s;
- trajectory: every generator of ``mission.trajectory.generators`` with random parameters over the
  overlap (75 %) or the whole flight area (25 %); a random contiguous 35-100 % of the path, and at
  most a time budget of U(5, 12) min of path (slow flights cover less);
- heading habit (equal odds): nose along the track; one fixed heading U(0, 360); slow rotation
  +-U(2, 10) deg/s; hover-and-turn (stop U(4, 12) s at every waypoint and turn 360 deg);
- attitude perturbation U(0.5, 4) deg (correlated over 0.3 s);
- physics (``mission.physics.presets.build_model`` spec), family ``"afar"`` centred on the
  calibration (``center`` preset, default ``afar``): with probability 0.4 the preset itself with its
  UAV-antenna heading jittered by U(-30, 30) deg; otherwise UAV antenna measured RM-WB1-DN flipped
  (0.4) / upright (0.3) / dipole (0.3) at a uniform mounting heading; gains from yaw only or full
  attitude (even odds); rover antenna isotropic (0.5), dipole (0.25) or measured upright at a random
  heading (0.25); path-gain slope U(-0.2, 0.8) (preset draws keep the preset's own slope); ground
  reflection on with probability 0.5 (eps_r log-U(3, 30), sigma U(0, 0.01) S/m).  Family
  ``"generic"`` never uses a preset (no real flight behind it): the same axes with the antenna
  choice alone (flipped / upright / dipole, equal odds).  Family ``"afar-heavy"`` is ``"afar"`` with
  the shadowing measured on real flights (below);
- spatially correlated shadowing sigma U(4, 10) dB, correlation U(10, 60) m (``shadowing_field``;
  family ``"afar-heavy"``: U(8, 16) dB over U(30, 120) m, ``SHADOWING``); white receiver noise U(1,
  4) dB; RSS-telemetry time offset U(-0.5, 0.5) s (telemetry read that much late/early); unknown RSS
  offset U(-40, 40) dB.

A physics family file instead of a built-in name (``family="F.json"``: schema 1,
``mission.physics.family``; the shipped ``mission/data/afar_family.json``, or ``rfsl gap --family``
output): the physics (model spec), the residual (correlated shadowing sigma and correlation length,
white nugget, whether the shadowing is fixed to the ground or to the path, ``shadowing_over``, its
shape, ``shadowing_marginal``, and its covariance, ``shadowing_covariance``)
and the RSS offset are one ``family.draw(rng)`` in place of the three built-in draws;
every other axis (position, altitude, speed, path, habit, coverage, time offset) is drawn as above.
``draw["family"]`` is then ``json:NAME@SHA8`` and ``draw["family_sha256"]`` the sha256 of the
family's canonical JSON (``family_sha256``), so a cache or a model names the family it drew from.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import NamedTuple

import numpy as np

from mission.errors import InputError
from mission.flightlog import FlightLog, make_meta
from mission.geo import afar_field
from mission.physics.family import SHADOWING_KEYS, nuisance_rss
from mission.physics.presets import build_model, load_preset
from mission.physics.shadowing import draw_shadowing
from mission.simulate import SimConfig, perturbation
from mission.trajectory.attitude import tilt_from_acceleration
from mission.trajectory.generators import GENERATORS, generate, trajectory_params
from mission.trajectory.kinematics import G, Kinematics, attitude_from_motion, plan_profile

# re-exported: the suite's family entry points
from mission.workshop.suite_family import (  # noqa: F401
    FAMILIES,
    FamilyArg,
    antenna_label,
    family_label,
    family_sha256,
    resolve_family,
)

SUITES = ("unseen",)
# Shadowing per family: (sigma range dB, correlation-length range m).  "afar-heavy" takes the
# residual field measured on the six real AFAR flights (``rfsl gap``: sigma 11-15 dB, correlation
# ~70 m) as its centre, because on real flights the RSS spread is about twice what the milder ranges
# produce (models/README.md).
SHADOWING = {
    "afar": ((4.0, 10.0), (10.0, 60.0)),
    "generic": ((4.0, 10.0), (10.0, 60.0)),
    "afar-heavy": ((8.0, 16.0), (30.0, 120.0)),
}
SUITE_TAG = 10  # mixed into every suite seed: keeps suite seeds apart from rfsl-dataset seeds
BENCHMARK_SEED = 2026
# cruise altitude drawn per flight (a network trained on "suite:" data spans it)
ALTITUDE_RANGE_M = (
    15.0,
    60.0,
)
P_OUTSIDE = 1 / 3  # AFAR 2023: the rover stood north of the flight area in a third of the flights
HABITS = ("along_track", "fixed", "slow_rotation", "hover_turn")
RSS_SOURCE = {
    "kind": "suite",
    "receiver": "simulated receiver (unseen-flight benchmark)",
    "calibrated": False,
}


class SuiteFlight(NamedTuple):
    """One benchmark flight: the log a method sees, the truth (x, y) in the log's ENU frame, and the
    draw."""

    log: object  # mission.flightlog.FlightLog
    truth_xy: np.ndarray
    draw: dict


def suite_rng(seed: int, i: int) -> np.random.Generator:
    """The generator of flight ``i`` of suite seed ``seed``."""
    return np.random.default_rng(
        np.random.SeedSequence([int(seed), SUITE_TAG], spawn_key=(int(i),))
    )


def _u(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(rng.uniform(lo, hi))


def _pick(rng: np.random.Generator, options: tuple, p: tuple[float, ...] | None = None):
    return options[int(rng.choice(len(options), p=p))]


def _physics(rng: np.random.Generator, family: str, center: str) -> dict:
    """A model spec for ``build_model`` (see the module docstring for the family)."""
    centred = family in ("afar", "afar-heavy")
    use_preset = centred and rng.uniform() < 0.4
    heading = _u(rng, 0.0, 360.0)
    jitter = _u(rng, -30.0, 30.0)
    antenna = _pick(rng, ("flipped", "upright", "dipole"), (0.4, 0.3, 0.3) if centred else None)
    attitude = _pick(rng, ("yaw", True))
    tx = _pick(rng, ("isotropic", "dipole", "measured"), (0.5, 0.25, 0.25))
    tx_heading = _u(rng, 0.0, 360.0)
    slope = _u(rng, -0.2, 0.8)
    ground = {
        "eps_r": float(math.exp(rng.uniform(math.log(3.0), math.log(30.0)))),
        "sigma_s_m": _u(rng, 0, 0.01),
    }
    ground_on = bool(rng.uniform() < 0.5)
    if use_preset:
        spec = load_preset(center)
        spec["rx_heading_deg"] = float((float(spec.get("rx_heading_deg", 0.0)) + jitter) % 360.0)
    else:
        spec = {
            "base": "free-space",
            "rx_pattern": "dipole" if antenna == "dipole" else "measured",
            "rx_flipped": antenna == "flipped",
            "rx_heading_deg": heading,
            "attitude": attitude,
            "path_gain_slope": slope,
        }
    spec.update(tx_pattern=tx, tx_heading_deg=tx_heading if tx == "measured" else 0.0)
    spec["ground"] = ground if ground_on else None
    return {
        "spec": spec,
        "from_preset": center if use_preset else None,
        "rx_antenna": "preset" if use_preset else antenna,
    }


def _rover_position(fld, outside: bool, rng: np.random.Generator) -> np.ndarray:
    """A transmitter position uniform in the part of the rover area outside (or inside) the flight
    area."""
    while True:
        xy = fld.rover_area.sample_uniform(16, rng)
        ok = fld.flight_area.contains(xy) != outside
        if ok.any():
            return xy[int(np.argmax(ok))]


def draw_flight(
    seed: int, i: int, family: FamilyArg = "afar", center: str = "afar"
) -> tuple[dict, np.random.Generator]:
    """Every parameter of flight ``i`` (JSON-able dict) and the generator, positioned for the
    simulation."""
    fam = resolve_family(family)
    rng = suite_rng(seed, i)
    fld = afar_field()
    outside = bool(rng.uniform() < P_OUTSIDE)
    xy = _rover_position(fld, outside, rng)
    d: dict = {
        "seed": int(seed),
        "index": int(i),
        "family": family_label(fam),
        "tx_xy": [float(xy[0]), float(xy[1])],
        "tx_height_m": _u(rng, 1.0, 2.0),
    }
    d["tx_outside_flight_area"] = outside
    d["altitude_m"] = _u(rng, *ALTITUDE_RANGE_M)
    d["speed_mps"] = _u(rng, 2.0, 10.0)
    d["dt_s"] = _u(rng, 0.025, 0.045)
    traj = _pick(rng, tuple(GENERATORS))
    tp = trajectory_params(traj, rng, {}, True)
    tp["region"] = _pick(rng, ("overlap", "flight"), (0.75, 0.25))
    d["trajectory"], d["trajectory_params"] = traj, tp
    d["keep_fraction"] = _u(rng, 0.35, 1.0)
    d["start_fraction"] = _u(rng, 0.0, 1.0)  # where the kept window lies in the rest of the path
    d["budget_s"] = _u(rng, 300.0, 720.0)
    d["heading_habit"] = _pick(rng, HABITS)
    d["fixed_heading_deg"] = _u(rng, 0.0, 360.0)
    d["rotation_dps"] = _u(rng, 2.0, 10.0) * (1 if rng.uniform() < 0.5 else -1)
    d["attitude_perturbation_deg"] = _u(rng, 0.5, 4.0)
    # a physics family file: physics, residual and offset are the family's draw
    if not isinstance(fam, str):
        fd = fam.draw(rng)
        d["family_sha256"] = family_sha256(fam)
        d["physics"] = {"spec": fd.spec, "from_preset": None, "rx_antenna": antenna_label(fd.spec)}
        d["shadowing_db"], d["shadowing_corr_m"], d["noise_db"] = (
            fd.shadowing_db,
            fd.shadowing_corr_m,
            fd.noise_db,
        )
        d["time_offset_s"] = _u(rng, -0.5, 0.5)
        d["rss_offset_db"] = fd.offset_db
        # a ground field with a Gaussian shape (every older cache) adds no key
        drawn = fd.to_dict()
        d.update({k: drawn[k] for k in SHADOWING_KEYS if k in drawn})
        # a family with per-flight structure (``physics.family`` nuisance)
        d.update({k: v for k, v in fd.nuisance().items() if v})
        return d, rng
    d["physics"] = _physics(rng, family, center)
    (s_lo, s_hi), (l_lo, l_hi) = SHADOWING[family]
    d["shadowing_db"] = _u(rng, s_lo, s_hi)
    d["shadowing_corr_m"] = _u(rng, l_lo, l_hi)
    d["noise_db"] = _u(rng, 1.0, 4.0)
    d["time_offset_s"] = _u(rng, -0.5, 0.5)
    d["rss_offset_db"] = _u(rng, -40.0, 40.0)
    return d, rng


def cut_polyline(p: np.ndarray, a: float, b: float) -> np.ndarray:
    """The part of polyline ``p`` (K, 3) between arc-length fractions ``a`` < ``b`` (new end
    vertices)."""
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))])
    sa, sb = a * s[-1], b * s[-1]
    at = [np.array([np.interp(v, s, p[:, k]) for k in range(p.shape[1])]) for v in (sa, sb)]
    return np.vstack([at[0], p[(s > sa) & (s < sb)], at[1]])


def _path(d: dict, fld) -> np.ndarray:
    """Home (ground) -> climb -> the kept part of the pattern -> back over home -> land."""
    wps = generate(d["trajectory"], fld, d["altitude_m"], **d["trajectory_params"])
    length = float(np.sum(np.linalg.norm(np.diff(wps, axis=0), axis=1)))
    keep = min(d["keep_fraction"], d["speed_mps"] * d["budget_s"] / max(length, 1e-9))
    a = d["start_fraction"] * (1.0 - keep)
    cut = cut_polyline(wps, a, a + keep)
    h = fld.origin.to_enu(*fld.takeoff_home) if fld.takeoff_home else np.zeros(3)
    home = np.array([h[0], h[1], 0.0])
    up = np.array([h[0], h[1], d["altitude_m"]])
    return np.vstack([home, up, cut, up, home])


def _times(d: dict, profile, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sample times, positions and completed hover turns (hover-and-turn stops at every cruise
    vertex)."""
    dt = d["dt_s"]
    if d["heading_habit"] != "hover_turn":
        t, pos = profile.sample(dt)
        return t, pos, np.zeros(len(t))
    tv = profile.t_vertex
    k = len(tv)
    hover = rng.uniform(4.0, 12.0, size=k)
    hover[:2] = 0.0  # no turn on the ground or at the top of the climb
    hover[-2:] = 0.0
    before = np.concatenate([[0.0], np.cumsum(hover)[:-1]])
    knots_new = np.column_stack([tv + before, tv + before + hover]).ravel()
    knots_old = np.repeat(tv, 2)
    turns_before = np.concatenate([[0.0], np.cumsum(hover > 0)[:-1]])
    knots_turn = np.column_stack([turns_before, turns_before + (hover > 0)]).ravel()
    t = np.arange(0.0, knots_new[-1] + 1e-9, dt)
    t_old = np.interp(t, knots_new, knots_old)
    return t, profile.position(t_old), np.interp(t, knots_new, knots_turn)


def _attitude(d: dict, t: np.ndarray, pos: np.ndarray, turns: np.ndarray, kin) -> np.ndarray:
    """Roll, pitch, yaw (N, 3) rad of the heading habit (tilt from the accelerations, as the
    simulator)."""
    habit = d["heading_habit"]
    if habit == "fixed":
        return attitude_from_motion(t, pos, replace(kin, heading_deg=d["fixed_heading_deg"]))[0]
    if habit in ("along_track", "hover_turn"):
        att = attitude_from_motion(t, pos, kin)[0]
        att[:, 2] = np.mod(att[:, 2] + 2 * np.pi * turns, 2 * np.pi)
        return att
    # nose north: tilt = accel (n, e)
    att = attitude_from_motion(t, pos, replace(kin, heading_deg=0.0))[0]
    a_n, a_e = -np.tan(att[:, 1]) * G, np.tan(att[:, 0]) * G
    yaw = np.deg2rad(d["fixed_heading_deg"] + d["rotation_dps"] * t)
    lim = np.deg2rad(kin.max_tilt_deg)
    roll, pitch = (np.clip(v, -lim, lim) for v in tilt_from_acceleration(a_n, a_e, yaw))
    return np.stack([roll, pitch, np.mod(yaw, 2 * np.pi)], axis=-1)


def simulate_draw(
    d: dict, rng: np.random.Generator
) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray]:
    """(log columns, true ENU positions (N, 3), cruise mask) of a drawn flight."""
    fld = afar_field()
    kin = Kinematics(cruise_speed_mps=d["speed_mps"])
    path = _path(d, fld)
    t, pos, turns = _times(d, plan_profile(path, kin), rng)
    att = _attitude(d, t, pos, turns, kin)
    pcfg = SimConfig(
        dt_s=d["dt_s"],
        attitude_perturbation_deg=d["attitude_perturbation_deg"],
        perturbation_corr_s=0.3,
    )
    att = att + perturbation(len(t), pcfg, rng)
    att[:, 2] = np.mod(att[:, 2], 2 * np.pi)
    model = build_model(d["physics"]["spec"], name="suite")
    tx = np.array([*d["tx_xy"], d["tx_height_m"]])
    rss = np.asarray(model.rss_dbm(tx, pos, att), dtype=float)
    rss += d["rss_offset_db"] + rng.normal(0.0, d["noise_db"], size=rss.shape)
    m = d.get("shadowing_marginal")
    rss += draw_shadowing(
        pos,
        d["shadowing_db"],
        d["shadowing_corr_m"],
        d.get("shadowing_over", "ground"),
        rng,
        None if m is None else (tuple(m["p"]), tuple(m["q"])),
        d.get("shadowing_covariance", "gaussian"),
    )
    # drawn last, as ``physics.family.simulate_rss``: a flight without it is unchanged
    rss += nuisance_rss(tx, pos, att, d, rng)
    # telemetry read time_offset_s late: the logged pose of sample k is the true pose at t_k +
    # offset
    ts = np.clip(t + d["time_offset_s"], t[0], t[-1])
    lpos = np.stack([np.interp(ts, t, pos[:, k]) for k in range(3)], axis=1)
    latt = np.stack(
        [np.interp(ts, t, a) for a in (att[:, 0], att[:, 1], np.unwrap(att[:, 2]))], axis=1
    )
    lat, lon, _ = fld.origin.to_geodetic(lpos)
    deg = np.rad2deg(latt)
    cols = {
        "t_s": t,
        "lat_deg": lat,
        "lon_deg": lon,
        "alt_m": fld.origin.alt_m + lpos[:, 2],
        "rel_alt_m": lpos[:, 2],
        "roll_deg": deg[:, 0],
        "pitch_deg": deg[:, 1],
        "yaw_deg": np.mod(deg[:, 2], 360.0),
        "rss_dbm": rss,
    }
    cruise = np.abs(pos[:, 2] - d["altitude_m"]) < 0.5
    return cols, pos, cruise


def rover_area_latlon() -> list[list[float]]:
    """The AFAR rover area as [lat, lon] vertices (the sidecar's ``rover_area``)."""
    fld = afar_field()
    v = fld.rover_area.vertices
    lat, lon, _ = fld.origin.to_geodetic(np.column_stack([v, np.zeros(len(v))]))
    return [[float(a), float(b)] for a, b in zip(lat, lon, strict=True)]


def _meta(d: dict) -> dict:
    return make_meta(
        afar_field().origin,
        dict(RSS_SOURCE),
        None,
        rover_area=rover_area_latlon(),
        source={"suite": "unseen", "seed": d["seed"], "index": d["index"]},
    )


def unseen_flight(
    seed: int, i: int, family: FamilyArg = "afar", center: str = "afar"
) -> SuiteFlight:
    """Flight ``i`` of the benchmark with seed ``seed`` (module docstring)."""
    d, rng = draw_flight(seed, i, family, center)
    cols, _, _ = simulate_draw(d, rng)
    d["n_samples"] = len(cols["t_s"])
    return SuiteFlight(FlightLog(cols, _meta(d)), np.array(d["tx_xy"]), d)


def unseen_flights(
    n: int,
    seed: int = BENCHMARK_SEED,
    family: FamilyArg = "afar",
    center: str = "afar",
    start: int = 0,
) -> list[SuiteFlight]:
    """Flights ``start .. start + n - 1`` of the benchmark (in memory; ~20 000 rows each)."""
    if n < 1:
        raise InputError(f"need n >= 1, got {n}", field="n")
    return [unseen_flight(seed, i, family, center) for i in range(start, start + n)]

"""Flight ``i`` of a dataset configuration: its random draws and the simulated per-sample arrays.

For flight ``i`` of a dataset with seed ``S`` every random draw comes from
``np.random.default_rng(np.random.SeedSequence(S, spawn_key=(i,)))`` -- exactly the ``i``-th child
of ``SeedSequence(S).spawn(N)`` -- so a flight's bytes depend only on ``(S, i)`` and the
configuration, never on the number of workers or on the chunk size.  Draw order per flight:
transmitter position, randomised parameters (altitude, trajectory and its parameters, pattern, beta,
ground permittivity, antenna headings, tx height, offset, noise level, truncation), then the
simulator's own draws (attitude perturbation, noise). ``FlightSimulator(cfg).draw(i)`` flies it,
``.features(draw)`` turns it into the stored row.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from mission.adaptive.planner import flown_ahead
from mission.localize.features import FeatureConfig, cluster_features, normalised_rss
from mission.localize.preprocess import cruise_mask
from mission.physics import make_model
from mission.physics.presets import build_model, load_preset
from mission.samples import FlightSamples
from mission.simulate import simulate_flight
from mission.spec import load_mission
from mission.trajectory.generators import (
    generate,
    trajectory_params,  # re-exported (mission.workshop.dataset)
)
from mission.trajectory.multicopter import Kinematics
from mission.workshop.dataset_config import (
    PARAM_NAMES,
    DatasetConfig,
    pattern_names,
    trajectory_names,
)
from mission.workshop.suite import unseen_flight


def flight_rng(seed: int, i: int) -> np.random.Generator:
    """The generator of flight ``i``: the ``i``-th child of ``SeedSequence(seed)`` (as ``spawn``
    makes)."""
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(i,)))


def _uniform(
    rng: np.random.Generator, rng_range: tuple[float, float] | None, default: float
) -> float:
    if rng_range is None:
        return float(default)
    lo, hi = float(rng_range[0]), float(rng_range[1])
    return float(rng.uniform(lo, hi)) if hi > lo else lo


def _choice(rng: np.random.Generator, options: Sequence[str], default: str) -> str:
    if not options:
        return default
    return str(options[int(rng.integers(len(options)))]) if len(options) > 1 else str(options[0])


@dataclass(frozen=True)
class _Draws:
    """A dataset flight's random draws (``FlightSimulator._draws``; None: the item is off)."""

    xy: np.ndarray  # transmitter east, north
    alt: float
    traj: str
    same: bool  # the mission's own trajectory generator
    tparams: dict
    pattern: str
    beta: float | None
    eps_r: float | None
    rx_h: float
    tx_h: float
    tx_height: float
    offset: float
    noise: float
    keep: float
    start: float
    fixed_h: float | None
    speed: float | None
    shadow: float
    corr: float
    jitter: float
    drag: float | None


@dataclass
class FlightDraw:
    """One simulated flight of a dataset: its random draws and the samples the features use (with
    the transmitter as ``samples.tx_enu_m``)."""

    index: int
    params: dict
    trajectory: str
    pattern: str
    samples: FlightSamples


class FlightSimulator:
    """Simulates flight ``i`` of a dataset configuration (built once per worker process)."""

    def __init__(self, cfg: DatasetConfig) -> None:
        self.cfg = cfg
        self.spec = flown_ahead(load_mission(cfg.mission))
        self.fcfg = (
            FeatureConfig.from_dict(cfg.feature_config) if cfg.feature_config else FeatureConfig()
        )
        self.sim = self.spec.sim_config()
        self._models: dict = {}
        self._preset_spec: dict | None = None
        if cfg.physics:
            self._preset_spec = {**load_preset(cfg.physics), **cfg.model_params}

    def _model(
        self,
        pattern: str,
        beta: float | None,
        eps_r: float | None,
        rx_h: float,
        tx_h: float,
        jitter: float = 0.0,
    ):
        if self.cfg.physics:
            return self._preset_model(jitter)
        kw = dict(self.spec.source.model_params)
        kw.update(self.cfg.model_params)
        if pattern:
            kw["pattern"] = pattern
        if beta is not None:
            kw["beta"] = beta
        if eps_r is not None:
            kw["eps_r"] = eps_r
        if rx_h:
            kw["rx_heading_rad"] = math.radians(rx_h)
        if tx_h:
            kw["tx_heading_rad"] = math.radians(tx_h)
        key = json.dumps(kw, sort_keys=True, default=str)
        m = self._models.get(key)
        if m is None:
            m = make_model(self.cfg.model, **kw)
            if len(self._models) < 64:
                self._models[key] = m
        return m

    def _preset_model(self, jitter: float):
        key = f"preset:{jitter:.6f}"
        m = self._models.get(key)
        if m is None:
            spec = {**self._preset_spec, "rx_heading_deg": self._preset_heading() + jitter}
            m = build_model(spec, name=f"preset:{self.cfg.physics}")
            if len(self._models) < 64:
                self._models[key] = m
        return m

    def _preset_heading(self) -> float:
        """The preset's UAV-antenna heading before jitter (degrees)."""
        return float((self._preset_spec or {}).get("rx_heading_deg", 0.0))

    def draw(self, i: int) -> FlightDraw:
        """Draw and fly flight ``i`` (deterministic in ``(cfg, i)``): its random draws in their
        fixed order, the path, the simulator settings, the flight (cut to its kept fraction)."""
        if self.cfg.suite:
            return self._draw_suite(i)
        rng = flight_rng(self.cfg.seed, i)
        d = self._draws(rng)
        tx = np.array([d.xy[0], d.xy[1], d.tx_height])
        model = self._model(d.pattern, d.beta, d.eps_r, d.rx_h, d.tx_h, d.jitter)
        sim = self._sim_config(d)
        fl: FlightSamples = simulate_flight(self._waypoints(d), tx, model, sim, rng)
        if d.keep < 1.0:
            n = len(fl)
            a = int(d.start * n)
            b = max(a + int(d.keep * n), a + 1)
            fl = fl.select(slice(a, b))
        return FlightDraw(i, self._params(d, sim), d.traj, d.pattern or "default", fl)

    def _draws(self, rng: np.random.Generator) -> _Draws:
        """Flight's random draws, in the order that makes a dataset's bytes (module docstring)."""
        r, spec = self.cfg.randomisation, self.spec
        xy = spec.field.rover_area.sample_uniform(1, rng)[0]
        alt = _uniform(rng, r.altitude_m, spec.altitude_m)
        traj = _choice(rng, r.trajectories, spec.trajectory.generator)
        same = traj == spec.trajectory.generator
        tparams = trajectory_params(
            traj, rng, spec.trajectory.params if same else {}, r.random_params
        )
        pattern = _choice(rng, r.patterns, "")
        beta = None if r.beta is None else _uniform(rng, r.beta, 0.0)
        eps_r = None if r.eps_r is None else _uniform(rng, r.eps_r, 0.0)
        heading = r.random_heading and pattern not in ("", "dipole", "isotropic")
        rx_h = float(rng.uniform(0.0, 360.0)) if heading else 0.0
        tx_h = float(rng.uniform(0.0, 360.0)) if heading else 0.0
        tx_height = _uniform(rng, r.tx_height_m, spec.source.tx_height_m)
        offset = _uniform(rng, r.offset_db, 0.0)
        noise = _uniform(rng, r.noise_db, self.sim.noise_db)
        keep = _uniform(rng, r.truncate, 1.0)
        start = float(rng.uniform(0.0, 1.0 - keep)) if keep < 1.0 else 0.0
        # draws added after the first release: taken only when switched on, so older configs keep
        # their bytes
        fixed_h = None
        if r.fixed_heading is not None and r.fixed_heading > 0:
            fixed = bool(rng.uniform() < r.fixed_heading)
            h = float(rng.uniform(0.0, 360.0))
            fixed_h = h if fixed else None
        speed = None if r.speed_mps is None else _uniform(rng, r.speed_mps, 0.0)
        shadow = 0.0 if r.shadowing_db is None else _uniform(rng, r.shadowing_db, 0.0)
        corr = (
            self.sim.shadowing_corr_m
            if r.shadowing_corr_m is None
            else _uniform(rng, r.shadowing_corr_m, 0.0)
        )
        jitter = 0.0
        if r.physics_heading_jitter_deg:
            jitter = float(rng.uniform(-r.physics_heading_jitter_deg, r.physics_heading_jitter_deg))
        drag = None
        if r.drag_pitch_deg_per_mps is not None:
            drag = _uniform(rng, r.drag_pitch_deg_per_mps, 0.0)
        return _Draws(
            xy,
            alt,
            traj,
            same,
            tparams,
            pattern,
            beta,
            eps_r,
            rx_h,
            tx_h,
            tx_height,
            offset,
            noise,
            keep,
            start,
            fixed_h,
            speed,
            shadow,
            corr,
            jitter,
            drag,
        )

    def _waypoints(self, d: _Draws) -> np.ndarray:
        """The flight's path: the mission's own waypoints at the drawn altitude, or generated."""
        spec = self.spec
        if d.traj == "waypoints" or (
            spec.trajectory.waypoints is not None
            and d.same
            and not self.cfg.randomisation.random_params
        ):
            wps = np.array(spec.waypoints_enu(), dtype=float)
            wps[:, 2] = d.alt
            return wps
        return generate(d.traj, spec.field, d.alt, **d.tparams)

    def _sim_config(self, d: _Draws):
        """The simulator settings of the flight: drawn noise, offset, shadowing, heading, speed."""
        kin = self.sim.kinematics
        if d.fixed_h is not None or d.speed is not None or d.drag is not None:
            kin = replace(
                kin,
                heading_deg=d.fixed_h if d.fixed_h is not None else kin.heading_deg,
                cruise_speed_mps=d.speed if d.speed is not None else kin.cruise_speed_mps,
                drag_pitch_deg_per_mps=(
                    d.drag if d.drag is not None else kin.drag_pitch_deg_per_mps
                ),
            )
        return replace(
            self.sim,
            noise_db=d.noise,
            rss_offset_db=d.offset,
            kinematics=kin,
            shadowing_db=d.shadow,
            shadowing_corr_m=d.corr,
        )

    def _params(self, d: _Draws, sim) -> dict:
        """The flight's row of ``params`` (``PARAM_NAMES``) as a dict, with its trajectory's
        parameters."""
        return {
            "altitude_m": d.alt,
            "offset_db": d.offset,
            "beta": np.nan if d.beta is None else d.beta,
            "eps_r": np.nan if d.eps_r is None else d.eps_r,
            "tx_height_m": d.tx_height,
            "noise_db": d.noise,
            "rx_heading_deg": self._preset_heading() + d.jitter if self.cfg.physics else d.rx_h,
            "tx_heading_deg": d.tx_h,
            "keep_fraction": d.keep,
            "fixed_heading_deg": np.nan if d.fixed_h is None else d.fixed_h,
            "speed_mps": sim.kinematics.cruise_speed_mps,
            "shadowing_db": d.shadow,
            "shadowing_corr_m": d.corr if d.shadow > 0 else np.nan,
            "drag_pitch_deg_per_mps": sim.kinematics.drag_pitch_deg_per_mps,
            "trajectory_params": d.tparams,
        }

    def _draw_suite(self, i: int) -> FlightDraw:
        """Flight ``i`` of the benchmark family (seed ``cfg.seed``), cut to the cruise as
        ``localize`` cuts a log."""
        f = unseen_flight(self.cfg.seed, i, self.cfg.suite_family, self.cfg.suite_center)
        d = f.draw
        keep = cruise_mask(f.log["rel_alt_m"]).mask
        spec = d["physics"]["spec"]
        ground = spec.get("ground") or {}
        params = {
            "altitude_m": d["altitude_m"],
            "offset_db": d["rss_offset_db"],
            "beta": np.nan,
            "eps_r": ground.get("eps_r", np.nan),
            "tx_height_m": d["tx_height_m"],
            "noise_db": d["noise_db"],
            "rx_heading_deg": spec.get("rx_heading_deg", 0.0),
            "tx_heading_deg": spec.get("tx_heading_deg", 0.0),
            "keep_fraction": d["keep_fraction"],
            "fixed_heading_deg": d["fixed_heading_deg"]
            if d["heading_habit"] == "fixed"
            else np.nan,
            "speed_mps": d["speed_mps"],
            "shadowing_db": d["shadowing_db"],
            "shadowing_corr_m": d["shadowing_corr_m"],
            # the benchmark family flies the default vehicle (suite.heading_attitude)
            "drag_pitch_deg_per_mps": Kinematics().drag_pitch_deg_per_mps,
            "trajectory_params": d["trajectory_params"],
        }
        tx = np.array([*d["tx_xy"], d["tx_height_m"]])
        samples = replace(f.log.samples(), tx_enu_m=tx).select(keep)
        return FlightDraw(i, params, d["trajectory"], "default", samples)

    def features(self, fd: FlightDraw) -> dict[str, np.ndarray]:
        """The stored row of one flight (features, truth, parameters)."""
        traj_names = self._traj_names()
        pat_names = self._pattern_names()
        row: dict[str, np.ndarray] = {}
        s = fd.samples
        if "clustering" in self.cfg.features:
            row["clustering"] = cluster_features(s.enu_m[:, 0], s.enu_m[:, 1], s.rss_dbm, self.fcfg)
        if "normalised_rss" in self.cfg.features:
            row["normalised_rss"] = normalised_rss(s.rss_dbm, self.fcfg)
        p = {
            **fd.params,
            "trajectory": traj_names.index(fd.trajectory),
            "pattern": pat_names.index(fd.pattern),
        }
        # column order = PARAM_NAMES
        row["params"] = np.array([p[k] for k in PARAM_NAMES], dtype=float)
        row["tx_enu"] = s.tx_enu_m
        row["n_samples"] = np.array(len(s))
        row["index"] = np.array(fd.index)
        return row

    def _traj_names(self) -> list[str]:
        return trajectory_names(self.cfg, self.spec.trajectory.generator)

    def _pattern_names(self) -> list[str]:
        return pattern_names(self.cfg)

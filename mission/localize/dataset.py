"""Simulated training/test datasets: many transmitter positions, each flown in the simulator, stored as
compact feature chunks (issue 5 item 1).

For flight ``i`` of a dataset with seed ``S`` every random draw comes from
``np.random.default_rng(np.random.SeedSequence(S, spawn_key=(i,)))`` -- exactly the ``i``-th child of
``SeedSequence(S).spawn(N)`` -- so a flight's bytes depend only on ``(S, i)`` and the configuration, never
on the number of workers or on the chunk size.  Draw order per flight: transmitter position, randomised
parameters (altitude, trajectory and its parameters, pattern, beta, ground permittivity, antenna headings,
tx height, offset, noise level, truncation), then the simulator's own draws (attitude perturbation, noise).

Domain randomisation (each switchable; ``Randomisation``):

- ``altitude_m``: cruise altitude uniform in a range (AFAR teams flew 20-47 m; the paper 30 m).
- ``offset_db``: a constant RSS offset (a real receiver's dB are not calibrated dBm; the features are
  offset-invariant, so this mainly checks that they are).
- ``trajectories`` with ``random_params``: generator drawn per flight, spacing / margin / start corner /
  direction / waypoint count drawn at random (real AFAR teams flew their own paths).
- ``truncate``: keep only a random contiguous fraction of the cruise (adaptive or interrupted flights,
  e.g. team 288's, cover only part of the field).
- ``patterns``: antenna pattern per flight ("dipole", "measured"); with ``random_heading`` the measured
  pattern's mounting heading on the UAV and the rover is random (their true headings are unknown).
- ``beta``: leg-shadowing exponent; ``eps_r``: ground relative permittivity.
- ``tx_height_m``: transmitter height (AFAR rover antenna about 1.5 m; paper 5 m).
- ``noise_db``: per-flight noise standard deviation.
- ``fixed_heading``: probability that a flight holds one compass heading (uniform 0-360 deg) instead of
  yawing along the track; the AFAR 2023 vehicles held a near-constant heading for the whole cruise, which
  with a directional UAV antenna fixes the antenna's world orientation.
- ``speed_mps``: cruise speed (AFAR team 288 crept at about 1 m/s median, team 328 flew about 4 m/s).
- ``shadowing_db`` / ``shadowing_corr_m``: a spatially correlated shadowing field per flight
  (``mission.simulate.shadowing_field``); real residuals persist over tens of metres.
- ``physics_heading_jitter_deg``: with a physics preset, the preset's UAV-antenna heading is jittered by
  U(-j, j) per flight (its fit is uncertain by several degrees and differs between teams).

Physics: ``model`` names one of ``make_model``'s models, or ``physics`` names a calibrated preset of
``mission.physics.presets`` (``afar``, or a fold such as ``afar:fit328`` fitted on team 328 only), which
replaces it.  Pattern / beta / eps_r randomisation apply to ``make_model`` models only.

Storage (``DIR``): ``manifest.json`` (every setting, the seed, the feature configuration, the field origin,
the chunk list with sha256 digests) and ``chunk_00000.npz`` ... each holding, for its flights (float32
unless noted): ``clustering`` (n, 3 C_k), ``normalised_rss`` (n, L) when requested, ``tx_enu`` (n, 3) the
raw truth, ``params`` (n, len(PARAM_NAMES)), ``n_samples`` (n,) int32 and ``index`` (n,) int64.
Chunks are written as they complete, so memory stays bounded by ``chunk`` flights.
"""

from __future__ import annotations

import hashlib
import io
import json
import math
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path

import numpy as np

from mission.errors import InputError, refuse_unknown_keys

FORMAT = "rfsl-dataset/1"
PARAM_NAMES = (
    "altitude_m",
    "offset_db",
    "beta",
    "eps_r",
    "tx_height_m",
    "noise_db",
    "rx_heading_deg",
    "tx_heading_deg",
    "trajectory",
    "pattern",
    "keep_fraction",
    "fixed_heading_deg",
    "speed_mps",
    "shadowing_db",
    "shadowing_corr_m",
)
FEATURE_KINDS = ("clustering", "normalised_rss")


@dataclass(frozen=True)
class Randomisation:
    """Domain randomisation ranges; ``None`` (or a single-element choice) switches an item off."""

    altitude_m: tuple[float, float] | None = None
    offset_db: tuple[float, float] | None = None
    trajectories: tuple[str, ...] = ()  # () = the mission's own trajectory
    random_params: bool = False
    truncate: tuple[float, float] | None = None  # kept fraction of the cruise, e.g. (0.4, 1.0)
    patterns: tuple[str, ...] = ()  # () = the mission's / model default pattern
    random_heading: bool = False
    beta: tuple[float, float] | None = None
    eps_r: tuple[float, float] | None = None
    tx_height_m: tuple[float, float] | None = None
    noise_db: tuple[float, float] | None = None
    fixed_heading: float | None = None  # probability of a fixed-heading flight
    speed_mps: tuple[float, float] | None = None
    shadowing_db: tuple[float, float] | None = None
    shadowing_corr_m: tuple[float, float] | None = None
    physics_heading_jitter_deg: float | None = None

    @classmethod
    def from_dict(cls, d: dict) -> Randomisation:
        refuse_unknown_keys(d, (f.name for f in fields(cls)), "randomisation")
        conv = {k: (tuple(v) if isinstance(v, list) else v) for k, v in d.items()}
        return cls(**conv)


@dataclass(frozen=True)
class DatasetConfig:
    """Everything that defines a dataset (recorded in the manifest; same config + seed = same bytes)."""

    mission: str | None  # mission YAML path (None: the default mission)
    n: int
    model: str = "e2r"
    seed: int = 0
    chunk: int = 500
    features: tuple[str, ...] = FEATURE_KINDS
    feature_config: dict = field(default_factory=dict)
    randomisation: Randomisation = field(default_factory=Randomisation)
    model_params: dict = field(default_factory=dict)
    cruise_only: bool = True  # fly the trajectory only (features see the cruise, as on real logs)
    physics: str | None = None  # a calibrated physics preset (e.g. "afar:fit328"), replaces ``model``
    suite: str | None = None  # "unseen": flights of the benchmark family (mission.localize.suite), not the mission
    suite_family: str = "afar"
    suite_center: str = "afar"

    @property
    def physics_label(self) -> str:
        """The propagation model's name as reports show it (``preset:afar:fit328`` or ``e2r``)."""
        return physics_label(self.to_dict())

    def to_dict(self) -> dict:
        d = asdict(self)
        d["features"] = list(self.features)
        return d

    @classmethod
    def from_dict(cls, d: dict) -> DatasetConfig:
        d = dict(d)
        d["randomisation"] = Randomisation.from_dict(d.get("randomisation", {}))
        d["features"] = tuple(d.get("features", FEATURE_KINDS))
        return cls(**d)


def physics_label(config: dict) -> str:
    """The physics of a dataset configuration dict (a manifest's ``config``): ``preset:NAME`` or the model."""
    if config.get("suite"):
        return f"suite:{config['suite']}:{config.get('suite_family', 'afar')}"
    return f"preset:{config['physics']}" if config.get("physics") else str(config.get("model"))


# ------------------------------------------------------------------------------------------ one flight


def flight_rng(seed: int, i: int) -> np.random.Generator:
    """The generator of flight ``i``: the ``i``-th child of ``SeedSequence(seed)`` (as ``spawn`` makes)."""
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(i,)))


def _uniform(rng: np.random.Generator, rng_range: tuple[float, float] | None, default: float) -> float:
    if rng_range is None:
        return float(default)
    lo, hi = float(rng_range[0]), float(rng_range[1])
    return float(rng.uniform(lo, hi)) if hi > lo else lo


def _choice(rng: np.random.Generator, options: Sequence[str], default: str) -> str:
    if not options:
        return default
    return str(options[int(rng.integers(len(options)))]) if len(options) > 1 else str(options[0])


def _trajectory_params(name: str, rng: np.random.Generator, base: dict, random_params: bool) -> dict:
    """Generator parameters: the mission's own ones (same generator) or a random draw."""
    if not random_params:
        return dict(base)
    p: dict = {"spacing_m": float(rng.uniform(16.0, 32.0)), "margin_m": float(rng.uniform(3.0, 10.0))}
    if name == "spiral":
        p["start"] = ("se", "sw", "ne", "nw")[int(rng.integers(4))]
    elif name == "lawnmower":
        p["direction"] = ("ew", "ns")[int(rng.integers(2))]
    elif name == "random_waypoints":
        p = {"n": int(rng.integers(8, 25)), "seed": int(rng.integers(2**31)), "margin_m": p["margin_m"]}
    elif name == "expanding_square":
        p["spacing_m"] = float(rng.uniform(20.0, 35.0))
    return p


@dataclass
class FlightDraw:
    """One simulated flight of a dataset: its draws and the per-sample arrays the features use."""

    index: int
    tx_enu: np.ndarray
    params: dict
    trajectory: str
    pattern: str
    enu: np.ndarray
    attitude_rad: np.ndarray
    rss_dbm: np.ndarray


class FlightSimulator:
    """Simulates flight ``i`` of a dataset configuration (built once per worker process)."""

    def __init__(self, cfg: DatasetConfig) -> None:
        from mission.localize.features import FeatureConfig
        from mission.spec import load_mission

        self.cfg = cfg
        self.spec = load_mission(cfg.mission)
        self.fcfg = FeatureConfig.from_dict(cfg.feature_config) if cfg.feature_config else FeatureConfig()
        self.sim = self.spec.sim_config()
        self._models: dict = {}
        self._preset_spec: dict | None = None
        if cfg.physics:
            from mission.physics.presets import load_preset

            self._preset_spec = {**load_preset(cfg.physics), **cfg.model_params}

    def _model(self, pattern: str, beta: float | None, eps_r: float | None, rx_h: float, tx_h: float,
               jitter: float = 0.0):
        from mission.physics import make_model

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
        from mission.physics.presets import build_model

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
        """Draw and fly flight ``i`` (deterministic in ``(cfg, i)``)."""
        from mission.simulate import simulate_flight
        from mission.trajectory.generators import generate

        cfg, r, spec = self.cfg, self.cfg.randomisation, self.spec
        if cfg.suite:
            return self._draw_suite(i)
        rng = flight_rng(cfg.seed, i)
        xy = spec.field.rover_area.sample_uniform(1, rng)[0]
        alt = _uniform(rng, r.altitude_m, spec.altitude_m)
        traj = _choice(rng, r.trajectories, spec.trajectory.generator)
        same = traj == spec.trajectory.generator
        tparams = _trajectory_params(traj, rng, spec.trajectory.params if same else {}, r.random_params)
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
        # draws added after the first release: taken only when switched on, so older configs keep their bytes
        fixed_h = None
        if r.fixed_heading is not None and r.fixed_heading > 0:
            fixed = bool(rng.uniform() < r.fixed_heading)
            h = float(rng.uniform(0.0, 360.0))
            fixed_h = h if fixed else None
        speed = None if r.speed_mps is None else _uniform(rng, r.speed_mps, 0.0)
        shadow = 0.0 if r.shadowing_db is None else _uniform(rng, r.shadowing_db, 0.0)
        corr = self.sim.shadowing_corr_m if r.shadowing_corr_m is None else _uniform(rng, r.shadowing_corr_m, 0.0)
        jitter = 0.0
        if r.physics_heading_jitter_deg:
            jitter = float(rng.uniform(-r.physics_heading_jitter_deg, r.physics_heading_jitter_deg))

        if traj == "waypoints" or (spec.trajectory.waypoints is not None and same and not r.random_params):
            wps = np.array(spec.waypoints_enu(), dtype=float)
            wps[:, 2] = alt
        else:
            wps = generate(traj, spec.field, alt, **tparams)
        tx = np.array([xy[0], xy[1], tx_height])
        model = self._model(pattern, beta, eps_r, rx_h, tx_h, jitter)
        kin = self.sim.kinematics
        if fixed_h is not None or speed is not None:
            kin = replace(kin, heading_deg=fixed_h if fixed_h is not None else kin.heading_deg,
                          cruise_speed_mps=speed if speed is not None else kin.cruise_speed_mps)
        sim = replace(self.sim, noise_db=noise, rss_offset_db=offset, kinematics=kin, shadowing_db=shadow,
                      shadowing_corr_m=corr)
        fl = simulate_flight(wps, tx, model, sim, rng)
        enu, att, rss = fl.enu, fl.attitude_rad, fl.rss_dbm
        if keep < 1.0:
            n = len(rss)
            a = int(start * n)
            b = max(a + int(keep * n), a + 1)
            enu, att, rss = enu[a:b], att[a:b], rss[a:b]
        params = {
            "altitude_m": alt,
            "offset_db": offset,
            "beta": np.nan if beta is None else beta,
            "eps_r": np.nan if eps_r is None else eps_r,
            "tx_height_m": tx_height,
            "noise_db": noise,
            "rx_heading_deg": self._preset_heading() + jitter if cfg.physics else rx_h,
            "tx_heading_deg": tx_h,
            "keep_fraction": keep,
            "fixed_heading_deg": np.nan if fixed_h is None else fixed_h,
            "speed_mps": kin.cruise_speed_mps,
            "shadowing_db": shadow,
            "shadowing_corr_m": corr if shadow > 0 else np.nan,
            "trajectory_params": tparams,
        }
        return FlightDraw(i, tx, params, traj, pattern or "default", enu, att, rss)

    def _draw_suite(self, i: int) -> FlightDraw:
        """Flight ``i`` of the benchmark family (seed ``cfg.seed``), cut to the cruise as ``localize`` cuts a log."""
        from mission.localize.preprocess import cruise_mask
        from mission.localize.suite import unseen_flight

        f = unseen_flight(self.cfg.seed, i, self.cfg.suite_family, self.cfg.suite_center)
        c, d = f.log.columns, f.draw
        keep = cruise_mask(c["rel_alt_m"]).mask
        enu = f.log.enu()[keep]
        att = np.deg2rad(np.stack([c["roll_deg"], c["pitch_deg"], c["yaw_deg"]], axis=1)[keep])
        spec = d["physics"]["spec"]
        ground = spec.get("ground") or {}
        params = {
            "altitude_m": d["altitude_m"], "offset_db": d["rss_offset_db"], "beta": np.nan,
            "eps_r": ground.get("eps_r", np.nan), "tx_height_m": d["tx_height_m"], "noise_db": d["noise_db"],
            "rx_heading_deg": spec.get("rx_heading_deg", 0.0), "tx_heading_deg": spec.get("tx_heading_deg", 0.0),
            "keep_fraction": d["keep_fraction"],
            "fixed_heading_deg": d["fixed_heading_deg"] if d["heading_habit"] == "fixed" else np.nan,
            "speed_mps": d["speed_mps"], "shadowing_db": d["shadowing_db"], "shadowing_corr_m": d["shadowing_corr_m"],
            "trajectory_params": d["trajectory_params"],
        }
        tx = np.array([*d["tx_xy"], d["tx_height_m"]])
        return FlightDraw(i, tx, params, d["trajectory"], "default", enu, att, np.asarray(c["rss_dbm"])[keep])

    def features(self, fd: FlightDraw) -> dict[str, np.ndarray]:
        """The stored row of one flight (features, truth, parameters)."""
        from mission.localize.features import cluster_features, normalised_rss

        traj_names = self._traj_names()
        pat_names = self._pattern_names()
        row: dict[str, np.ndarray] = {}
        if "clustering" in self.cfg.features:
            row["clustering"] = cluster_features(fd.enu[:, 0], fd.enu[:, 1], fd.rss_dbm, self.fcfg)
        if "normalised_rss" in self.cfg.features:
            row["normalised_rss"] = normalised_rss(fd.rss_dbm, self.fcfg)
        p = {**fd.params, "trajectory": traj_names.index(fd.trajectory), "pattern": pat_names.index(fd.pattern)}
        row["params"] = np.array([p[k] for k in PARAM_NAMES], dtype=float)  # column order = PARAM_NAMES
        row["tx_enu"] = fd.tx_enu
        row["n_samples"] = np.array(len(fd.rss_dbm))
        row["index"] = np.array(fd.index)
        return row

    def _traj_names(self) -> list[str]:
        return trajectory_names(self.cfg, self.spec.trajectory.generator)

    def _pattern_names(self) -> list[str]:
        return pattern_names(self.cfg)


def trajectory_names(cfg: DatasetConfig, mission_generator: str) -> list[str]:
    """Index -> trajectory name of the ``params[:, trajectory]`` column."""
    if cfg.suite:
        from mission.trajectory.generators import GENERATORS

        return list(GENERATORS)
    return list(cfg.randomisation.trajectories) or [mission_generator]


def pattern_names(cfg: DatasetConfig) -> list[str]:
    """Index -> pattern name of the ``params[:, pattern]`` column."""
    return list(cfg.randomisation.patterns) or ["default"]


# -------------------------------------------------------------------------------------- workers, chunks

_WORKER: FlightSimulator | None = None


def _init_worker(cfg_dict: dict) -> None:
    global _WORKER
    import os

    os.environ.setdefault("OMP_NUM_THREADS", "1")
    try:
        from threadpoolctl import threadpool_limits

        threadpool_limits(1)
    except ImportError:  # pragma: no cover
        pass
    _WORKER = FlightSimulator(DatasetConfig.from_dict(cfg_dict))


def _work(i: int) -> dict[str, np.ndarray]:
    assert _WORKER is not None
    return _WORKER.features(_WORKER.draw(i))


def _stack(rows: list[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    out = {}
    for k in rows[0]:
        a = np.stack([r[k] for r in rows])
        if k == "n_samples":
            out[k] = a.astype(np.int32)
        elif k == "index":
            out[k] = a.astype(np.int64)
        else:
            out[k] = a.astype(np.float32)
    return out


def _npz_bytes(arrays: dict[str, np.ndarray]) -> bytes:
    """Deterministic npz bytes (``np.savez_compressed`` writes fixed zip timestamps)."""
    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)
    return buf.getvalue()


def iter_rows(
    cfg: DatasetConfig, workers: int = 1, indices: Sequence[int] | None = None
) -> Iterator[dict[str, np.ndarray]]:
    """Rows of flights ``indices`` (default all) in index order, computed by ``workers`` processes."""
    idx = list(range(cfg.n)) if indices is None else list(indices)
    if workers <= 1:
        _init_worker(cfg.to_dict())
        for i in idx:
            yield _work(i)
        return
    import multiprocessing as mp

    ctx = (
        mp.get_context("spawn") if mp.get_start_method(allow_none=True) != "fork" else mp.get_context("fork")
    )
    with ctx.Pool(workers, initializer=_init_worker, initargs=(cfg.to_dict(),)) as pool:
        yield from pool.imap(_work, idx, chunksize=4)


def check_config(cfg: DatasetConfig) -> None:
    """Refuse configurations that would silently do something else than asked (InputError naming the field)."""
    r = cfg.randomisation
    if cfg.suite:
        from mission.localize.suite import BENCHMARK_SEED, FAMILIES, SUITES

        if cfg.suite not in SUITES or cfg.suite_family not in FAMILIES:
            raise InputError(f"unknown suite {cfg.suite!r} / family {cfg.suite_family!r}", field="suite")
        if cfg.seed == BENCHMARK_SEED:
            raise InputError(f"seed {BENCHMARK_SEED} is the benchmark's own: train on other seeds", field="seed")
        if cfg.physics or r != Randomisation():
            raise InputError("--suite draws every axis itself: no --physics or randomisation flags", field="suite")
    if cfg.physics:
        from mission.physics.presets import load_preset

        try:
            load_preset(cfg.physics)
        except KeyError as e:
            raise InputError(f"physics preset {cfg.physics!r} is incomplete ({e})", field="physics") from None
        for name in ("patterns", "beta", "eps_r"):
            if getattr(r, name):
                raise InputError(f"{name} randomisation applies to make_model models, not to the physics "
                                 f"preset {cfg.physics!r}", field=name)
    elif r.physics_heading_jitter_deg:
        raise InputError("physics_heading_jitter_deg needs a physics preset", field="physics_heading_jitter_deg")
    if r.fixed_heading is not None and not 0.0 <= r.fixed_heading <= 1.0:
        raise InputError(f"fixed_heading is a probability in [0, 1], got {r.fixed_heading}", field="fixed_heading")
    for name in ("speed_mps", "shadowing_corr_m"):
        v = getattr(r, name)
        if v is not None and min(v) <= 0:
            raise InputError(f"{name} must be > 0, got {v}", field=name)


def generate_dataset(
    cfg: DatasetConfig,
    out_dir: str | Path,
    workers: int = 1,
    progress: Callable[[int, int], None] | None = None,
    overwrite: bool = False,
) -> dict:
    """Simulate all flights of ``cfg`` and write the chunks and the manifest to ``out_dir``.

    ``progress(done, total)`` is called after each flight.  Returns the manifest.
    """
    from mission import __version__
    from mission.localize.features import FeatureConfig
    from mission.spec import load_mission

    if cfg.n < 1 or cfg.chunk < 1:
        raise InputError(f"need n >= 1 and chunk >= 1, got n={cfg.n}, chunk={cfg.chunk}")
    bad = [f for f in cfg.features if f not in FEATURE_KINDS]
    if bad:
        raise InputError(
            f"unknown feature kind {bad[0]!r} (expected {', '.join(FEATURE_KINDS)})", field="features"
        )
    check_config(cfg)
    out = Path(out_dir)
    if (out / "manifest.json").exists() and not overwrite:
        raise InputError("a dataset exists already here (use --overwrite)", source=str(out))
    out.mkdir(parents=True, exist_ok=True)
    for old in out.glob("chunk_*.npz"):
        old.unlink()
    spec = load_mission(cfg.mission)
    fcfg = FeatureConfig.from_dict(cfg.feature_config) if cfg.feature_config else FeatureConfig()
    t0 = time.perf_counter()
    chunks: list[dict] = []
    buf: list[dict[str, np.ndarray]] = []
    done = 0

    def flush() -> None:
        arrays = _stack(buf)
        data = _npz_bytes(arrays)
        name = f"chunk_{len(chunks):05d}.npz"
        (out / name).write_bytes(data)
        chunks.append(
            {
                "file": name,
                "n": len(buf),
                "first_index": int(arrays["index"][0]),
                "sha256": hashlib.sha256(data).hexdigest(),
            }
        )
        buf.clear()

    for row in iter_rows(cfg, workers):
        buf.append(row)
        done += 1
        if progress:
            progress(done, cfg.n)
        if len(buf) == cfg.chunk:
            flush()
    if buf:
        flush()
    elapsed = time.perf_counter() - t0
    manifest = {
        "format": FORMAT,
        "software_version": __version__,
        "config": cfg.to_dict(),
        "mission_name": spec.name,
        "mission_generator": spec.trajectory.generator,
        "mission_altitude_m": spec.altitude_m,
        "field_origin": spec.field.origin.to_dict(),
        "feature_config": fcfg.to_dict(),
        "param_names": list(PARAM_NAMES),
        "trajectory_names": trajectory_names(cfg, spec.trajectory.generator),
        "pattern_names": pattern_names(cfg),
        "seeding": "flight i uses np.random.SeedSequence(seed, spawn_key=(i,)) (= SeedSequence(seed).spawn(n)[i])",
        "chunks": chunks,
        "n": cfg.n,
        "generation": {
            "workers": workers,
            "seconds": round(elapsed, 2),
            "flights_per_s": round(cfg.n / elapsed, 3) if elapsed > 0 else None,
        },
    }
    # the timing block differs between runs; everything else is deterministic
    (out / "manifest.json").write_text(json.dumps(manifest, indent=2, default=float))
    return manifest


# --------------------------------------------------------------------------------------------- reading


def read_manifest(path: str | Path) -> dict:
    """The manifest of a dataset folder (or of the manifest file itself)."""
    p = Path(path)
    mf = p / "manifest.json" if p.is_dir() else p
    if not mf.is_file():
        raise InputError("not a dataset (no manifest.json)", source=str(p))
    m = json.loads(mf.read_text())
    if m.get("format") != FORMAT:
        raise InputError(f"unknown dataset format {m.get('format')!r} (expected {FORMAT})", source=str(mf))
    return m


def load_dataset(
    path: str | Path, keys: Sequence[str] = ("clustering", "tx_enu", "params"), verify: bool = False
) -> tuple[dict[str, np.ndarray], dict]:
    """Concatenate the arrays ``keys`` of all chunks; returns (arrays, manifest).

    ``verify`` checks every chunk's sha256 against the manifest.
    """
    root = Path(path)
    m = read_manifest(root)
    parts: dict[str, list[np.ndarray]] = {k: [] for k in keys}
    for c in m["chunks"]:
        f = root / c["file"]
        if verify:
            h = hashlib.sha256(f.read_bytes()).hexdigest()
            if h != c["sha256"]:
                raise InputError("chunk digest does not match the manifest", source=str(f))
        with np.load(f) as z:
            for k in keys:
                if k not in z:
                    raise InputError(f"dataset has no {k!r} array (generated without it?)", source=str(f))
                parts[k].append(z[k])
    return {k: np.concatenate(v) for k, v in parts.items()}, m


def dataset_config(manifest: dict) -> DatasetConfig:
    """The ``DatasetConfig`` recorded in a manifest (to regenerate flights, e.g. for classical methods)."""
    return DatasetConfig.from_dict(manifest["config"])

"""What defines a simulated dataset: ``DatasetConfig`` (recorded in its manifest; same config + seed
= same bytes), its ``Randomisation`` and the checks that refuse configurations that would do
something else than asked.

Domain randomisation (each switchable; ``Randomisation``):

- ``altitude_m``: cruise altitude uniform in a range (AFAR teams flew 20-47 m; the paper 30 m).
- ``offset_db``: a constant RSS offset (a real receiver's dB are not calibrated dBm; the features
  are offset-invariant, so this mainly checks that they are).
- ``trajectories`` with ``random_params``: generator drawn per flight, spacing / margin / start
  corner / direction / waypoint count drawn at random (real AFAR teams flew their own paths).
- ``truncate``: keep only a random contiguous fraction of the cruise (adaptive or interrupted
  flights, e.g. team 288's, cover only part of the field).
- ``patterns``: antenna pattern per flight ("dipole", "measured"); with ``random_heading`` the
  measured pattern's mounting heading on the UAV and the rover is random (their true headings are
  unknown).
- ``beta``: leg-shadowing exponent; ``eps_r``: ground relative permittivity.
- ``tx_height_m``: transmitter height (AFAR rover antenna about 1.5 m; paper 5 m).
- ``noise_db``: per-flight noise standard deviation.
- ``fixed_heading``: probability that a flight holds one compass heading (uniform 0-360 deg) instead
  of yawing along the track; the AFAR 2023 vehicles held a near-constant heading for the whole
  cruise, which with a directional UAV antenna fixes the antenna's world orientation.
- ``speed_mps``: cruise speed (AFAR team 288 crept at about 1 m/s median, team 328 flew about 4
  m/s).
- ``shadowing_db`` / ``shadowing_corr_m``: a spatially correlated shadowing field per flight
  (``mission.simulate.shadowing_field``); real residuals persist over tens of metres.
- ``physics_heading_jitter_deg``: with a physics preset, the preset's UAV-antenna heading is
  jittered by U(-j, j) per flight (its fit is uncertain by several degrees and differs between
  teams).
- ``drag_pitch_deg_per_mps``: the vehicle's steady nose-down pitch per m/s of airspeed
  (``Kinematics.drag_pitch_deg_per_mps``; the default 0.6 cruises at about -3 deg as AFAR's
  vehicles did, ArduCopter SITL cruises at about -14 deg (2.8), PX4 SITL at about -28 deg (5.6)): a
  network trained on level cruise never saw the dipole tilted that far.

Physics: ``model`` names one of ``make_model``'s models, or ``physics`` names a calibrated preset of
``mission.physics.presets`` (``afar``, or a fold such as ``afar:fit328`` fitted on team 328 only),
which replaces it.  Pattern / beta / eps_r randomisation apply to ``make_model`` models only.


Storage (``DIR``): ``manifest.json`` (every setting, the seed, the feature configuration, the field
origin, the chunk list with sha256 digests) and ``chunk_00000.npz`` ... each holding, for its
flights (float32

``suite="unseen"`` replaces all of the above by the unseen-flight benchmark's family
(``mission.workshop.suite``; ``suite_family`` a built-in name or a physics family .json,
``suite_center`` the preset at the afar family's centre): every axis is drawn there, and the seed of
the benchmark itself (2026) is refused.

``PARAM_NAMES`` is the column order of a dataset's ``params`` array; each flight's parameters are a
dict keyed by these names (``mission.workshop.flight_draws``), so the order lives here only.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields

from mission.fields import Fields
from mission.physics.presets import load_preset
from mission.trajectory.generators import GENERATORS
from mission.workshop.suite import BENCHMARK_SEED, SUITES, resolve_family

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
    "drag_pitch_deg_per_mps",
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
    drag_pitch_deg_per_mps: tuple[float, float] | None = None

    @classmethod
    def from_dict(cls, d: dict) -> Randomisation:
        Fields(d, None, "randomisation").done(f.name for f in fields(cls))
        conv = {k: (tuple(v) if isinstance(v, list) else v) for k, v in d.items()}
        return cls(**conv)


@dataclass(frozen=True)
class DatasetConfig:
    """Everything that defines a dataset (recorded in the manifest; same config + seed = same
    bytes)."""

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
    physics: str | None = (
        None  # a calibrated physics preset (e.g. "afar:fit328"), replaces ``model``
    )
    suite: str | None = (
        None  # "unseen": flights of the benchmark family (mission.workshop.suite), not the mission
    )
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
    """The physics of a dataset configuration dict (a manifest's ``config``): ``preset:NAME`` or the
    model."""
    if config.get("suite"):
        return f"suite:{config['suite']}:{config.get('suite_family', 'afar')}"
    return f"preset:{config['physics']}" if config.get("physics") else str(config.get("model"))


def trajectory_names(cfg: DatasetConfig, mission_generator: str) -> list[str]:
    """Index -> trajectory name of the ``params[:, trajectory]`` column."""
    if cfg.suite:
        return list(GENERATORS)
    return list(cfg.randomisation.trajectories) or [mission_generator]


def pattern_names(cfg: DatasetConfig) -> list[str]:
    """Index -> pattern name of the ``params[:, pattern]`` column."""
    return list(cfg.randomisation.patterns) or ["default"]


def check_config(cfg: DatasetConfig) -> None:
    """Refuse configurations that would silently do something else than asked (InputError naming the
    field)."""
    r = cfg.randomisation
    c, rf = Fields(cfg.to_dict()), Fields(asdict(r))
    c.int_("n", lo=1)
    c.int_("chunk", lo=1)
    bad = [f for f in cfg.features if f not in FEATURE_KINDS]
    if bad:
        raise c.err(
            "features", f"unknown feature kind {bad[0]!r} (expected {', '.join(FEATURE_KINDS)})"
        )
    if cfg.suite:
        c.str_("suite", None, SUITES)
        resolve_family(cfg.suite_family)  # a built-in name or a readable, valid family file
        if cfg.seed == BENCHMARK_SEED:
            raise c.err(
                "seed", f"seed {BENCHMARK_SEED} is the benchmark's own: train on other seeds"
            )
        if cfg.physics or r != Randomisation():
            raise c.err(
                "suite", "--suite draws every axis itself: no --physics or randomisation flags"
            )
    if cfg.physics:
        try:
            load_preset(cfg.physics)
        except KeyError as e:
            raise c.err("physics", f"physics preset {cfg.physics!r} is incomplete ({e})") from None
        for name in ("patterns", "beta", "eps_r"):
            if getattr(r, name):
                raise rf.err(
                    name,
                    f"{name} randomisation applies to make_model models, not to the physics "
                    f"preset {cfg.physics!r}",
                )
    elif r.physics_heading_jitter_deg:
        raise rf.err("physics_heading_jitter_deg", "needs a physics preset")
    rf.num("fixed_heading", None, 0.0, 1.0)  # a probability
    for name in ("speed_mps", "shadowing_corr_m"):
        rf.span(name, None, 0.0, strict_lo=True, ordered=False)
    drag = rf.span("drag_pitch_deg_per_mps", None, 0.0, ordered=False)
    if drag is not None and max(drag) >= 45.0:
        raise rf.err("drag_pitch_deg_per_mps", f"must be below 45 deg per m/s, got {list(drag)!r}")

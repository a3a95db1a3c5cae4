"""YAML mission files -> typed, validated ``MissionSpec`` (the schema is documented in
missions/spiral.yaml).

A mission names its field (AFAR by default), altitude, speed, time budget, fence margin, take-off
and return behaviour, the trajectory (a generator with parameters, or explicit waypoints), the
simulated RSS source and the vehicle connection.  Files are read with ``yaml.safe_load``; every bad
or unknown key is an ``InputError`` naming the file and the dotted key
(``trajectory.params.spacing_m``), so a user fixes a mission from one line of output.
"""

from __future__ import annotations

import math
from dataclasses import MISSING, dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from mission.adaptive.config import parse_adaptive
from mission.defaults import (
    BUDGET_POLICIES,
    DEFAULT_ALTITUDE_M,
    DEFAULT_TX_HEIGHT_M,
    MAX_DURATION_S,
    MAX_SPEEDUP,
)
from mission.errors import InputError
from mission.fields import Fields, is_number, read_yaml
from mission.geo import AFAR_GEOMETRY, Area, Field, Origin, afar_field
from mission.physics import make_model
from mission.shipped import missions_dir, resolve_shipped
from mission.simulate import SimConfig
from mission.trajectory.checks import RETURN_OVERSHOOT_M
from mission.trajectory.generators import GENERATORS, generate
from mission.trajectory.kinematics import Kinematics


class _Reader(Fields):
    """A mission file's mappings: an unknown key points at the annotated schema."""

    hint = "see the schema at the top of missions/spiral.yaml"


DEFAULT_MISSION = missions_dir() / "spiral.yaml"  # the checkout's missions/ or the installed copy
RETURN_BEHAVIOURS = ("rtl", "land")
# logging.on_write_error: what a failed log write does
WRITE_ERROR_POLICIES = (
    "return",
    "continue",
)
MAX_LOCAL_M = (
    1e6  # |ENU coordinate| of a position in a mission file (a waypoint at 1e300 overflowed)
)
MAX_ALTITUDE_M = 1e4  # altitudes and heights in a mission file (1e308 overflowed)
MAX_NAME_CHARS = 100  # a mission name becomes a folder and file name
MAX_MISSION_BYTES = 1_000_000  # the shipped missions are ~2 kB; a 30 MB file ran for minutes
# heading_deg (fixed-heading flight) is a simulator/dataset option: the mission runner does not
# command yaw, so a mission may not ask for it (its vehicle would fly differently from the simulated
# one)
_KIN_FIELDS = tuple(
    k for k in Kinematics.__dataclass_fields__ if k not in ("cruise_speed_mps", "heading_deg")
)


@dataclass(frozen=True)
class TrajectorySpec:
    """A generator name and its parameters, or explicit waypoints (``generator == "waypoints"``)."""

    generator: str
    params: dict = field(default_factory=dict)
    waypoints: np.ndarray | None = (
        None  # (K, 3) ENU; z = the mission altitude unless given per waypoint
    )


@dataclass(frozen=True)
class SourceSpec:
    """The simulated RSS source: propagation model, transmitter (ENU or "random"), seed and
    noise."""

    model: str = "e2r"
    tx: tuple[float, float, float] | str = "random"
    tx_height_m: float = DEFAULT_TX_HEIGHT_M
    seed: int = 0
    noise_db: float = SimConfig.noise_db  # the simulator's own defaults: one home (SimConfig)
    attitude_perturbation_deg: float = SimConfig.attitude_perturbation_deg
    sample_period_s: float = SimConfig.dt_s
    model_params: dict = field(default_factory=dict)


@dataclass(frozen=True)
class VehicleSpec:
    """How to reach the vehicle: a MAVSDK connection URL, or None for the built-in simulated
    vehicle."""

    connection: str | None = None
    speedup: float = 1.0
    # overrides of Kinematics fields (accel_mps2, ...)
    kinematics: dict = field(default_factory=dict)


@dataclass(frozen=True)
class MissionSpec:
    """A validated mission; positions are ENU metres about ``field.origin``."""

    name: str
    path: Path | None
    field: Field
    altitude_m: float = DEFAULT_ALTITUDE_M
    cruise_speed_mps: float = 5.5
    time_budget_s: float = 600.0
    budget_policy: str = (
        "trim"  # BUDGET_POLICIES: when the landing would pass the budget less its reserve
    )
    budget_reserve_s: float = 10.0  # kept free at landing by the policy
    fence_margin_m: float = 3.0
    home_margin_m: float = (
        2.0  # home keeps the autopilots' known return overshoot plus this from the fence
    )
    altitude_limits_m: tuple[float, float] = (10.0, 120.0)
    home_enu: np.ndarray = field(default_factory=lambda: np.zeros(3))
    return_behaviour: str = "rtl"
    trajectory: TrajectorySpec = field(default_factory=lambda: TrajectorySpec("spiral"))
    source: SourceSpec = field(default_factory=SourceSpec)
    vehicle: VehicleSpec = field(default_factory=VehicleSpec)
    adaptive: Any = (
        None  # mission.adaptive.config.AdaptiveSpec when the file has an ``adaptive:`` block
    )
    on_write_error: str = (
        "return"  # ``logging.on_write_error``: a failed log write returns to launch or not
    )

    @property
    def source_name(self) -> str:
        """The file for error messages ("<mission>" when built in code)."""
        return str(self.path) if self.path else f"<mission {self.name}>"

    def kinematics(self) -> Kinematics:
        """The vehicle kinematics (cruise speed plus ``vehicle.kinematics`` overrides)."""
        return Kinematics(cruise_speed_mps=self.cruise_speed_mps, **self.vehicle.kinematics)

    def trajectory_meta(self) -> dict:
        """What a flight log's sidecar records of the path (``trajectory``): generator, its
        parameters and the cruise altitude, so a localizer can tell which networks were trained on
        this kind of flight."""
        t = self.trajectory
        return {
            "generator": t.generator,
            "params": dict(t.params),
            "altitude_m": float(self.altitude_m),
        }

    def waypoints_enu(self) -> np.ndarray:
        """The trajectory (K, 3) ENU at cruise altitude (generated, or the explicit waypoints)."""
        t = self.trajectory
        if t.waypoints is not None:
            return np.array(t.waypoints, dtype=float)

        try:
            return generate(t.generator, self.field, self.altitude_m, **t.params)
        except InputError as e:
            key = (
                "trajectory.generator"
                if e.field == "generator"
                else f"trajectory.params.{e.field}"
                if e.field
                else "trajectory.params"
            )
            msg = str(e).split(": ", 1)[1] if e.field else str(e)
            raise InputError(msg, source=self.source_name, field=key) from None

    def flight_path_enu(self) -> np.ndarray:
        """Home (ground) -> climb -> waypoints -> back over home -> land; with ``return_behaviour:
        land`` the vehicle lands below the last waypoint instead."""
        w = self.waypoints_enu()
        home = np.asarray(self.home_enu, dtype=float)
        up = np.array([home[0], home[1], w[0, 2]])
        if self.return_behaviour == "land":
            tail = [np.array([w[-1, 0], w[-1, 1], home[2]])]
        else:
            tail = [np.array([home[0], home[1], w[-1, 2]]), home]
        return np.vstack([home, up, w, *tail])

    def resolve_tx(self, rng: np.random.Generator) -> np.ndarray:
        """The transmitter (3,) ENU: the configured one, or uniform in the rover area at
        ``tx_height_m``."""
        if isinstance(self.source.tx, str):
            xy = self.field.rover_area.sample_uniform(1, rng)[0]
            return np.array([xy[0], xy[1], self.source.tx_height_m])
        return np.array(self.source.tx, dtype=float)

    def transmitter(self, seed: int | None = None) -> np.ndarray:
        """The simulated transmitter of draw ``seed`` (default: the mission's ``source.seed``): the
        one home of that draw, so ``rfsl simulate`` and ``fly-mission`` put seed N's transmitter in
        the same place (``resolve_tx`` with ``default_rng([seed, 1])``, a stream apart from the
        flight's noise)."""
        return self.resolve_tx(
            np.random.default_rng([self.source.seed if seed is None else seed, 1])
        )

    def sim_config(self) -> SimConfig:
        """Simulator settings (sample period, perturbation, noise, kinematics) of this mission."""
        s = self.source
        return SimConfig(
            dt_s=s.sample_period_s,
            attitude_perturbation_deg=s.attitude_perturbation_deg,
            noise_db=s.noise_db,
            kinematics=self.kinematics(),
        )

    def propagation_model(self):
        """The ``mission.physics`` model named by ``source.model`` (with
        ``source.model_params``)."""
        try:
            return make_model(self.source.model, **self.source.model_params)
        except (ValueError, TypeError, KeyError) as e:
            if isinstance(e, InputError):
                raise
            raise InputError(
                f"cannot build propagation model '{self.source.model}': {e}",
                source=self.source_name,
                field="source.model",
            ) from None


# ---------------------------------------------------------------------------------------------
# loading


def _default(cls: type, name: str) -> Any:
    """The dataclass default of ``cls.name``: a key the file omits gets it, so each default is
    written once."""
    f = cls.__dataclass_fields__[name]
    return f.default if f.default is not MISSING else f.default_factory()


def _point(v: Any, r: _Reader, key: str, origin: Origin) -> np.ndarray:
    """A position: [x, y] / [x, y, z] ENU metres, or {lat, lon[, height_m]} (height above the
    origin)."""
    if isinstance(v, dict):
        pr = _Reader(v, r.src, key)
        lat, lon = pr.num("lat", 0.0, -90, 90), pr.num("lon", 0.0, -180, 180)
        if not (pr.has("lat") and pr.has("lon")):
            raise InputError("needs both 'lat' and 'lon'", source=r.src, field=key)
        h = pr.num("height_m", 0.0, -MAX_LOCAL_M, MAX_LOCAL_M) if pr.has("height_m") else math.nan
        pr.done()
        e = origin.to_enu(lat, lon)
        return np.array([e[0], e[1], h])
    if isinstance(v, list | tuple) and len(v) in (2, 3) and all(is_number(c) for c in v):
        if any(abs(c) > MAX_LOCAL_M for c in v):
            raise InputError(
                f"{v!r} is more than {MAX_LOCAL_M:g} m from the origin (ENU metres)",
                source=r.src,
                field=key,
            )
        return np.array([float(v[0]), float(v[1]), float(v[2]) if len(v) == 3 else math.nan])
    raise InputError(
        f"expected [x, y], [x, y, z] (ENU metres) or {{lat: .., lon: ..}}, got {v!r}",
        source=r.src,
        field=key,
    )


def _area(v: Any, r: _Reader, key: str, name: str, origin: Origin) -> Area:
    """An area: a lat/lon box {lat_min, lat_max, lon_min, lon_max}, {polygon: [[lat, lon], ...]} or
    {enu: [[x, y], ...]}."""
    ar = _Reader(v, r.src, key)
    try:
        if ar.has("polygon"):
            ll = np.array(ar.raw("polygon"), dtype=float)
            if ll.ndim != 2 or ll.shape[1] != 2 or len(ll) < 3:
                raise ar.err("polygon", "expected at least 3 [lat, lon] vertices")
            a = Area.from_geodetic(name, ll, origin)
        elif ar.has("enu"):
            a = Area(name, np.array(ar.raw("enu"), dtype=float))
        else:
            box = {}
            for k in ("lat_min", "lat_max", "lon_min", "lon_max"):
                if not ar.has(k):
                    raise ar.err(
                        k, "missing (an area is a lat/lon box, {polygon: ...} or {enu: ...})"
                    )
                box[k] = ar.num(k, 0.0, -180.0, 180.0)
            if box["lat_min"] >= box["lat_max"] or box["lon_min"] >= box["lon_max"]:
                raise ar.err("lat_min", "needs lat_min < lat_max and lon_min < lon_max")
            a = Area.from_box(name, box, origin)
    except (TypeError, ValueError) as e:
        if isinstance(e, InputError) and e.source:
            raise
        raise InputError(f"bad area: {e}", source=r.src, field=key) from None
    ar.done()
    return a


def _field(r: _Reader) -> tuple[Field, tuple[float, float] | None]:
    fr = r.sub("field")
    preset = fr.str_("preset", "afar", ("afar", "custom"))
    if preset == "afar" and not any(fr.has(k) for k in ("origin", "flight_area", "rover_area")):
        fr.str_("name", None)
        fr.done()
        f = afar_field()
        return f, f.takeoff_home
    if fr.has("origin"):
        orr = fr.sub("origin")
        for k in ("lat_deg", "lon_deg"):
            if not orr.has(k):
                raise orr.err(k, "missing (the origin needs lat_deg, lon_deg and optionally alt_m)")
        origin = Origin(
            orr.num("lat_deg", 0.0, -90, 90),
            orr.num("lon_deg", 0.0, -180, 180),
            orr.num("alt_m", 0.0),
        )
        orr.done()
    elif preset == "afar":
        fa = AFAR_GEOMETRY["flight_area"]
        origin = Origin(fa["lat_min"], fa["lon_min"], 0.0)
    else:
        raise fr.err("origin", "missing (a custom field needs an origin)")
    base = afar_field(origin=origin) if preset == "afar" else None
    areas = {}
    for k, nice in (("flight_area", "flight area"), ("rover_area", "rover area")):
        if fr.has(k):
            areas[k] = _area(fr.raw(k), fr, fr.k(k), nice, origin)
        elif base is not None:
            areas[k] = getattr(base, k)
        else:
            raise fr.err(k, "missing (a custom field needs both areas)")
    name = fr.str_("name", "AFAR" if preset == "afar" else "custom field")
    fr.done()
    home = base.takeoff_home if base is not None else None
    return Field(
        origin, areas["flight_area"], areas["rover_area"], name=name, takeoff_home=home
    ), home


def mission_name(name: str, src: str) -> str:
    """``name`` if it is safe as one folder or file name (flights go to ``<out>/<name>_<time>/``,
    simulated logs to ``<out>/<name>_sim_...csv``), else an InputError: no path separator, no
    '.'/'..', no control character or NUL, at most ``MAX_NAME_CHARS`` (``../../x`` wrote a flight
    two levels above --out)."""
    bad = next((c for c in name if c in "/\\" or ord(c) < 32 or ord(c) == 127), None)
    if bad is not None or name.strip() in ("", ".", "..") or len(name) > MAX_NAME_CHARS:
        why = (
            f"holds {bad!r}"
            if bad is not None
            else f"is {len(name)} characters (at most {MAX_NAME_CHARS})"
            if len(name) > MAX_NAME_CHARS
            else f"is {name!r}"
        )
        raise InputError(
            f"a mission name becomes a folder name: it {why}; use letters, digits, '-', '_' or '.'",
            source=src,
            field="name",
        )
    return name


def _inside(area: Area, p: np.ndarray, clearance: float) -> np.ndarray:
    """``p`` moved straight away from the nearest edge of ``area`` until it is ``clearance`` inside
    (unchanged when it already is): the AFAR launch point is 0.44 m inside the fence, where a real
    autopilot's take-off and landing drift outside (``checks.RETURN_OVERSHOOT_M``)."""
    d = float(area.signed_distance(p[None])[0])
    if d >= clearance:
        return p
    h = 1e-3
    g = np.array(
        [
            area.signed_distance((p + e)[None])[0] - area.signed_distance((p - e)[None])[0]
            for e in (np.array([h, 0.0]), np.array([0.0, h]))
        ]
    ) / (2 * h)
    return p + (clearance - d) * g / max(float(np.hypot(*g)), 1e-9)


def parse_mission(data: Any, path: str | Path | None = None) -> MissionSpec:
    """Validate a parsed YAML document (a mapping) into a ``MissionSpec``."""
    src = str(path) if path else "<mission>"
    r = _Reader(data, src)
    name = mission_name(r.str_("name", Path(path).stem if path else "mission"), src)
    fld, takeoff = _field(r)
    d = partial(_default, MissionSpec)
    altitude = r.num("altitude_m", d("altitude_m"), 0.0, MAX_ALTITUDE_M, strict_lo=True)
    cruise = r.num("cruise_speed_mps", d("cruise_speed_mps"), 0.0, 30.0, strict_lo=True)
    budget = r.num("time_budget_s", d("time_budget_s"), 0.0, MAX_DURATION_S, strict_lo=True)
    policy = r.str_("budget_policy", d("budget_policy"), BUDGET_POLICIES)
    reserve = r.num("budget_reserve_s", d("budget_reserve_s"), 0.0, MAX_DURATION_S)
    if reserve >= budget:
        raise r.err(
            "budget_reserve_s", f"must be less than time_budget_s ({budget:g} s), got {reserve:g}"
        )
    margin = r.num("fence_margin_m", d("fence_margin_m"), 0.0, MAX_LOCAL_M)
    lim = r.raw("altitude_limits_m", list(d("altitude_limits_m")))
    if not (
        isinstance(lim, list)
        and len(lim) == 2
        and all(is_number(x) for x in lim)
        and 0 <= lim[0] < lim[1] <= MAX_ALTITUDE_M
    ):
        raise r.err(
            "altitude_limits_m",
            f"expected [min, max] metres with 0 <= min < max <= {MAX_ALTITUDE_M:g}, got {lim!r}",
        )
    home_margin = r.num("home_margin_m", d("home_margin_m"), 0.0, MAX_LOCAL_M)
    home = _home(r, fld, takeoff, home_margin)
    ret = r.str_("return_behaviour", d("return_behaviour"), RETURN_BEHAVIOURS)

    traj = _trajectory(r, fld.origin, altitude)
    source = _source(r, fld.origin)
    vehicle = _vehicle(r)
    adaptive = parse_adaptive(r.sub("adaptive")) if "adaptive" in r.d else None
    lg = r.sub("logging")
    on_write_error = lg.str_("on_write_error", d("on_write_error"), WRITE_ERROR_POLICIES)
    lg.done()
    r.done()
    return MissionSpec(
        name=name,
        path=Path(path) if path else None,
        field=fld,
        altitude_m=altitude,
        cruise_speed_mps=cruise,
        time_budget_s=budget,
        budget_policy=policy,
        budget_reserve_s=reserve,
        fence_margin_m=margin,
        home_margin_m=home_margin,
        altitude_limits_m=(float(lim[0]), float(lim[1])),
        home_enu=home,
        return_behaviour=ret,
        trajectory=traj,
        source=source,
        vehicle=vehicle,
        adaptive=adaptive,
        on_write_error=on_write_error,
    )


def _home(r: _Reader, fld, takeoff, home_margin: float) -> np.ndarray:
    """``home`` (a position), else the logged take-off point moved inside the flight area, else
    the default; its height 0 unless given."""
    if r.has("home"):
        home = _point(r.raw("home"), r, "home", fld.origin)
    elif takeoff is not None:
        home = fld.origin.to_enu(*takeoff)
        home[2] = math.nan  # ground level (the origin's ground; earth curvature is not a height)
        home[:2] = _inside(fld.flight_area, home[:2], RETURN_OVERSHOOT_M + home_margin + 1.0)
    else:
        home = _default(MissionSpec, "home_enu")
    home = np.array([home[0], home[1], 0.0 if math.isnan(home[2]) else home[2]])
    return home


def _trajectory(r: _Reader, origin, altitude: float) -> TrajectorySpec:
    """The ``trajectory`` section: explicit waypoints (z defaults to ``altitude``) or a generator
    with its parameters."""
    tr = r.sub("trajectory")
    if tr.has("waypoints"):
        wps = tr.raw("waypoints")
        if not isinstance(wps, list) or len(wps) < 1:
            raise tr.err("waypoints", "expected a non-empty list of waypoints")
        pts = np.array(
            [_point(w, tr, f"trajectory.waypoints[{i}]", origin) for i, w in enumerate(wps)]
        )
        pts[np.isnan(pts[:, 2]), 2] = altitude
        gen = tr.str_("generator", "waypoints", ("waypoints",))
        if tr.has("params"):
            raise tr.err("params", "explicit waypoints take no generator parameters")
        traj = TrajectorySpec("waypoints", {}, pts)
    else:
        gen = tr.str_("generator", _default(MissionSpec, "trajectory").generator, tuple(GENERATORS))
        params = tr.raw("params", {}) or {}
        if not isinstance(params, dict):
            raise tr.err("params", f"expected a mapping of generator parameters, got {params!r}")
        traj = TrajectorySpec(gen, dict(params), None)
    tr.done()
    return traj


def _source(r: _Reader, origin) -> SourceSpec:
    """The ``source`` section: the simulated transmitter, its model and noise."""
    sr, ds = r.sub("source"), partial(_default, SourceSpec)
    tx_raw = sr.raw("tx", ds("tx"))
    tx_h = sr.num("tx_height_m", ds("tx_height_m"), 0.0, MAX_ALTITUDE_M)
    if isinstance(tx_raw, str):
        if tx_raw != "random":
            raise sr.err("tx", f"expected 'random' or a position, got '{tx_raw}'")
        tx: tuple[float, float, float] | str = "random"
    else:
        p = _point(tx_raw, sr, "source.tx", origin)
        tx = (float(p[0]), float(p[1]), tx_h if math.isnan(p[2]) else float(p[2]))
    model_params = sr.raw("model_params", {}) or {}
    if not isinstance(model_params, dict):
        raise sr.err("model_params", "expected a mapping")
    source = SourceSpec(
        model=sr.str_("model", ds("model")),
        tx=tx,
        tx_height_m=tx_h,
        seed=sr.int_("seed", ds("seed"), 0, 2**63 - 1),
        noise_db=sr.num("noise_db", ds("noise_db"), 0.0, 100.0),
        attitude_perturbation_deg=sr.num(
            "attitude_perturbation_deg", ds("attitude_perturbation_deg"), 0.0, 45.0
        ),
        sample_period_s=sr.num("sample_period_s", ds("sample_period_s"), 0.0, 10.0, strict_lo=True),
        model_params=dict(model_params),
    )
    sr.done()
    return source


def _vehicle(r: _Reader) -> VehicleSpec:
    """The ``vehicle`` section: connection, speed-up and kinematics overrides."""
    vr = r.sub("vehicle")
    conn = vr.str_("connection", _default(VehicleSpec, "connection"))
    speedup = vr.num("speedup", _default(VehicleSpec, "speedup"), 0.0, MAX_SPEEDUP, strict_lo=True)
    kr = vr.sub("kinematics")
    kin = {
        k: kr.num(k, getattr(Kinematics, k), 0.0, 1e4, strict_lo=True)
        for k in _KIN_FIELDS
        if kr.has(k)
    }
    kr.used.update(kin)
    kr.done()
    vr.done()
    return VehicleSpec(connection=conn, speedup=speedup, kinematics=kin)


def load_mission(path: str | Path | None = None) -> MissionSpec:
    """Read and validate a mission YAML file (default: ``missions/spiral.yaml``): a path, or the
    name of a shipped mission (``spiral``, ``missions/spiral.yaml`` from any folder:
    ``mission.shipped``)."""
    p = resolve_mission_path(path)
    data = read_yaml(p, "mission file", max_bytes=MAX_MISSION_BYTES)
    if data is None:
        raise InputError(
            "empty mission file (no keys); see missions/spiral.yaml for the schema", source=str(p)
        )
    spec = parse_mission(data, p)
    if spec.trajectory.waypoints is None:
        spec.waypoints_enu()  # validate generator parameters now, with the key in the message
    return spec


def resolve_mission_path(path: str | Path | None) -> Path:
    """The mission file ``path`` names: the path itself when it exists, else the shipped mission of
    that name (``mission.shipped.resolve_shipped``); an InputError when neither exists."""
    p = resolve_shipped(path, "missions", ".yaml") if path is not None else DEFAULT_MISSION
    if p.exists():
        return p
    names = ", ".join(sorted(q.stem for q in missions_dir().glob("*.yaml")))
    raise InputError(f"mission file not found (shipped missions: {names})", source=str(p))

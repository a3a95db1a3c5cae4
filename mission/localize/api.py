"""``localize_log``: the one function the ``localize`` CLI and ``fly-mission`` (after landing) call.

Steps: read the log (``read_flight_log``: any problem is an ``InputError`` naming file/row/column),
keep the samples to use (``preprocess.select_samples``: mission legs when the log has a phase
column, else the cruise altitudes), run the chosen method, express the estimate in the log's own ENU
frame and as lat/lon, and add the error when the truth is known (argument, else the sidecar).

Method choice when none is given: an explicit ``model_path`` -> ``onnx``; a real receiver's log (the
sidecar's ``rss_source.kind`` is not ``sim``) -> ``fusion``: the plain mean of the self-calibrating
estimate (``selfcal.SelfCalibratingGrid``: antenna hypotheses and offset profiled out per flight, no
preset) and the network ``models/rfsl_spiral_e2r.onnx``, chosen by the rule written before scoring
on the unseen-flight benchmark and the held-out real flights (``models/README.md``); its uncertainty
regions are the self-calibrating posterior's.  A simulated log -> the shipped default model
(``models/rfsl_default.onnx``, see ``default_model_path``) when present, else ``grid`` with the
log's own simulation model.  The estimate's ``extras["method_choice"]`` says which and why.

Grid physics: ``physics_preset`` (a preset name) or ``physics_model`` (a ``make_model`` name or a
model object, with ``physics_params``); neither -> the simulator's own model for a simulated log
(from its sidecar), else the ``afar`` preset (real receivers).

Search area of ``grid``: the sidecar's ``rover_area`` (list of [lat, lon] vertices) when present;
else the AFAR rover area when the log's origin is the AFAR field origin (the transmitter can be
anywhere in it); else the flight's bounding box grown by 60 m.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from mission.defaults import DEFAULT_TX_HEIGHT_M
from mission.errors import InputError
from mission.flightlog import FlightLog, read_flight_log
from mission.flightlog.schema import QUALITY_COLUMN, SOUNDER_LOCK_DB, lock_floor_db, out_of_lock
from mission.geo import Area, afar_field
from mission.localize import Estimate, Selection
from mission.localize.error_circles import (
    CIRCLE_METHODS,
    NO_CIRCLE_APPLIES,
    attach_circles,
    card_calibration,
    method_calibration,
)
from mission.localize.methods import (
    ADAPTIVE_ANSWER,
    ADAPTIVE_METHOD,
    DEFAULT_MODEL_NAME,
    FROM_CARD,
    MODEL_FRAME,
    TRAINED_LEGS,
    Method,
    composer,
    method_entry,
)
from mission.localize.preprocess import select_samples
from mission.localize.sim_default import sim_default_model
from mission.localize.training_domain import (
    ATTITUDE_TOLERANCE_DEG,
    CIRCLE_ATTITUDE_TOLERANCE_DEG,
    altitude_note,
    flight_altitudes,
    flight_attitude,
    flown_domain,
    trained_legs,
)
from mission.physics.propagation import MODEL_NAMES

# re-exported: importers say mission.localize.api.shipped_model
from mission.shipped import (
    shipped_model,
)

FUSION_MODEL_NAME = "rfsl_spiral_e2r.onnx"
DEFAULT_PHYSICS_PRESET = "afar"
OUTSIDE_WARN_M = 25.0  # an estimate this far outside the rover area gets a warning
LOCK_NOTE_SHARE = 0.1  # a log with this share of its samples read out of lock gets a note


def default_model_path() -> Path | None:
    """The simulated-log default network, ``models/rfsl_default.onnx``, if present."""
    return shipped_model(DEFAULT_MODEL_NAME)


def search_area(log):
    """The grid search region for a log (``Area`` in the log's frame, or None for the flight's
    box)."""
    origin = log.origin
    ra = log.meta.get("rover_area")
    if isinstance(ra, list) and len(ra) >= 3:
        try:
            return Area.from_geodetic("rover area", np.asarray(ra, dtype=float), origin)
        except (ValueError, InputError):
            raise InputError(
                "sidecar rover_area must be a list of [lat, lon] vertices",
                source=str(log.path),
                field="rover_area",
            ) from None
    af = afar_field()
    off = af.origin.to_enu(origin.lat_deg, origin.lon_deg, origin.alt_m)
    if float(np.hypot(off[0], off[1])) < 1.0:
        return af.rover_area
    return None


def _truth_enu(log, truth) -> np.ndarray | None:
    if truth is not None:
        lat, lon = truth
        return log.origin.to_enu(lat, lon)
    try:
        return log.truth_enu
    except (KeyError, TypeError, ValueError):
        raise InputError(
            "sidecar truth is malformed", source=str(log.path), field="truth"
        ) from None


def make_localizer(
    method: str,
    model_path: str | Path | None = None,
    physics_model: str = "e2r",
    physics_params: dict | None = None,
    tx_height_m: float = DEFAULT_TX_HEIGHT_M,
    area=None,
    floor_db: float | None = None,
    physics_preset: str | None = None,
):
    """Build the localizer object for a method name: its registry entry's factory
    (``mission.localize.methods``; ``physics_preset`` replaces ``physics_model``)."""
    entry = method_entry(method)
    if entry.factory is None:
        raise InputError(
            f"method {method!r} combines other methods: localize_log runs it, not one localizer"
        )
    return entry.factory(
        model_path=model_path,
        physics_model=physics_model,
        physics_params=physics_params,
        tx_height_m=tx_height_m,
        area=area,
        floor_db=floor_db,
        physics_preset=physics_preset,
    )


def _is_simulated(log) -> bool:
    """True when the sidecar says the RSS came from a simulator (not a real receiver)."""
    # the same test as choose_method's
    return (log.meta.get("rss_source") or {}).get("kind") == "sim"


def _default_physics(log) -> tuple[str | None, dict | None, str | None]:
    """Grid physics when none is asked for: the simulator's own model for a simulated log (its
    sidecar says which, with its parameters), else the ``afar`` preset calibrated on real
    receivers."""
    src = log.meta.get("rss_source") or {}

    if src.get("kind") == "sim" and src.get("model") in MODEL_NAMES:
        return src["model"], dict(src.get("model_params") or {}), None
    return None, None, DEFAULT_PHYSICS_PRESET


def _in_log_frame(loc, est: Estimate, origin, frame: str) -> Estimate:
    """Express a localizer's estimate in the log's ENU frame and as lat/lon (``frame``: its registry
    entry's; networks answer in their own frame)."""
    if frame == MODEL_FRAME:  # model frame -> lat/lon -> log frame
        xy = origin.to_enu(est.lat_deg, est.lon_deg)
        est.extras["model_frame_xy_m"] = [est.x_m, est.y_m]
        est.extras["model_path"] = str(loc.path)
        est.extras["feature_config"] = loc.cfg.to_dict()
        est.x_m, est.y_m = float(xy[0]), float(xy[1])
    else:
        lat, lon, _ = origin.to_geodetic(np.array([est.x_m, est.y_m, 0.0]))
        est.lat_deg, est.lon_deg = float(lat), float(lon)
    return est


def _check_altitude(est: Estimate, net, part) -> bool:
    """Record the network's training altitudes and the flight's (``network_training_altitude_m``,
    ``flight_altitude_m``) and add a note when the flight is outside them (``training_domain``);
    True then."""
    trained, flown = net.card.domain.altitude_m, flight_altitudes(part.enu()[:, 2])
    est.extras["network_training_altitude_m"] = None if trained is None else list(trained)
    est.extras["flight_altitude_m"] = list(flown)
    note = altitude_note(net.model_name, trained, flown)
    est.add_note(note)
    return note is not None


def _network_regions(est: Estimate, net, part, simulated: bool, area) -> None:
    """A network's estimate gets its card's calibrated error circles (``error_circles``, clipped to
    the rover ``area`` when known) and the altitude check; on a simulated log outside the training
    altitudes the circles (calibrated inside them) are too small."""
    cal = card_calibration(net.card, "sim" if simulated else "real")  # sized for what was flown
    # 'sim' circles hold for the training's attitudes only (no tolerance)
    tol = CIRCLE_ATTITUDE_TOLERANCE_DEG if simulated else ATTITUDE_TOLERANCE_DEG
    flown = flown_domain(part, net.card.domain.attitude_deg, net.model_name, tol)
    # 'real' circles come from benchmark flights of every attitude: a note, not a veto
    if not simulated:
        est.add_note(flown.pop("attitude_note"))
    est.add_note(attach_circles(est, cal, area, flown))
    if _check_altitude(est, net, part) and simulated and est.regions:
        est.add_note(
            "Its error circles were calibrated on flights inside those altitudes: expect them "
            "to be too "
            "small here."
        )


def _method_regions(
    est: Estimate, method: str, simulated: bool, default_config: bool, area
) -> None:
    """Strongest sample, centroid and grid get error circles calibrated for their default
    configuration (the grid's default physics, the default sample selection), clipped to the rover
    ``area`` when known; any other configuration gets a note instead."""
    if method not in CIRCLE_METHODS:
        return
    if not default_config:
        est.add_note(
            "no uncertainty region: the error circles of this method were calibrated for its "
            "default "
            "physics and sample selection only"
        )
        return
    cal = method_calibration(method, "sim" if simulated else "real")
    est.add_note(attach_circles(est, cal, area))


def _fallback_regions(est: Estimate, part, origin, area, tx_height_m: float) -> None:
    """A default network's answer without regions (its circles do not apply: e.g. PX4 SITL's SIH
    flies at -28 deg pitch, outside the networks' training attitudes) takes the self-calibrating
    posterior's regions, whose calibration holds for any attitude (it models the flight's own
    attitude), with a note: as ``fusion`` does, the regions are the search's and the point stays the
    network's.  Why: every flight ends with a region."""
    if est.regions:
        return
    _, alt = run_member("selfcal", part, origin, tx_height_m=tx_height_m, area=area)
    if not alt.regions:
        return

    est.regions, est.posterior = alt.regions, alt.posterior
    est.extras["regions_from"] = "selfcal"
    est.notes = [
        n.replace(NO_CIRCLE_APPLIES, "Its error circles do not apply.").replace(
            "no uncertainty region: ", "no error circle: ", 1
        )
        for n in est.notes
    ]
    est.add_note(
        f"The regions are the self-calibrating search's posterior's (its estimate "
        f"{alt.x_m:.0f}, {alt.y_m:.0f} m, {np.hypot(alt.x_m - est.x_m, alt.y_m - est.y_m):.0f} "
        "m from "
        "this one)."
    )


def fusion_model_path() -> Path | None:
    """The network of the fused default (``models/rfsl_spiral_e2r.onnx``), if present."""
    return shipped_model(FUSION_MODEL_NAME)


def member_samples(part, entry: Method):
    """The samples a method takes (its registry entry's ``samples``)."""
    return trained_legs(part) if entry.samples == TRAINED_LEGS else part


def run_member(name: str, part, origin, **kw) -> tuple[object, Estimate]:
    """(localizer, its estimate in the log's frame) of one registered method on ``part``."""
    entry = method_entry(name)
    loc = make_localizer(name, **kw)
    return loc, _in_log_frame(loc, loc.predict(member_samples(part, entry)), origin, entry.frame)


def fusion(
    part, origin, area, tx_height_m: float = DEFAULT_TX_HEIGHT_M, model_path=None, **_
) -> Estimate:
    """The plain mean of the self-calibrating estimate and a network's (no weights fitted: the rule
    in ``models/README.md``; weighting by each member's 50 % region scale was not adopted,
    benchmarks/fusion_weights.py); the uncertainty regions are the self-calibrating posterior's, and
    a note says when the fused point falls outside them (the two components disagree: ~5 % of
    benchmark flights)."""
    _, a = run_member("selfcal", part, origin, tx_height_m=tx_height_m, area=area)
    path = model_path or fusion_model_path()
    if path is None:
        a.extras["fusion"] = (
            f"no network (models/{FUSION_MODEL_NAME}): self-calibrating estimate alone"
        )
        return a
    net, b = run_member("onnx", part, origin, model_path=path, tx_height_m=tx_height_m)
    x, y = 0.5 * (a.x_m + b.x_m), 0.5 * (a.y_m + b.y_m)
    lat, lon, _ = origin.to_geodetic(np.array([x, y, 0.0]))
    est = Estimate(
        float(x),
        float(y),
        "fusion",
        f"mean of selfcal and {Path(path).name}",
        float(lat),
        float(lon),
        extras=dict(a.extras),
        posterior=a.posterior,
        notes=list(a.notes),
    )
    if "regions" in a.extras:
        est.regions = a.regions  # typed; the JSON form keeps its place in the copied extras
    est.set_components({"selfcal": a, Path(path).name: b})
    est.extras["component_distance_m"] = dist = float(np.hypot(a.x_m - b.x_m, a.y_m - b.y_m))
    # is the fused point inside its own regions?
    if a.posterior is not None and a.posterior.grid is not None:
        # log frame, as the grid
        est.extras["fused_point_hpd_level"] = q = a.posterior.hpd_level(float(x), float(y))
        outer = est.outer_region
        if outer is not None and q >= outer.mass:
            est.add_note(
                f"the network and the self-calibrating search disagree ({dist:.0f} m apart): "
                "the fused "
                f"point lies outside the {100 * outer.level:.0f} % region, which is the "
                "search's alone"
            )
    _check_altitude(est, net, part)
    return est


REAL_DEFAULT = "fusion"  # the real-log default, chosen by the rule in models/README.md


def choose_method(
    meta: dict,
    heights_m: np.ndarray,
    model_path: str | Path | None = None,
    default_model: Path | None = None,
    physics_label: str = "the log's physics",
    attitude_deg: tuple[tuple[float, float], tuple[float, float]] | None = None,
) -> tuple[str, str | Path | None, str]:
    """(method, model path, why) when none is asked for: a pure function of the sidecar, the
    selected samples' heights and roll / pitch spans (``flight_attitude``), the model given and the
    shipped default network (``tests/test_methods.py`` holds its table)."""
    if model_path is not None:
        return "onnx", model_path, f"model {Path(model_path).name} given"
    if (meta.get("trajectory") or {}).get("adaptive"):  # flown by fly-mission --adaptive
        return (
            ADAPTIVE_ANSWER,
            None,
            (
                f"adaptive flight: the live method ({ADAPTIVE_METHOD}), the survey's "
                "fixed-flight default or the survey network, whichever the networks' physics "
                "explains best where it explains the flight, else whichever of the first two the "
                "rounds' RSS supports (rounds_answer)"
            ),
        )
    if (meta.get("rss_source") or {}).get("kind") != "sim":
        return (
            REAL_DEFAULT,
            None,
            (
                "real receiver log: mean of the self-calibrating estimate and the network "
                f"{FUSION_MODEL_NAME}, chosen by the rule written before scoring "
                "(unseen-flight benchmark and "
                "held-out real flights, models/README.md); --method selfcal / grid / onnx run "
                "one method"
            ),
        )
    if default_model is not None:
        path, why = sim_default_model(meta, heights_m, default_model, attitude_deg)
        return "onnx", path, why
    return (
        "grid",
        None,
        f"no default model (models/{DEFAULT_MODEL_NAME}); grid search with {physics_label}",
    )


def localize_log(
    log_or_path,
    method: str | None = None,
    model_path: str | Path | None = None,
    truth: tuple[float, float] | None = None,
    cruise: bool = True,
    physics_model: str | None = None,
    physics_params: dict | None = None,
    tx_height_m: float = DEFAULT_TX_HEIGHT_M,
    floor_db: float | None = None,
    physics_preset: str | None = None,
) -> Estimate:
    """Estimate the transmitter position from a flight log (path or ``FlightLog``).

    Grid physics: ``physics_preset`` or ``physics_model`` (not both); neither -> the sidecar's
    simulation model for a simulated log, else the ``afar`` preset.
    """
    if physics_preset is not None and physics_model is not None:
        raise InputError("give a physics model or a physics preset, not both")

    log = log_or_path if isinstance(log_or_path, FlightLog) else read_flight_log(log_or_path)
    physics_given = physics_preset is not None or physics_model is not None or floor_db is not None
    # a default network: selfcal's regions if its circles fail
    by_default = method is None and model_path is None
    if physics_preset is None and physics_model is None:
        physics_model, physics_params, physics_preset = _default_physics(log)
    physics_label = f"physics preset {physics_preset}" if physics_preset else str(physics_model)
    n_all = len(log)
    if cruise:
        part, reason = select_samples(log)
    else:
        part, reason = log, "cruise selection off: all samples used"
    if method is None:
        method, model_path, choice = choose_method(
            log.meta,
            part.enu()[:, 2],
            model_path,
            default_model_path(),
            physics_label,
            flight_attitude(part),
        )
    else:
        choice = f"method {method} requested"
    entry = method_entry(method)  # an unknown name: InputError listing the known ones
    # the transmitter's area: bounds the searches, clips error circles, checks estimates
    ra = search_area(log)
    est = run_method(
        entry,
        method,
        part,
        log,
        ra,
        model_path=model_path,
        physics_model=physics_model,
        physics_params=physics_params,
        physics_preset=physics_preset,
        tx_height_m=tx_height_m,
        floor_db=floor_db,
        by_default=by_default,
        default_config=cruise and not (method == "grid" and physics_given),
    )
    if ra is not None:
        _outside_warning(est, ra)
    _lock_note(est, part)
    t = _truth_enu(log, truth)
    if t is not None:
        est.error_m = float(np.hypot(est.x_m - t[0], est.y_m - t[1]))
        est.extras["truth_x_m"], est.extras["truth_y_m"] = float(t[0]), float(t[1])
    est.extras["method_choice"] = choice
    est.selection = Selection(len(part), n_all, reason)
    est.extras["log"] = str(log.path) if log.path else None
    return est


def run_method(
    entry: Method,
    method: str,
    part,
    log,
    ra,
    *,
    model_path,
    physics_model,
    physics_params,
    physics_preset,
    tx_height_m: float,
    floor_db,
    by_default: bool,
    default_config: bool,
) -> Estimate:
    """The registry entry's estimate on the samples ``part`` in the log's frame, with its
    uncertainty regions (a composer's own; a network's card circles, selfcal's regions as the
    default's fallback; a classical method's calibrated circles)."""
    origin = log.origin
    area = ra if entry.bounded else None
    if entry.compose is not None:  # a meta-estimator over other methods
        return composer(entry)(
            part,
            origin,
            area,
            tx_height_m=tx_height_m,
            model_path=model_path,
            physics_preset=physics_preset,
        )
    loc = make_localizer(
        method,
        model_path,
        physics_model or "e2r",
        physics_params,
        tx_height_m,
        area,
        floor_db,
        physics_preset=physics_preset,
    )
    est = _in_log_frame(loc, loc.predict(member_samples(part, entry)), origin, entry.frame)
    if entry.calibration == FROM_CARD:  # a network: its card's circles
        _network_regions(est, loc, part, _is_simulated(log), ra)
        if by_default:
            _fallback_regions(est, part, origin, ra, tx_height_m)
    else:
        _method_regions(est, method, _is_simulated(log), default_config, ra)
    return est


def _lock_note(est: Estimate, part) -> None:
    """A log whose receiver reports its quality (``QUALITY_COLUMN``): the share of the samples used
    that it read out of lock and the level where it loses lock (``lock_floor_db``), and a note when
    that share is a tenth or more.  They are kept: read as they are they still mark where the
    transmitter is not; without them or clamped no member did better on the AFAR flights, and the
    default's change flipped sign with the cut (models/README.md, issue 32)."""
    if QUALITY_COLUMN not in part.columns or not len(part):
        return
    share = float(out_of_lock(part[QUALITY_COLUMN]).mean())
    est.extras["out_of_lock_share"] = share
    floor = lock_floor_db(part["rss_dbm"], part[QUALITY_COLUMN])
    est.extras["lock_floor_db"] = floor
    if share >= LOCK_NOTE_SHARE:
        below = "" if floor is None else f" below about {floor:.0f} dB"
        est.add_note(
            f"{100 * share:.0f} % of the samples used were read with the receiver out of lock"
            f"{below} (quality under {SOUNDER_LOCK_DB:g} dB; on the AFAR flights such samples "
            "read 23-37 dB low); they are kept: they still mark where the transmitter is not"
        )


def _outside_warning(est: Estimate, ra) -> None:
    """Networks are not bounded: say so when an estimate leaves the transmitter's area."""
    out_m = -float(ra.signed_distance(np.array([[est.x_m, est.y_m]]))[0])
    if out_m > OUTSIDE_WARN_M:
        est.extras["warning"] = (
            f"estimate lies {out_m:.0f} m outside the {ra.name}: the method did not "
            "recognise this flight (other path or physics than it was trained on?)"
        )

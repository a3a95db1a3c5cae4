"""The localization methods, one entry each: name, factory, kind of uncertainty, where it is
calibrated, a line.

Every list of method names (``localize --method``, ``localize_log``, the error circles, ``rfsl
evaluate``) reads from ``METHODS``.  Importing this module loads no numpy: the CLI builds
``--method`` from it, and a factory imports its estimator only when called.  A factory takes the
keyword arguments of ``mission.localize.api.make_localizer`` and ignores those it does not use.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from mission.defaults import DEFAULT_TX_HEIGHT_M
from mission.errors import InputError

# what an estimate's uncertainty is
POSTERIOR = "posterior"  # HPD regions of the method's own posterior (uncertainty.hpd_regions)
CIRCLE = "circle"  # split-conformal error circles about the point (error_circles)
# where its 50 / 90 % sizes come from
FROM_REGION_MASSES = (
    "region masses"  # HPD masses recalibrated on the benchmark (benchmarks/calibrate_regions.py)
)
FROM_DRAWS = (
    "held-out draws"  # HPD masses that held this flight's own held-out simulated draws (matched)
)
FROM_CARD = (
    "card circles"  # the network's card, models/<name>.json (error_circles.card_calibration)
)
FROM_METHOD_CIRCLES = (
    "method circles"  # mission/data/method_circles.json (benchmarks/calibrate_error_circles.py)
)

# the frame an estimator answers in, and the samples it takes
LOG_FRAME = "log"  # the log's own ENU frame
MODEL_FRAME = (
    "model"  # a network's own frame (its card's origin): localize_log converts through lat/lon
)
SELECTED = "selected"  # the samples preprocess.select_samples keeps
TRAINED_LEGS = (
    "trained legs"  # those less the transit to the first waypoint, as the networks were trained
)

DEFAULT_MODEL_NAME = "rfsl_default.onnx"  # the network ``onnx`` runs without a model path (models/)
# an adaptive flight's live method: its rounds plan on this posterior
ADAPTIVE_METHOD = "selfcal"
# an adaptive flight's answer: the live method or the survey's fixed-flight default, by the rounds
ADAPTIVE_ANSWER = "rounds"
# the extras key (and live series key) of the candidate the networks' physics explains best where
# it explains the flight (``rounds_answer``'s judge), also on the survey before any round: the
# planner may fly the first round over it (``planner.round_target``)
JUDGED_PICK = "judged_pick"


@dataclass(frozen=True)
class Method:
    """One localization method: ``factory(**kw)`` builds its estimator (``predict(flight) ->
    Estimate``); None for the meta-estimators ``fusion`` and ``evidence``, which ``localize_log``
    composes from others."""

    name: str
    # "network", "classical" (classical.py's estimators), "self-calibrating", "fusion", "stacking"
    kind: str
    uncertainty: str  # POSTERIOR or CIRCLE
    calibration: str  # FROM_REGION_MASSES, FROM_DRAWS, FROM_CARD or FROM_METHOD_CIRCLES
    bounded: bool  # searches inside the transmitter's area (localize_log passes it the rover area)
    description: str
    factory: Callable[..., object] | None
    # a meta-estimator's "module:function", (part, origin, area, **kw) -> Estimate, imported when it
    # runs (it runs other entries, so naming it here by reference keeps the registry below it: no
    # import circle)
    compose: str | None = None
    frame: str = (
        LOG_FRAME  # the frame it answers in: LOG_FRAME, or MODEL_FRAME (converted through lat/lon)
    )
    samples: str = (
        SELECTED  # which samples it takes: SELECTED, or TRAINED_LEGS (training_domain.trained_legs)
    )


def _onnx(model_path: str | Path | None = None, tx_height_m: float = DEFAULT_TX_HEIGHT_M, **_):
    from mission.localize.onnx_model import OnnxLocalizer
    from mission.shipped import shipped_model

    path = model_path or shipped_model(DEFAULT_MODEL_NAME)
    if path is None:
        raise InputError(f"method onnx needs --model (no models/{DEFAULT_MODEL_NAME} shipped)")
    return OnnxLocalizer(path, tx_height_m=tx_height_m)


def _strongest(**_):
    from mission.localize.classical import StrongestSample

    return StrongestSample()


def _centroid(**_):
    from mission.localize.classical import WeightedCentroid

    return WeightedCentroid()


def _grid(
    physics_model="e2r",
    physics_params: dict | None = None,
    tx_height_m: float = DEFAULT_TX_HEIGHT_M,
    area=None,
    floor_db: float | None = None,
    physics_preset: str | None = None,
    **_,
):
    """``physics_preset`` (a calibrated preset) replaces ``physics_model`` and its
    ``physics_params``."""
    from mission.localize.classical import ModelGridSearch

    if physics_preset is not None:
        from mission.physics.presets import preset_model

        try:
            model = preset_model(physics_preset, **(physics_params or {}))
        except InputError:
            raise
        except ValueError as e:
            raise InputError(
                f"physics preset {physics_preset!r}: {e}", field="physics_params"
            ) from None
        return ModelGridSearch(model, tx_height_m=tx_height_m, area=area, floor_db=floor_db)
    return ModelGridSearch(
        physics_model, physics_params, tx_height_m=tx_height_m, area=area, floor_db=floor_db
    )


def _selfcal(tx_height_m: float = DEFAULT_TX_HEIGHT_M, area=None, **_):
    from mission.localize.selfcal import SelfCalibratingGrid

    return SelfCalibratingGrid(area=area, tx_height_m=tx_height_m)


def _matched(tx_height_m: float = DEFAULT_TX_HEIGHT_M, area=None, **_):
    from mission.localize.matched import MatchedLocalizer

    return MatchedLocalizer(area=area, tx_height_m=tx_height_m)


METHODS: dict[str, Method] = {
    m.name: m
    for m in (
        Method(
            "onnx",
            "network",
            CIRCLE,
            FROM_CARD,
            False,
            "an ONNX network on the 3D-clustering features (--model, else "
            "models/rfsl_default.onnx)",
            _onnx,
            frame=MODEL_FRAME,
            samples=TRAINED_LEGS,
        ),
        Method(
            "strongest",
            "classical",
            CIRCLE,
            FROM_METHOD_CIRCLES,
            False,
            "the position of the strongest RSS sample",
            _strongest,
        ),
        Method(
            "centroid",
            "classical",
            CIRCLE,
            FROM_METHOD_CIRCLES,
            False,
            "RSS-weighted centroid of the strongest samples",
            _centroid,
        ),
        Method(
            "grid",
            "classical",
            CIRCLE,
            FROM_METHOD_CIRCLES,
            True,
            "grid search under a propagation model or a calibrated physics preset",
            _grid,
        ),
        Method(
            "selfcal",
            "self-calibrating",
            POSTERIOR,
            FROM_REGION_MASSES,
            True,
            "grid search with the antenna and RSS offset profiled out on the flight itself",
            _selfcal,
        ),
        Method(
            "rounds",
            "stacking",
            POSTERIOR,
            FROM_REGION_MASSES,
            True,
            "an adaptive flight's answer: the live method or the survey's fixed-flight default, "
            "whichever the rounds' held-out RSS supports (regions: the live method's posterior at "
            "masses calibrated on adaptive flights)",
            None,
            compose="mission.localize.rounds_answer:rounds_answer",
        ),
        Method(
            "fusion",
            "fusion",
            POSTERIOR,
            FROM_REGION_MASSES,
            True,
            "mean of selfcal and the network rfsl_spiral_e2r; selfcal's regions (the real-log "
            "default)",
            None,
            compose="mission.localize.api:fusion",
        ),
        Method(
            "evidence",
            "stacking",
            POSTERIOR,
            FROM_REGION_MASSES,
            True,
            "candidates of every method weighed by the flight's held-out RSS (stacking); "
            "mixture regions",
            None,
            compose="mission.localize.evidence_stage:evidence_stage",
        ),
        Method(
            "matched",
            "self-calibrating",
            POSTERIOR,
            FROM_DRAWS,
            True,
            "track-matched ABC: transmitters simulated along the flown track under the physics "
            "family",
            _matched,
        ),
    )
}
METHOD_NAMES = tuple(METHODS)


def method_entry(name: str) -> Method:
    """The registry entry of ``name``; an unknown name is an ``InputError`` listing the known
    ones."""
    try:
        return METHODS[name]
    except (KeyError, TypeError):
        raise InputError(
            f"unknown method {name!r} (expected one of {', '.join(METHOD_NAMES)})"
        ) from None


def composer(entry: Method) -> Callable[..., object]:
    """The function of a meta-estimator's ``compose`` reference."""
    from importlib import import_module

    module, _, name = str(entry.compose).partition(":")
    return getattr(import_module(module), name)


def names_where(**fields) -> tuple[str, ...]:
    """The names of the methods whose entry has every given field value, in registry order
    (``names_where(calibration=FROM_METHOD_CIRCLES)`` -> the methods calibrated by method
    circles)."""
    return tuple(
        m.name for m in METHODS.values() if all(getattr(m, k) == v for k, v in fields.items())
    )

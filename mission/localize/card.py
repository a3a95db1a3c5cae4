"""A network's model card: what the runtime knows about it, read once when the network is loaded.

Two files hold it, both written at training time:

- the ONNX file's ``metadata_props`` (JSON strings), the contract with the trainer: ``feature_kind``
  (``"clustering"`` or ``"normalised_rss"``), ``feature_config`` (``FeatureConfig.to_dict()``), the
  ``input_normalisation`` (``input_mean``, ``input_std``, ``output_mean``, ``output_std``: the
  network sees ``(features - input_mean) / input_std``, its output ``o`` is ``o * output_std +
  output_mean`` metres), ``field_origin`` (``lat_deg``, ``lon_deg``, ``alt_m``: the frame of
  features and output) and ``training_data`` (free-form; its ``altitude_normalisation`` entry,
  ``altitude_scale``, is read);
- the JSON card beside it (``models/<name>.json``): ``training_domain`` (the training flights'
  cruise altitude and roll / pitch spans, measured by ``mission.workshop.domain`` when the network
  was trained or its card written) and ``regions`` (the calibrated error circles, ``error_circles``,
  each naming the model file's sha256).

A network without a JSON card, or whose card has no ``training_domain``, makes no claim about its
domain.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mission.errors import InputError
from mission.fields import REQUIRED, Fields
from mission.geo import Origin
from mission.localize.altitude_scale import METADATA_KEY, reference_height
from mission.localize.features import FEATURE_VERSION, FeatureConfig

REQUIRED_KEYS = ("feature_kind", "feature_config", "input_normalisation", "field_origin")
FEATURE_KINDS = ("clustering", "normalised_rss")
DOMAIN_KEY = "training_domain"
REGIONS_KEY = "regions"
# a ``regions`` record holding only this key: circles that were calibrated and refused by a rule
# (the text says by which and why), so that no note invites calibrating them again
REFUSED_KEY = "refused"

Span = tuple[float, float]


def card_path(model_path: str | Path) -> Path:
    """The JSON card beside a network: ``models/<name>.json`` for ``models/<name>.onnx``."""
    return Path(model_path).with_suffix(".json")


def model_digest(model_path: str | Path) -> str:
    """sha256 of a model file: a card's calibration names the exact network it was measured on."""
    return hashlib.sha256(Path(model_path).read_bytes()).hexdigest()


@dataclass(frozen=True)
class Normalisation:
    """The affine maps around the network: inputs ``(x - input_mean) / input_std``, outputs
    ``o * output_std + output_mean`` (scalars broadcast)."""

    input_mean: np.ndarray
    input_std: np.ndarray
    output_mean: np.ndarray
    output_std: np.ndarray

    @classmethod
    def from_dict(cls, norm, src: str) -> Normalisation:
        f = Fields(norm, src, "input_normalisation")
        arrays = []
        for k in ("input_mean", "input_std", "output_mean", "output_std"):
            try:
                arrays.append(np.asarray(f.raw(k, REQUIRED), dtype=np.float64))
            except (TypeError, ValueError):
                raise f.err(k, "expected a number or a list of numbers") from None
        return cls(*arrays)


@dataclass(frozen=True)
class TrainingDomain:
    """The training flights' cruise altitude span (m) and (roll, pitch) spans (deg); None where
    unknown."""

    altitude_m: Span | None = None
    attitude_deg: tuple[Span, Span] | None = None

    def to_dict(self) -> dict:
        att = self.attitude_deg
        return {
            "altitude_m": None if self.altitude_m is None else list(self.altitude_m),
            "roll_deg": None if att is None else list(att[0]),
            "pitch_deg": None if att is None else list(att[1]),
        }

    @classmethod
    def from_dict(cls, d, src: str) -> TrainingDomain:
        """The card's record; ``InputError`` naming the card and key when a span is not two
        ascending numbers."""
        f = Fields(d, src, DOMAIN_KEY)
        spans = {key: f.span(key, None) for key in ("altitude_m", "roll_deg", "pitch_deg")}
        if (spans["roll_deg"] is None) != (spans["pitch_deg"] is None):
            raise f.err("pitch_deg", "roll_deg and pitch_deg are both given or both null")
        att = None if spans["roll_deg"] is None else (spans["roll_deg"], spans["pitch_deg"])
        return cls(spans["altitude_m"], att)


def _metadata(props: dict, src: str) -> dict:
    """The ONNX metadata with the contract's keys decoded from JSON (``feature_kind`` may be plain
    text)."""
    f = Fields(props, src)
    for key in REQUIRED_KEYS:
        if key not in props:
            raise f.err(key, "model metadata lacks this key")
    meta: dict = {}
    for key, val in props.items():
        if key in REQUIRED_KEYS or key == "training_data":
            try:
                meta[key] = json.loads(val)
            except json.JSONDecodeError:
                if key != "feature_kind":
                    raise f.err(key, "model metadata is not valid JSON") from None
                meta[key] = val
        else:
            meta[key] = val
    return meta


def _feature_config(fc, expect_config: FeatureConfig | dict | None, src: str) -> FeatureConfig:
    """The model's feature configuration, compared key by key with what the caller intends to
    feed."""
    # a model older than a later key was made with its neutral value
    fc = FeatureConfig.normalised(Fields(fc, src, "feature_config").d)
    if expect_config is not None:
        want = (
            expect_config.to_dict()
            if isinstance(expect_config, FeatureConfig)
            else dict(expect_config)
        )
        for k in sorted(set(want) | set(fc)):
            if k not in fc:
                raise InputError(
                    f"model's feature_config lacks {k!r} (caller expects {want[k]!r})",
                    source=src,
                    field=f"feature_config.{k}",
                )
            if k not in want or want[k] != fc[k]:
                raise InputError(
                    f"model's feature_config {k}={fc[k]!r} does not match the expected "
                    f"{want.get(k)!r}",
                    source=src,
                    field=f"feature_config.{k}",
                )
    try:
        cfg = FeatureConfig.from_dict(fc)
    except (InputError, TypeError) as e:
        raise InputError(f"bad feature_config ({e})", source=src, field="feature_config") from None
    if cfg.version != FEATURE_VERSION:
        raise InputError(
            f"model's features are version {cfg.version}, this software computes version "
            f"{FEATURE_VERSION}",
            source=src,
            field="feature_config.version",
        )
    return cfg


def _json_card(path: Path) -> dict | None:
    """The JSON card beside a model (None when absent); ``InputError`` when it is not a JSON
    object."""
    p = card_path(path)
    if not p.is_file():
        return None
    try:
        card = json.loads(p.read_text())
    except json.JSONDecodeError:
        card = None
    if not isinstance(card, dict):
        raise InputError("not a JSON object", source=str(p))
    return card


def _card_domain(card: dict | None, path: Path) -> TrainingDomain:
    """The training domain recorded in a JSON card (an empty one, no claim, without it)."""
    if card is not None and card.get(DOMAIN_KEY) is not None:
        return TrainingDomain.from_dict(card[DOMAIN_KEY], str(card_path(path)))
    return TrainingDomain()


def training_domain_of(model_path: str | Path) -> TrainingDomain:
    """The training domain of the network at ``model_path``, from its JSON card alone: what a
    router reads to choose a network, without opening an onnxruntime session for it."""
    path = Path(model_path)
    return _card_domain(_json_card(path), path)


@dataclass(frozen=True)
class ModelCard:
    """Everything the runtime reads about a network, validated once (``ModelCard.read``).

    ``regions`` is the JSON card's raw ``regions`` mapping (None without a card): each record is
    checked when a flight asks for it (``error_circles.card_calibration``), so a malformed one is
    reported where it is used."""

    path: Path
    kind: str
    feature_config: FeatureConfig
    normalisation: Normalisation
    origin: Origin
    reference_height_m: float | None
    domain: TrainingDomain
    regions: dict | None
    sha256: str
    meta: dict

    @property
    def n_features(self) -> int:
        """Width of the network's feature vector."""
        return (
            self.feature_config.n_features
            if self.kind == "clustering"
            else self.feature_config.rss_length
        )

    @classmethod
    def read(
        cls,
        path: str | Path,
        props: dict,
        expect_config: FeatureConfig | dict | None = None,
        expect_kind: str | None = None,
    ) -> ModelCard:
        """The card of the network at ``path`` whose ONNX ``metadata_props`` are ``props``;
        ``expect_config`` / ``expect_kind``: what the caller intends to feed (a model trained on
        anything else is refused, ``InputError`` naming the differing key)."""
        path = Path(path)
        src = str(path)
        meta = _metadata(props, src)
        kind = Fields(meta, src).str_("feature_kind", choices=FEATURE_KINDS)
        if expect_kind is not None and expect_kind != kind:
            raise InputError(
                f"model was trained on {kind!r} features, caller asks for {expect_kind!r}",
                source=src,
                field="feature_kind",
            )
        cfg = _feature_config(meta["feature_config"], expect_config, src)
        norm = Normalisation.from_dict(meta["input_normalisation"], src)
        fo = Fields(meta["field_origin"], src, "field_origin")
        origin = Origin(
            fo.num("lat_deg", lo=-90, hi=90),
            fo.num("lon_deg", lo=-180, hi=180),
            fo.num("alt_m", 0.0),
        )
        ref = reference_height(meta.get("training_data"), src)
        if ref is not None and kind != "clustering":
            raise InputError(
                "altitude normalisation needs clustering features",
                source=src,
                field=f"training_data.{METADATA_KEY}",
            )
        card = _json_card(path)
        domain = _card_domain(card, path)
        regions = None if card is None else card.get(REGIONS_KEY) or {}
        return cls(path, kind, cfg, norm, origin, ref, domain, regions, model_digest(path), meta)

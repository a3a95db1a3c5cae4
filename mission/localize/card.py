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
from mission.geo import Origin
from mission.localize.altitude_scale import METADATA_KEY, reference_height
from mission.localize.features import FEATURE_VERSION, FeatureConfig

REQUIRED_KEYS = ("feature_kind", "feature_config", "input_normalisation", "field_origin")
FEATURE_KINDS = ("clustering", "normalised_rss")
DOMAIN_KEY = "training_domain"
REGIONS_KEY = "regions"

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
        try:
            return cls(
                *(
                    np.asarray(norm[k], dtype=np.float64)
                    for k in ("input_mean", "input_std", "output_mean", "output_std")
                )
            )
        except (KeyError, TypeError) as e:
            raise InputError(
                f"input_normalisation needs input_mean/input_std/output_mean/output_std ({e})",
                source=src,
                field="input_normalisation",
            ) from None


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
        if not isinstance(d, dict):
            raise InputError("needs a JSON object", source=src, field=DOMAIN_KEY)
        spans = {}
        for key in ("altitude_m", "roll_deg", "pitch_deg"):
            v = d.get(key)
            try:
                spans[key] = None if v is None else (float(v[0]), float(v[1]))
                ok = v is None or (len(v) == 2 and spans[key][0] <= spans[key][1])
            except (TypeError, ValueError, IndexError, KeyError):
                ok = False
            if not ok:
                raise InputError(
                    "needs [low, high] or null", source=src, field=f"{DOMAIN_KEY}.{key}"
                )
        if (spans["roll_deg"] is None) != (spans["pitch_deg"] is None):
            raise InputError(
                "roll_deg and pitch_deg are both given or both null", source=src, field=DOMAIN_KEY
            )
        att = None if spans["roll_deg"] is None else (spans["roll_deg"], spans["pitch_deg"])
        return cls(spans["altitude_m"], att)


def _metadata(props: dict, src: str) -> dict:
    """The ONNX metadata with the contract's keys decoded from JSON (``feature_kind`` may be plain
    text)."""
    for key in REQUIRED_KEYS:
        if key not in props:
            raise InputError("model metadata lacks this key", source=src, field=key)
    meta: dict = {}
    for key, val in props.items():
        if key in REQUIRED_KEYS or key == "training_data":
            try:
                meta[key] = json.loads(val)
            except json.JSONDecodeError:
                if key != "feature_kind":
                    raise InputError(
                        "model metadata is not valid JSON", source=src, field=key
                    ) from None
                meta[key] = val
        else:
            meta[key] = val
    return meta


def _feature_config(fc, expect_config: FeatureConfig | dict | None, src: str) -> FeatureConfig:
    """The model's feature configuration, compared key by key with what the caller intends to
    feed."""
    if not isinstance(fc, dict):
        raise InputError("feature_config must be a JSON object", source=src, field="feature_config")
    # a model older than a later key was made with its neutral value
    fc = FeatureConfig.normalised(fc)
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
        kind = meta["feature_kind"]
        if kind not in FEATURE_KINDS:
            raise InputError(
                f"unknown feature kind {kind!r} (expected {', '.join(FEATURE_KINDS)})",
                source=src,
                field="feature_kind",
            )
        if expect_kind is not None and expect_kind != kind:
            raise InputError(
                f"model was trained on {kind!r} features, caller asks for {expect_kind!r}",
                source=src,
                field="feature_kind",
            )
        cfg = _feature_config(meta["feature_config"], expect_config, src)
        norm = Normalisation.from_dict(meta["input_normalisation"], src)
        try:
            origin = Origin.from_dict(meta["field_origin"])
        except (KeyError, TypeError, ValueError):
            raise InputError(
                "field_origin needs lat_deg, lon_deg", source=src, field="field_origin"
            ) from None
        ref = reference_height(meta.get("training_data"))
        if ref is not None and kind != "clustering":
            raise InputError(
                "altitude normalisation needs clustering features",
                source=src,
                field=f"training_data.{METADATA_KEY}",
            )
        card = _json_card(path)
        domain = TrainingDomain()
        if card is not None and card.get(DOMAIN_KEY) is not None:
            domain = TrainingDomain.from_dict(card[DOMAIN_KEY], str(card_path(path)))
        regions = None if card is None else card.get(REGIONS_KEY) or {}
        return cls(path, kind, cfg, norm, origin, ref, domain, regions, model_digest(path), meta)

"""Run a trained localizer network (ONNX, onnxruntime) on a flight, with its features computed by
features.py.

What the network expects and where it was trained is its card (``mission.localize.card.ModelCard``:
the ONNX file's ``metadata_props`` and the JSON card beside it), read once when the network is
loaded.  The network's single input is float32 ``(batch, F)`` or ``(batch, 1, F)`` (rank read from
the graph); its first output is ``(batch, 2)`` = x, y.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import onnxruntime as ort

from mission.defaults import DEFAULT_TX_HEIGHT_M
from mission.errors import InputError
from mission.geo import Origin
from mission.localize import Estimate
from mission.localize.altitude_scale import flight_height, scale_cluster_xy, scale_factor
from mission.localize.card import ModelCard
from mission.localize.classical import as_flight
from mission.localize.features import FeatureConfig, cluster_features, normalised_rss
from mission.samples import FlightSamples
from mission.shipped import check_shipped_digest
from mission.threads import compute_threads


def session_options(threads: int):
    """onnxruntime session options: quiet log, ``threads`` intra- and inter-op threads (0 =
    onnxruntime's default pool).  One thread by default: a small network runs in well under a
    millisecond, and an idle pool's spinning threads cost CPU on a busy machine."""
    opts = ort.SessionOptions()
    opts.log_severity_level = 3
    if threads > 0:
        opts.intra_op_num_threads = threads
        opts.inter_op_num_threads = threads
        opts.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
        opts.add_session_config_entry("session.intra_op.allow_spinning", "0")
        opts.add_session_config_entry("session.inter_op.allow_spinning", "0")
    return opts


class OnnxLocalizer:
    """A localizer network loaded from an ONNX file; ``predict(flight) -> Estimate``.

    ``expect_config`` / ``expect_kind``: what the caller intends to feed; a model trained with
    anything else is refused (``InputError`` naming the differing key).  ``threads``: onnxruntime's
    intra/inter-op threads (None: ``mission.threads.compute_threads()``, i.e. ``$RFSL_THREADS``,
    default 1; 0: onnxruntime's default). An altitude-normalised network
    (``training_data.altitude_normalisation`` in its metadata, ``mission.localize.altitude_scale``)
    sees each flight's coordinates rescaled by its height above the transmitter (``tx_height_m``
    assumed); ``predict_features`` then needs those heights.
    """

    name = "onnx"

    def __init__(
        self,
        path: str | Path,
        expect_config: FeatureConfig | dict | None = None,
        expect_kind: str | None = None,
        threads: int | None = None,
        tx_height_m: float = DEFAULT_TX_HEIGHT_M,
    ) -> None:
        self.tx_height_m = float(tx_height_m)
        self.threads = compute_threads() if threads is None else int(threads)
        self.path = Path(path)
        src = str(self.path)
        if not self.path.exists():
            raise InputError("no such model file", source=src)
        # a shipped name with flipped bytes loads and answers wrongly
        check_shipped_digest(self.path)
        try:
            opts = session_options(self.threads)
            self.session = ort.InferenceSession(
                src, sess_options=opts, providers=["CPUExecutionProvider"]
            )
        except Exception as e:  # onnxruntime raises its own exception types
            raise InputError(
                f"not a loadable ONNX model ({str(e).splitlines()[0][:200]})", source=src
            ) from None
        props = self.session.get_modelmeta().custom_metadata_map
        self.card = ModelCard.read(self.path, props, expect_config, expect_kind)
        norm = self.card.normalisation
        self.in_mean, self.in_std, self.out_mean, self.out_std = (
            norm.input_mean,
            norm.input_std,
            norm.output_mean,
            norm.output_std,
        )
        inp = self.session.get_inputs()[0]
        self.input_name = inp.name
        self.input_rank = len(inp.shape)
        self.n_features = self.card.n_features
        width = inp.shape[-1] if inp.shape else None
        if isinstance(width, int) and width != self.n_features:
            key = "feature_config.c_k" if self.kind == "clustering" else "feature_config.rss_length"
            raise InputError(
                f"network input has {width} values but the feature configuration gives "
                f"{self.n_features}",
                source=src,
                field=key,
            )
        if self.in_mean.size not in (1, self.n_features) or self.in_std.size not in (
            1,
            self.n_features,
        ):
            raise InputError(
                f"input normalisation has {self.in_mean.size} values, the features "
                f"{self.n_features}",
                source=src,
                field="input_normalisation",
            )

    @property
    def kind(self) -> str:
        """The features the network reads: "clustering" or "normalised_rss"."""
        return self.card.kind

    @property
    def cfg(self) -> FeatureConfig:
        return self.card.feature_config

    @property
    def origin(self) -> Origin:
        return self.card.origin

    @property
    def meta(self) -> dict:
        """The ONNX metadata, decoded (``training_data`` shown by reports, not checked)."""
        return self.card.meta

    @property
    def reference_height_m(self) -> float | None:
        return self.card.reference_height_m

    @property
    def model_name(self) -> str:
        return self.path.name

    def features(self, f: FlightSamples) -> np.ndarray:
        """Feature vector (F,) of a flight whose positions are ENU about the model's field
        origin."""
        if self.kind == "clustering":
            return cluster_features(f.enu_m[:, 0], f.enu_m[:, 1], f.rss_dbm, self.cfg)
        return normalised_rss(f.rss_dbm, self.cfg)

    @property
    def needs_heights(self) -> bool:
        """Whether ``predict_features`` needs each flight's height above the transmitter."""
        return self.reference_height_m is not None

    def predict_features(
        self, feats: np.ndarray, heights_m: np.ndarray | None = None
    ) -> np.ndarray:
        """(B, F) features -> (B, 2) positions in metres about the model's field origin;
        ``heights_m`` (B,): each flight's height above the transmitter, needed (and only used) by an
        altitude-normalised network."""
        s = None
        if self.needs_heights:
            if heights_m is None:
                raise InputError(
                    "an altitude-normalised network needs each flight's height above the "
                    "transmitter",
                    source=str(self.path),
                    field="heights_m",
                )
            s = scale_factor(heights_m, self.reference_height_m)
            feats = scale_cluster_xy(feats, s)
        x = (np.atleast_2d(feats) - self.in_mean) / self.in_std
        x = x.astype(np.float32)
        if self.input_rank == 3:
            x = x[:, None, :]
        out = self.session.run(None, {self.input_name: x})[0]
        out = np.asarray(out, dtype=np.float64).reshape(len(x), -1)[:, :2]
        out = out * self.out_std + self.out_mean
        return out if s is None else out / s[:, None]

    def predict(self, flight, origin: Origin | None = None) -> Estimate:
        """Estimate for a FlightLog (converted to the model's origin) or for arrays already in that
        frame."""
        if hasattr(flight, "columns"):
            f = as_flight(flight, self.origin)
        else:
            f = as_flight(flight)
        h = None
        # the log's own frame: heights above its ground origin, as the note reports them
        if self.needs_heights:
            h = [
                flight_height(
                    (flight.enu() if hasattr(flight, "columns") else f.enu_m)[:, 2],
                    self.tx_height_m,
                )
            ]
        xy = self.predict_features(self.features(f)[None, :], h)[0]
        lat, lon, _ = self.origin.to_geodetic(np.array([xy[0], xy[1], 0.0]))
        est = Estimate(
            float(xy[0]),
            float(xy[1]),
            self.name,
            self.model_name,
            float(lat),
            float(lon),
            extras={"feature_kind": self.kind, "model_origin": self.origin.to_dict()},
        )
        if h is not None:
            est.extras["height_above_tx_m"] = h[0]  # what the altitude-normalised network scaled by
        return est

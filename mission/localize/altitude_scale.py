"""Altitude-normalised network coordinates: horizontal metres rescaled by the flight's height above
the transmitter.

Why: free space with antenna gains that depend only on the direction of the link is scale-invariant.
Multiplying every sample's horizontal offset from the transmitter *and* its height above it by ``s``
multiplies every link distance by ``s`` and leaves every direction unchanged, so every RSS moves by
the same ``-20 log10 s`` dB (Friis, SPEC section 2), which the offset-invariant features ignore (the
k-means runs on z-scored columns, so its clusters do not change either).  A network that sees
horizontal coordinates in units of the flight's height therefore learns one function for every
altitude.  Two-ray interference is not exactly invariant (its fringes move), so it stays an
approximation.  In simulation (e2r spirals), the spiral network trained this way on altitudes 15-60
m held a 7-9 m mean error from 20 to 55 m, where the one trained at 30 m only went from 7 m at 30 m
to 60 m at 55 m (models/README.md).

Coordinates are scaled about the model's field origin by ``s = REFERENCE_HEIGHT_M / height``, and
the network's output is divided by ``s``.  At the reference height (a 30 m flight over a 1.5 m
transmitter) scaled metres are metres.
"""

from __future__ import annotations

import numpy as np

from mission.defaults import DEFAULT_TX_HEIGHT_M
from mission.errors import InputError
from mission.fields import Fields

REFERENCE_ALTITUDE_M = 30.0  # the mission altitude the networks were first trained at
# 28.5 m: over the default transmitter height
REFERENCE_HEIGHT_M = REFERENCE_ALTITUDE_M - DEFAULT_TX_HEIGHT_M
MIN_HEIGHT_M = (
    5.0  # below this height above the transmitter a flight is not a cruise: no scale is claimed
)
METADATA_KEY = "altitude_normalisation"  # in a network's ``training_data`` metadata


def metadata_entry() -> dict:
    """What ``rfsl train --altitude-normalised`` records under ``training_data[METADATA_KEY]``."""
    return {
        "reference_height_m": REFERENCE_HEIGHT_M,
        "scaled": "cluster x, y and the output about the field origin by reference_height_m / "
        "(median height "
        "of the samples used - transmitter height)",
    }


def reference_height(training_data: dict | None, src: str | None = None) -> float | None:
    """The reference height (m) of an altitude-normalised network from its ``training_data``
    metadata; None for a network whose coordinates are metres.  A malformed entry is an InputError
    naming the model ``src`` and the field."""
    td = Fields(training_data, src, "training_data")
    if not td.has(METADATA_KEY):
        return None
    return td.sub(METADATA_KEY).num("reference_height_m", lo=0.0, strict_lo=True)


def scale_factor(height_m, reference_m: float = REFERENCE_HEIGHT_M) -> np.ndarray:
    """``s = reference / height`` per flight (B,); refuses heights under ``MIN_HEIGHT_M`` or not
    finite."""
    h = np.atleast_1d(np.asarray(height_m, dtype=float))
    bad = ~np.isfinite(h) | (h < MIN_HEIGHT_M)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        who = "the flight" if h.size == 1 else f"flight {i}"
        raise InputError(
            f"{who} is {h[i]:.1f} m above the transmitter: an altitude-normalised network needs a "
            f"cruise at least {MIN_HEIGHT_M:.0f} m above it (transmitter height right?)",
            field="height",
        )
    return reference_m / h


def scale_cluster_xy(feats: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Clustering features (B, 3 C_k) laid out ``[p_1, x_1, y_1, ...]``
    (``features.cluster_features``) with every cluster's x and y multiplied by its flight's ``s``
    (B,); the RSS columns are unchanged.  Returns a copy."""
    out = np.array(feats, dtype=np.float64, ndmin=2)
    out[:, 1::3] *= s[:, None]
    out[:, 2::3] *= s[:, None]
    return out


def flight_height(z_m: np.ndarray, tx_height_m: float) -> float:
    """A flight's height above the transmitter (m): the median height of the samples used, minus the
    transmitter's (robust to the few take-off or landing samples a selection keeps)."""
    return float(np.median(np.asarray(z_m, dtype=float))) - float(tx_height_m)

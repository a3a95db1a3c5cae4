"""Transmitter localization from a flight log: features, classical estimators, ONNX networks.

Every localizer returns an ``Estimate``; ``mission.localize.api.localize_log`` is the one entry point used
by the ``localize`` CLI and by ``fly-mission`` after landing; the methods it runs are registered in
``mission.localize.methods``.
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class Estimate:
    """A transmitter position estimate in the local ENU frame of the log (x east, y north, metres)."""

    x_m: float
    y_m: float
    method: str
    model: str | None = None
    lat_deg: float | None = None
    lon_deg: float | None = None
    error_m: float | None = None
    extras: dict = field(default_factory=dict)
    posterior: object | None = field(default=None, repr=False)  # uncertainty.Posterior, when the method has one

    def to_dict(self) -> dict:
        d = {
            "lat_deg": self.lat_deg,
            "lon_deg": self.lon_deg,
            "x_m": self.x_m,
            "y_m": self.y_m,
            "method": self.method,
            "model": self.model,
        }
        if self.error_m is not None:
            d["error_m"] = self.error_m
        d.update({k: v for k, v in self.extras.items() if k not in d})
        return d

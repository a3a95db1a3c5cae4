"""``FlightSamples``: one flight's per-sample arrays in memory, the one container every step reads.

Why one: the localizers, the gap diagnosis, calibration, the simulator and the dataset generator all
need the same few arrays (times, UAV positions, attitudes, RSS, the transmitter when known); one
container with names that carry their units means one spelling of each (``rss_dbm``, never ``rss``
or ``rss_db``).  A ``FlightLog`` gives its view with ``FlightLog.samples()``; ``SimulatedFlight`` is
one with its flight profile; a dataset's ``FlightDraw`` holds one beside its random draws.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

PER_SAMPLE = ("enu_m", "rss_dbm", "attitude_rad", "t_s", "phase")  # the fields ``select`` cuts


@dataclass
class FlightSamples:
    """Per-sample arrays of one flight (N samples) and what belongs to the flight as a whole.

    ``attitude_rad`` is None when the log has none (a receiver-only log), ``t_s`` when the input
    gave only positions and RSS, ``phase`` when the log has no mission-phase column, ``tx_enu_m``
    when the truth is unknown.  Power is dBm (a real receiver's uncalibrated dB; everything
    downstream is offset-invariant).
    """

    enu_m: np.ndarray  # (N, 3) UAV positions, local ENU metres (z above the origin's ground)
    rss_dbm: np.ndarray  # (N,) received power
    attitude_rad: np.ndarray | None = None  # (N, 3) roll, pitch, yaw (SPEC section 1)
    t_s: np.ndarray | None = None  # (N,) time since the log's start
    phase: np.ndarray | None = None  # (N,) mission phase names (``flightlog.PHASES``)
    tx_enu_m: np.ndarray | None = None  # (3,) true transmitter position
    name: str = "flight"
    meta: dict = field(default_factory=dict)  # the log's sidecar metadata, when it came from one

    def __len__(self) -> int:
        return len(self.rss_dbm)

    def select(self, mask: np.ndarray | slice) -> FlightSamples:
        """The samples where ``mask`` holds (a boolean mask, indices or a slice); times stay
        absolute, and a subclass keeps its type and its other fields."""
        cut = {k: getattr(self, k)[mask] for k in PER_SAMPLE if getattr(self, k) is not None}
        return replace(self, **cut, meta=dict(self.meta))

"""The mission phase of a flown vehicle over time, for the ``phase`` / ``mission_item`` log columns.

Why: later steps (localization) select the mission legs of a log; the vehicle's landed state and the
mission progress say which phase it is in, but they arrive as events.  ``PhaseTracker`` turns them
into a step function of vehicle time that the log writer reads for each row.  Phase names:
``flightlog.PHASES``. A simulated flight has no events: ``simulate.path_phases`` derives the same
columns from its planned path (same names, same item rule: the index of the waypoint being flown to,
counted from the first).
"""

from __future__ import annotations

import numpy as np

from mission.flightlog import ADAPTIVE, GROUND, LAND, MISSION, RETURN, TAKEOFF


def final_phase(return_behaviour: str) -> str:
    """The phase of a mission's final item: ``land`` for ``return_behaviour: land``, else
    ``return``."""
    return LAND if return_behaviour == "land" else RETURN


class PhaseTracker:
    """Phase and mission item as a step function of vehicle time, fed by landed-state and progress
    events.

    ``first_wp`` is the raw item index of the first waypoint, ``last_item`` that of the final item
    (RTL or LAND, ``final`` names which); mission item = raw index - ``first_wp`` while flying the
    waypoints.
    """

    def __init__(self) -> None:
        self.t: list[float] = [-np.inf]
        self.phase: list[str] = [GROUND]
        self.item: list[int] = [-1]
        self.first_wp, self.last_item, self.final = 0, 1 << 30, RETURN
        self.landed_state = "ON_GROUND"
        self.raw_item = -1
        self.returning = False
        # raw index of the first adaptive waypoint (missions extended in flight)
        self.first_adaptive = 1 << 30

    def configure(
        self, first_wp: int, last_item: int, final: str, first_adaptive: int | None = None
    ) -> None:
        """Raw indices of the first waypoint and the final item; ``first_adaptive``: raw items from
        there on are legs planned in flight (``adaptive``, item counted from 0 there)."""
        self.first_wp, self.last_item, self.final = first_wp, last_item, final
        if first_adaptive is not None:
            self.first_adaptive = first_adaptive

    @property
    def current(self) -> str:
        return self.phase[-1]

    def _set(self, t: float, phase: str, item: int) -> None:
        if (phase, item) == (self.phase[-1], self.item[-1]) or not np.isfinite(t):
            return
        t = max(t, self.t[-1])
        self.t.append(t)
        self.phase.append(phase)
        self.item.append(item)

    def _update(self, t: float) -> None:
        ls = self.landed_state
        if ls == "ON_GROUND":
            self._set(t, GROUND, -1)
        elif ls == "LANDING":
            self._set(t, LAND, -1)
        elif self.returning or self.raw_item >= self.last_item:
            self._set(t, self.final if not self.returning else RETURN, -1)
        elif ls == "TAKING_OFF" or self.raw_item < self.first_wp:
            self._set(t, TAKEOFF, -1)
        elif self.raw_item >= self.first_adaptive:
            self._set(t, ADAPTIVE, self.raw_item - self.first_adaptive)
        else:
            self._set(t, MISSION, self.raw_item - self.first_wp)

    def on_landed_state(self, t: float, name: str) -> None:
        """MAVSDK ``LandedState`` name (ON_GROUND, TAKING_OFF, IN_AIR, LANDING) at vehicle time
        ``t``."""
        if name == "ON_GROUND" and self.landed_state != "ON_GROUND":
            self.returning = False
        self.landed_state = name
        self._update(t)

    def on_progress(self, t: float, raw_item: int) -> None:
        """The mission's current raw item at vehicle time ``t``."""
        self.raw_item = raw_item
        self._update(t)

    def on_return(self, t: float) -> None:
        """Return to launch commanded (abort or failure)."""
        self.returning = True
        self._update(t)

    def at(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Phase names and mission items at vehicle times ``t``."""
        k = np.searchsorted(np.asarray(self.t), np.asarray(t, dtype=float), side="right") - 1
        return np.asarray(self.phase, dtype=object)[k].astype(str), np.asarray(self.item)[k]


__all__ = [
    "PhaseTracker",
    "final_phase",
    "GROUND",
    "TAKEOFF",
    "MISSION",
    "ADAPTIVE",
    "RETURN",
    "LAND",
]


class MonotonicPhases(PhaseTracker):
    """The tracker a flight uses: mission progress never goes back in flight (a re-upload briefly
    reports item 0 before the current item is set again, which must not relabel rows as
    take-off)."""

    def on_progress(self, t: float, raw_item: int) -> None:
        if self.landed_state == "ON_GROUND" or raw_item >= self.raw_item or self.returning:
            super().on_progress(t, raw_item)

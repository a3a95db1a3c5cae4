"""How a real autopilot flies what the kinematic plan (``trajectory.kinematics``) leaves open: its
pace on mission legs, its own climb and landing speeds, and its return to launch from anywhere.

Why apart from the flight's budget (``mission.flight.budget``, which measures and acts during a
flight): the adaptive round planner and the fast simulator plan with the same return, and neither
needs a MAVLink link.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mission.trajectory.kinematics import Kinematics, plan_profile


@dataclass(frozen=True)
class Pace:
    """Flown leg time = planned x (``scale`` + ``headwind`` . u) + ``per_leg_s`` (the stop and
    restart at a waypoint), u the leg's unit direction (east, north).  Why the headwind: in wind a
    multicopter holds its ground speed downwind and loses it upwind, so the legs' pace depends on
    their direction (ArduCopter SITL in an 8 m/s wind: upwind legs up to 10 s slow, the others on
    plan); ``headwind`` points where the wind comes from, in extra seconds per planned second.  A
    closed loop (a round's square, a whole ring) sums it to about zero, so legs without a direction
    are planned at ``scale`` alone."""

    scale: float = 1.0
    per_leg_s: float = 0.0
    headwind: tuple[float, float] = (0.0, 0.0)

    def legs(self, planned: np.ndarray, dirs: np.ndarray | None = None) -> float:
        """Seconds to fly legs planned at ``planned`` seconds each, in unit directions ``dirs``
        (n x 2, east and north) when known."""
        planned = np.asarray(planned, dtype=float)
        extra = 0.0
        if dirs is not None and planned.size:
            extra = float(planned @ (np.asarray(dirs, dtype=float) @ np.asarray(self.headwind)))
        return self.flown(planned.sum(), planned.size) + extra

    def flown(self, planned_s: float, n_legs: int) -> float:
        """Seconds to fly ``n_legs`` legs planned at ``planned_s`` seconds in all (directions
        unknown: the headwind left out)."""
        return float(self.scale * planned_s + self.per_leg_s * n_legs)

    def at_least(self, other: Pace | None) -> Pace:
        """Each term the larger of this pace's and ``other``'s: what a plan of short legs takes
        when this pace was fitted on long ones, which cannot tell a cost per leg from a slower
        cruise (PX4 SITL's survey fit gave 1.11 x + 0.05 s a leg; its 28 m round then took 54 s
        where that pace planned 40, and its known 1.03 x + 3 s a leg plans 55); the headwind is
        this pace's."""
        if other is None:
            return self
        return Pace(
            max(self.scale, other.scale), max(self.per_leg_s, other.per_leg_s), self.headwind
        )


@dataclass(frozen=True)
class VerticalSpeeds:
    """The autopilot's own climb and descent speeds (m/s): take-off at ``up_mps``; the final descent
    at ``down_mps`` down to ``low_alt_m`` above ground, then at ``land_mps`` (ArduCopter: 0.5 m/s
    below 10 m, which made its landing 36 s where the mission's kinematics plan 12 s)."""

    up_mps: float
    down_mps: float
    land_mps: float
    low_alt_m: float
    hover_s: float = (
        0.0  # hover over home before the descent of a return (ArduPilot RTL_LOIT_TIME: 5 s)
    )
    # a return climbs to this height above home first when lower (PX4 RTL_RETURN_ALT, 30 m on a
    # multicopter; ArduPilot RTL_ALT, 15 m): PX4 SITL climbed from a 15 m round to 30 m
    return_alt_m: float = 0.0

    def valid(self) -> bool:
        return (
            min(self.up_mps, self.down_mps, self.land_mps) > 0
            and self.low_alt_m >= 0 <= self.hover_s
            and self.return_alt_m >= 0
        )


def leg_speeds(
    d: np.ndarray, kin: Kinematics, vertical: VerticalSpeeds | None, horizontal_mps: float
) -> tuple[np.ndarray, np.ndarray]:
    """The cruise speed of each leg ``d`` (K, 3), and which legs are vertical (``plan_profile``'s
    rule): a vertical leg at the autopilot's climb or descent speed (the mission's climb rate when
    they are not known), the others at ``horizontal_mps``."""
    vert = np.abs(d[:, 2]) / np.maximum(np.linalg.norm(d, axis=1), 1e-9) > 0.7
    vs = np.full(len(d), kin.climb_rate_mps)
    if vertical is not None:
        vs = np.where(d[:, 2] > 0, vertical.up_mps, vertical.down_mps)
    return np.where(vert, vs, horizontal_mps), vert


@dataclass(frozen=True)
class ReturnModel:
    """How the vehicle gets from anywhere to disarmed on the ground at the end of its mission: with
    ``behaviour`` "rtl" it climbs to the autopilot's return altitude when lower, flies over home at
    ``speed_mps`` (None: the mission's cruise), hovers, descends at the autopilot's ``vertical``
    speeds (None: the mission's climb rate) and disarms ``disarm_s`` later; with "land" it descends
    where it is.

    Why one model: the budget plan's return from the survey and the adaptive rounds' return from a
    round's end must be the same flight (PX4 SITL overran its budget by 13 s when the rounds planned
    their return without the climb to 30 m and PX4's landing speeds)."""

    home: np.ndarray
    kin: Kinematics
    behaviour: str = "rtl"
    speed_mps: float | None = None
    vertical: VerticalSpeeds | None = None
    disarm_s: float = 0.0

    @classmethod
    def of(cls, spec, **kw) -> ReturnModel:
        """The return of ``spec`` (its home, kinematics and return behaviour), with ``kw`` the
        autopilot's own settings when known."""
        home = np.asarray(spec.home_enu, dtype=float)
        return cls(home, spec.kinematics(), spec.return_behaviour, **kw)

    def legs(self, frm) -> tuple[np.ndarray, np.ndarray, int]:
        """The path from ``frm`` (3,) to the ground (vertices, no zero-length leg), each leg's
        cruise speed, and the index of the first leg of the final descent."""
        frm, h, v = np.asarray(frm, dtype=float), self.home, self.vertical
        if self.behaviour == "land" or frm[2] <= h[2]:  # (on the ground: nothing to climb)
            pts = [frm, [frm[0], frm[1], h[2]]]
        else:
            z = max(frm[2], h[2] + (v.return_alt_m if v is not None else 0.0))
            pts = [frm, [frm[0], frm[1], z], [h[0], h[1], z], h]
        pts = np.asarray(pts, dtype=float)
        if v is not None and 0 < v.low_alt_m < pts[-2, 2] - h[2]:  # slower below low_alt_m
            pts = np.vstack([pts[:-1], pts[-1] + [0.0, 0.0, v.low_alt_m], pts[-1:]])
        d = np.diff(pts, axis=0)
        keep = np.linalg.norm(d, axis=1) > 1e-6
        pts, d = pts[np.concatenate([[True], keep])], d[keep]
        speeds, vert = leg_speeds(d, self.kin, v, self.speed_mps or self.kin.cruise_speed_mps)
        if v is not None and len(d) and vert[-1]:
            speeds[-1] = v.land_mps  # the last leg ends on the ground below low_alt_m
        j = len(d)
        while j > 0 and vert[j - 1] and d[j - 1, 2] < 0:
            j -= 1
        return pts, speeds, j

    @property
    def after_s(self) -> float:
        """Seconds over home and on the ground that no flying covers: the hover (a return only)
        and touchdown to disarm."""
        hover = self.vertical.hover_s if self.vertical is not None else 0.0
        return (hover if self.behaviour == "rtl" else 0.0) + self.disarm_s

    def split(self, frm) -> tuple[float, float]:
        """(seconds flying back until the final descent starts, seconds from there to disarmed)
        from ``frm`` at rest."""
        pts, speeds, j = self.legs(frm)
        if len(pts) < 2:
            return 0.0, self.after_s
        t = plan_profile(pts, self.kin, speeds=speeds).t_vertex
        return float(t[j]), float(t[-1] - t[j]) + self.after_s

    def seconds(self, frm, pace: Pace | None = None) -> float:
        """Seconds from ``frm`` (at rest) to disarmed; the flying back at ``pace`` when given, the
        descent and what follows at the autopilot's own speeds (as ``BudgetWatch.predict``)."""
        back, land = self.split(frm)
        return (back if pace is None else pace.flown(back, 1)) + land

"""How an estimate reads: its point, its region and its error, in one place for the ``localize``
table, ``fly-mission``'s last lines and the live status line.

Why one home: the three printed the same three facts each their own way (the error as "truth" in
one, "true transmitter at" in another; the region of a live entry and of an estimate worded apart).
``Shown`` is what they show, built from an ``Estimate`` (``of``) or from a live series entry
(``of_entry``: ``mission.flight.live.summary``, which keeps the point and the region's area only);
each output picks its form: ``rows`` (table), ``lines`` (last lines, each within 80 columns),
``line`` (status line).  Imports only the region, so the flight process can render without loading
the localizer.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from mission.localize.region import Region, widest

NO_REGION = "none: no calibration applies to this flight (localize --json: notes)"
SERIES_LEVEL = 0.9  # the level of a live series entry's region area (``mission.flight.live``)


@dataclass(frozen=True)
class Shown:
    """The facts every output shows of an estimate: point (log ENU m; WGS84 when known), who
    answered, its regions (an estimate) or its region's area (a live entry, at ``level``), the
    truth and the error when known (the error measured from the truth unless given), and when in
    the flight it was made (a live entry's log time)."""

    x_m: float
    y_m: float
    label: str
    lat_deg: float | None = None
    lon_deg: float | None = None
    regions: tuple[Region, ...] = ()
    area_m2: float | None = None
    level: float = SERIES_LEVEL
    truth: tuple[float, float] | None = None
    error_m: float | None = None
    t_s: float | None = None

    def __post_init__(self) -> None:
        if self.truth is not None and self.error_m is None:
            err = math.hypot(self.x_m - self.truth[0], self.y_m - self.truth[1])
            object.__setattr__(self, "error_m", err)

    @classmethod
    def of(cls, est, truth: dict | None = None) -> Shown:
        """From an ``Estimate``; ``truth`` ({"x_m", "y_m"}) or else the one the log's sidecar
        gave it (``truth_x_m``, ``truth_y_m`` beside ``error_m``)."""
        model = est.extras.get("model_path")  # which network answered, when one did
        t, err = None, None
        if truth is not None:
            t = (float(truth["x_m"]), float(truth["y_m"]))
        elif est.error_m is not None and "truth_x_m" in est.extras:
            t = (float(est.extras["truth_x_m"]), float(est.extras["truth_y_m"]))
            err = est.error_m
        outer = est.outer_region
        return cls(
            est.x_m,
            est.y_m,
            est.method + (f" {Path(model).name}" if model else ""),
            est.lat_deg,
            est.lon_deg,
            tuple(est.regions),
            None if outer is None else outer.area_m2,
            SERIES_LEVEL if outer is None else outer.level,
            t,
            err,
        )

    @classmethod
    def of_entry(cls, d: dict, truth: dict | None = None, method: str = "", origin=None) -> Shown:
        """From a live series entry (``t_s``, ``x_m``, ``y_m``, ``area_m2``, ``method``);
        ``origin`` (the log frame's ``geo.Origin``): its WGS84 point too, which a field team
        walks to."""
        x, y = float(d["x_m"]), float(d["y_m"])
        lat = lon = None
        if origin is not None:
            la, lo, _ = origin.to_geodetic([x, y, 0.0])
            lat, lon = float(la), float(lo)
        return cls(
            x,
            y,
            str(d.get("method") or method),
            lat,
            lon,
            area_m2=d.get("area_m2"),
            truth=None if truth is None else (float(truth["x_m"]), float(truth["y_m"])),
            t_s=d.get("t_s"),
        )

    @property
    def outer(self) -> Region | None:
        return widest(self.regions)

    def error(self, bold: bool = False) -> str:
        """The error and where the truth lies ("" when unknown); ``bold``: rich markup on the
        number."""
        if self.truth is None:
            return ""
        e = f"{self.error_m:.1f} m"
        return (f"[bold]{e}[/]" if bold else e) + (
            f" (true transmitter at {self.truth[0]:.1f}, {self.truth[1]:.1f} m)"
        )

    def rows(self) -> list[tuple[str, str]]:
        """The ``localize`` table's point and error rows (rich markup)."""
        out = [("local x, y", f"{self.x_m:.1f} m east, {self.y_m:.1f} m north (log origin)")]
        if self.lat_deg is not None:
            out.append(("lat, lon", f"{self.lat_deg:.7f}, {self.lon_deg:.7f}"))
        if self.truth is not None:
            out.append(("error", self.error(bold=True)))
        return out

    def region_rows(self) -> list[tuple[str, str]]:
        """The table's region rows: every region in full, lowest level first."""
        return [(f"{100 * r.level:.0f} % region", r.describe()) for r in self.regions]

    def lines(self) -> list[str]:
        """``fly-mission``'s last lines: point, method, widest region, error (within 80
        columns for the usual widths)."""
        where = (
            f" (lat {self.lat_deg:.7f}, lon {self.lon_deg:.7f})" if self.lat_deg is not None else ""
        )
        out = [f"estimate: x={self.x_m:.1f} m, y={self.y_m:.1f} m{where}"]
        if self.t_s is None:
            out.append(f"  method: {self.label}")
        else:
            out.append(f"  method: {self.label}, in flight at t={self.t_s:g} s")
            out.append(f"  (`localize LOG --at {self.t_s:g}` gives it back)")
        if self.outer is not None:
            reg = self.outer.describe(short=True)
        elif self.area_m2 is not None:
            reg = f"{self.area_m2:.0f} m^2"  # a live entry keeps its region's area only
        else:
            reg = None
        out.append(
            f"  region: {NO_REGION}" if reg is None else f"  {100 * self.level:.0f} % region: {reg}"
        )
        if self.truth is not None:
            out.append(f"  error: {self.error()}")
        return out

    def line(self) -> str:
        """The live status line: point, the region's area and the error, short."""
        text = f"({self.x_m:.0f}, {self.y_m:.0f}) m"
        if self.area_m2 is not None:
            text += f", {100 * self.level:.0f} % in {self.area_m2:.0f} m^2"
        if self.truth is not None:
            text += f", error {self.error_m:.1f} m"
        return text

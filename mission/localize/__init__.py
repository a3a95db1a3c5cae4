"""Transmitter localization from a flight log: features, classical estimators, ONNX networks.

Every localizer returns an ``Estimate``; ``mission.localize.api.localize_log`` is the one entry
point used by the ``localize`` CLI and by ``fly-mission`` after landing; the methods it runs are
registered in ``mission.localize.methods``.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field

from mission.localize.region import Region, widest


def sentence(note: str) -> str:
    """``note`` ending as a sentence (a full stop added where it ends without one), so that notes
    joined one after another read apart ("... an extrapolation. rfsl_spiral_e2r.onnx was ...")."""
    note = note.strip()
    return note if note.endswith((".", "!", "?")) else note + "."


@dataclass(frozen=True)
class Selection:
    """Which samples an estimate used: ``used`` of ``total``, and why
    (``preprocess.select_samples``)."""

    used: int
    total: int
    why: str

    def to_dict(self) -> dict:
        return {"cruise": self.why, "samples_used": self.used, "samples_total": self.total}

    def line(self) -> str:
        return f"{self.used} of {self.total}: {self.why}"


@dataclass(frozen=True)
class Fit:
    """The per-flight nuisance a model-based method fitted: RSS offset (dB), residual rms (dB), UAV
    antenna."""

    offset_db: float
    residual_rms_db: float | None = None
    antenna: str | None = None

    @classmethod
    def from_extras(cls, extras: dict) -> Fit | None:
        """The fit a method recorded in its extras (``offset_db``, ``cost_rms_db`` or
        ``residual_rms_db``, ``antenna``); None for a method that fits no offset."""
        if "offset_db" not in extras:
            return None
        rms = extras.get("cost_rms_db", extras.get("residual_rms_db"))
        return cls(
            float(extras["offset_db"]), None if rms is None else float(rms), extras.get("antenna")
        )

    def line(self) -> str:
        out = f"offset {self.offset_db:.1f} dB"
        if self.residual_rms_db is not None:
            out += f", residual rms {self.residual_rms_db:.2f} dB"
        return out + (f"; UAV antenna: {self.antenna}" if self.antenna else "")


@dataclass
class Estimate:
    """A transmitter position estimate in the local ENU frame of the log (x east, y north, metres).

    ``extras`` is the ordered record that ``to_dict`` / ``--json`` print after the position.  What
    consumers read has a typed home: ``regions`` (the 50 / 90 % regions, ``Region``), ``notes``
    (the sentences ``localize`` prints under "note"), ``components`` (a fusion's member estimates).
    Setting one writes its JSON form into ``extras`` at that moment (``"regions"`` as
    ``Region.to_dict``, ``"note"`` joined by spaces, ``"components"`` as name -> [x, y]), so the
    output keeps the key order it always had.  ``Region`` objects passed in ``extras["regions"]``
    at construction become ``regions``; any other value there is a composer's own layout, printed
    as it is (the benchmark reads it: ``mission.workshop.evaluate_suite``).
    """

    x_m: float
    y_m: float
    method: str
    model: str | None = None
    lat_deg: float | None = None
    lon_deg: float | None = None
    error_m: float | None = None
    extras: dict = field(default_factory=dict)
    # uncertainty.Posterior, when the method has one
    posterior: object | None = field(default=None, repr=False)
    notes: list[str] = field(default_factory=list, repr=False)
    components: dict[str, Estimate] = field(default_factory=dict, repr=False)
    # candidates.Candidate, most weight first
    candidates: list = field(default_factory=list, repr=False)
    selection: Selection | None = field(default=None, repr=False)
    _regions: tuple[Region, ...] = field(default=(), init=False, repr=False)

    @property
    def fit(self) -> Fit | None:
        """The nuisance the method fitted, typed (None when it fits none)."""
        return Fit.from_extras(self.extras)

    def __post_init__(self) -> None:
        self.notes = [sentence(n) for n in self.notes if n]
        if self.notes:
            self.extras["note"] = " ".join(self.notes)
        given = self.extras.get("regions")
        if isinstance(given, list | tuple) and all(isinstance(r, Region) for r in given):
            self.regions = given

    @property
    def regions(self) -> tuple[Region, ...]:
        """The uncertainty regions, lowest level first: HPD sets of a posterior or error circles
        (``Region``); empty when none applies."""
        return self._regions

    @regions.setter
    def regions(self, value: Iterable[Region]) -> None:
        self._regions = tuple(value)
        self.extras["regions"] = [r.to_dict() for r in self._regions]

    def region(self, level: float) -> Region | None:
        """The region of nominal ``level`` (None when the estimate has none)."""
        return next((r for r in self._regions if r.level == level), None)

    @property
    def outer_region(self) -> Region | None:
        """The widest region (highest level), None when the estimate has none."""
        return widest(self._regions)

    def add_note(self, note: str | None) -> None:
        """Append a sentence to ``notes`` (nothing for an empty one)."""
        if note:
            self.notes.append(sentence(note))
            self.extras["note"] = " ".join(self.notes)

    def set_components(self, members: dict[str, Estimate]) -> None:
        """The member estimates of a fusion, by name (in the log's frame)."""
        self.components = dict(members)
        self.extras["components"] = {n: [e.x_m, e.y_m] for n, e in members.items()}

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
        sel = self.selection.to_dict() if self.selection is not None else {}
        # the selection's keys follow method_choice, as they always did
        for k, v in self.extras.items():
            if k not in d:
                d[k] = v
                if k == "method_choice":
                    d.update(sel)
        for k, v in sel.items():
            d.setdefault(k, v)
        return d

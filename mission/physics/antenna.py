"""Antenna patterns by name or file, and the shipped measured UAV antenna (RM-WB1-DN, 3300 MHz).

The antenna frame, mounting (:func:`mount_angles`) and the pattern classes live in
``mission.physics.patterns``; the CSV and AERPAW file formats in ``mission.physics.pattern_files``.
Both are re-exported here, so ``from mission.physics.antenna import Dipole, load_pattern_csv,
rm_wb1_dn`` keeps working.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from mission.errors import InputError
from mission.physics.pattern_files import (
    AERPAW_CREDIT,
    load_aerpaw_pattern,
    load_pattern_csv,
    save_pattern_csv,
)
from mission.physics.patterns import (
    TWO_PI,
    Dipole,
    Isotropic,
    Mounted,
    Pattern,
    TabulatedPattern,
    mount_angles,
    sphere_integral,
)

__all__ = [
    "AERPAW_CREDIT",
    "SHIPPED_RM_WB1_DN",
    "TWO_PI",
    "Dipole",
    "Isotropic",
    "Mounted",
    "Pattern",
    "TabulatedPattern",
    "load_aerpaw_pattern",
    "load_pattern",
    "load_pattern_csv",
    "mount_angles",
    "rm_wb1_dn",
    "save_pattern_csv",
    "sphere_integral",
]

SHIPPED_RM_WB1_DN = "rm_wb1_dn_right_side_up_3300mhz.csv"


def load_pattern(spec: str | Path) -> Pattern:
    """A pattern by name (``isotropic``, ``dipole``, ``measured`` = shipped RM-WB1-DN) or file path.

    Files ending in ``.csv`` use the CSV format; other files are read as AERPAW measurement files.
    """
    key = str(spec).strip().lower()
    if key == "isotropic":
        return Isotropic()
    if key == "dipole":
        return Dipole()
    if key in ("measured", "rm-wb1-dn", "rm_wb1_dn"):
        return rm_wb1_dn()
    path = Path(spec)
    if not path.is_file():
        raise InputError(
            "antenna pattern file not found (or use isotropic, dipole, measured)", source=str(path)
        )
    if path.suffix.lower() == ".csv":
        return load_pattern_csv(path)
    return load_aerpaw_pattern(path)


_CACHE: dict[str, TabulatedPattern] = {}


def rm_wb1_dn() -> TabulatedPattern:
    """The shipped RM-WB1-DN(-BLK) right-side-up pattern at 3300 MHz (directivity, dBi)."""
    if SHIPPED_RM_WB1_DN not in _CACHE:
        ref = resources.files("mission").joinpath("data", SHIPPED_RM_WB1_DN)
        with resources.as_file(ref) as p:
            _CACHE[SHIPPED_RM_WB1_DN] = load_pattern_csv(p, name="RM-WB1-DN right side up 3300 MHz")
    return _CACHE[SHIPPED_RM_WB1_DN]

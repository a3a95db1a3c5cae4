"""Antenna gain patterns: isotropic, vertical half-wave dipole, tabulated 3D (CSV or measured AERPAW files).

Antenna frame
-------------
Every pattern is a function of direction in the antenna's own right-handed frame: ``z_a`` is the
antenna's "up" (its axis, pointing away from its mounting base when right side up), elevation ``el``
is measured from the antenna's horizontal plane (positive towards ``z_a``) and azimuth ``az`` is
counter-clockwise from ``x_a`` seen from above (the usual spherical convention of a chamber
measurement). Angles are radians in code, degrees in files.

Mounting (:func:`mount_angles`) maps a platform's angles to the antenna frame. Platform angles are
``el_p`` (up-positive elevation of the platform's level/body plane) and ``az_p`` clockwise from the
platform's forward direction (the body azimuth ``az_b`` for the UAV, the compass bearing for the rover).
``heading_rad`` turns the antenna's ``x_a`` clockwise from forward; ``flipped`` mounts it upside down
(a 180 degree turn about ``x_a``): upright ``el_a = el_p, az_a = -(az_p - heading)``; flipped
``el_a = -el_p, az_a = az_p - heading``.

Tabulated CSV format (:func:`load_pattern_csv`, :func:`save_pattern_csv`)
------------------------------------------------------------------------
UTF-8 text. Lines starting with ``#`` are comments (source, licence, normalisation). The first other
line is the header: a label cell (e.g. ``el\\az``) then the azimuths in degrees, strictly ascending,
distinct modulo 360 (the grid is periodic in azimuth; e.g. 0, 3, ..., 357). Each further line is an
elevation in degrees (strictly ascending over the rows, within [-90, 90]) then the gains in dBi, one per
azimuth. Gains are interpolated bilinearly in dB (periodic in azimuth); elevations outside the table's
range are clamped to its first/last row. Example::

    # my antenna, 3.3 GHz, gain dBi
    el\\az,0,90,180,270
    -90,-10,-10,-10,-10
    0,2,2,1.5,2
    90,-10,-10,-10,-10

Measured AERPAW files (:func:`load_aerpaw_pattern`)
---------------------------------------------------
AERPAW "3D antenna radiation pattern measurement" (anechoic chamber, 3300 MHz): rows
``Phi(rad) Theta(rad) ETotal_dB EPhi_dB ETheta_dB EPhi_phase ETheta_phase`` with Phi 0..177 deg and Theta
-180..180 deg in 3 deg steps. Theta is the polar angle from the antenna axis in the cut plane at
azimuth Phi; negative Theta is the opposite half of that cut (azimuth Phi + 180). Direction
``(sin T cos P, sin T sin P, cos T)``, so ``el = 90 - |Theta|`` and ``az = Phi`` (Theta >= 0) or
``Phi + 180`` (Theta < 0). Evidence: all Phi give the same value at Theta = 0 and at Theta = +-180
(the poles of the cut system); the upside-down RM-WB1-DN file matches the right-side-up one turned
180 degrees about the chamber x axis (2.3 dB rms, against 5-6 dB for any turn about z), so the
antenna's axis is the chamber z axis; and the dipole-like SA-1400-5900 has its deep null within about
20 degrees of Theta = 0. The right-side-up RM-WB1-DN at 3.3 GHz is NOT a donut: its maximum (~+6 dBi)
is within about 15 degrees of its axis (z_a up, away from the base) and it is weakest below (Theta
near +-180). ETotal_dB is relative; it is normalised to directivity (dBi) by integrating the radiated
power over the sphere: ``G = E + 10 log10(4 pi / sum 10^(E/10) cos(el) d_el d_az)`` (trapezoid in
elevation, rectangle in the periodic azimuth), i.e. a lossless antenna (efficiency 1).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mission.errors import InputError
from mission.physics.constants import DIPOLE_G0, GAIN_FLOOR_DBI

TWO_PI = 2.0 * np.pi
SHIPPED_RM_WB1_DN = "rm_wb1_dn_right_side_up_3300mhz.csv"
AERPAW_CREDIT = ('AERPAW "3D antenna radiation pattern measurement" data set (anechoic chamber), as carried '
                 "in anilgurses/CHEM data/antenna (commit 6b9e58f8)")


def mount_angles(el_p: ArrayLike, az_p: ArrayLike, heading_rad: float = 0.0, flipped: bool = False
                 ) -> tuple[NDArray, NDArray]:
    """Platform angles (el up-positive, az clockwise from forward) -> antenna-frame (el_a, az_a), rad."""
    el_p = np.asarray(el_p)
    az_p = np.asarray(az_p)
    if flipped:  # 180 deg about x_a: (x, y, z) -> (x, -y, -z)
        return -el_p, np.mod(az_p - heading_rad, TWO_PI)
    return el_p, np.mod(heading_rad - az_p, TWO_PI)


class Pattern:
    """Base class: gain of an antenna in its own frame.

    ``gain_dbi(el, az)`` is the reference (angles in rad, float64); ``amplitude(sin_el, cos_el, az)`` is
    the fast path used by the propagation kernel: sqrt of the linear gain, dtype preserved. ``az`` is only
    computed by the caller when ``azimuth_symmetric`` is False.
    """

    name: str = "pattern"
    azimuth_symmetric: bool = False
    elevation_symmetric: bool = False

    def gain_dbi(self, el: ArrayLike, az: ArrayLike) -> NDArray[np.float64]:  # pragma: no cover
        raise NotImplementedError

    def amplitude(self, sin_el: NDArray, cos_el: NDArray, az: NDArray | None) -> NDArray:
        el = np.arctan2(sin_el, cos_el)
        return self.amplitude_at(el, az if az is not None else np.zeros_like(el))

    def amplitude_at(self, el: NDArray, az: NDArray) -> NDArray:
        """sqrt of the linear gain at antenna-frame angles (rad), dtype of ``el``."""
        g = self.gain_dbi(el, az)
        return np.power(10.0, g / 20.0).astype(np.result_type(el), copy=False)


@dataclass(frozen=True)
class Isotropic(Pattern):
    """0 dBi in every direction."""

    name: str = "isotropic"
    azimuth_symmetric: bool = True
    elevation_symmetric: bool = True

    def gain_dbi(self, el: ArrayLike, az: ArrayLike) -> NDArray[np.float64]:
        return np.zeros(np.broadcast_shapes(np.shape(el), np.shape(az)))

    def amplitude(self, sin_el: NDArray, cos_el: NDArray, az: NDArray | None) -> NDArray:
        return np.ones_like(sin_el)


@dataclass(frozen=True)
class Dipole(Pattern):
    """Vertical half-wave dipole ("donut"): G = G_0 (cos(pi/2 sin el) / cos el)^2 (SPEC section 3).

    ``g0`` = 1.641 (2.15 dBi at el = 0); the axial limit (el = +-90 deg) is 0, floored at ``floor_dbi``.
    """

    g0: float = DIPOLE_G0
    floor_dbi: float = GAIN_FLOOR_DBI
    name: str = "dipole"
    azimuth_symmetric: bool = True
    elevation_symmetric: bool = True

    def gain_dbi(self, el: ArrayLike, az: ArrayLike | None = None) -> NDArray[np.float64]:
        el = np.asarray(el, dtype=float)
        cos_el = np.cos(el)
        with np.errstate(divide="ignore", invalid="ignore"):
            G = self.g0 * (np.cos(0.5 * np.pi * np.sin(el)) / cos_el) ** 2
        G = np.where(np.abs(cos_el) < 1e-12, 0.0, G)  # limit at the axis
        return np.maximum(10.0 * np.log10(np.maximum(G, 1e-300)), self.floor_dbi)

    def amplitude(self, sin_el: NDArray, cos_el: NDArray, az: NDArray | None) -> NDArray:
        # sqrt(G) = sqrt(G_0) cos(pi/2 sin el) / cos el, no trig for cos el (the caller has it)
        dt = np.result_type(sin_el)
        a = np.cos(sin_el * dt.type(0.5 * np.pi))
        a *= dt.type(math.sqrt(self.g0))
        a /= np.maximum(cos_el, dt.type(1e-6))
        return np.maximum(a, dt.type(10.0 ** (self.floor_dbi / 20.0)), out=a)


@dataclass(frozen=True, eq=False)
class TabulatedPattern(Pattern):
    """Gain (dBi) on an elevation x azimuth grid (degrees), bilinear in dB, periodic in azimuth."""

    el_deg: NDArray[np.float64]
    az_deg: NDArray[np.float64]
    gain: NDArray[np.float64]  # (len(el_deg), len(az_deg)), dBi
    name: str = "tabulated"
    note: str = ""
    floor_dbi: float = GAIN_FLOOR_DBI
    _az_ext: NDArray = field(init=False, repr=False)
    _gain_ext: NDArray = field(init=False, repr=False)
    _uniform: tuple | None = field(init=False, repr=False)

    def __post_init__(self) -> None:
        el = np.asarray(self.el_deg, dtype=float)
        az = np.asarray(self.az_deg, dtype=float)
        g = np.asarray(self.gain, dtype=float)
        if el.ndim != 1 or az.ndim != 1 or g.shape != (el.size, az.size):
            raise ValueError(f"gain must be ({el.size}, {az.size}), got {g.shape}")
        if el.size < 2 or np.any(np.diff(el) <= 0) or el[0] < -90 - 1e-9 or el[-1] > 90 + 1e-9:
            raise ValueError("elevations must be >= 2, strictly ascending, within [-90, 90] deg")
        if az.size < 2 or np.any(np.diff(az) <= 0) or az[-1] - az[0] >= 360:
            raise ValueError("azimuths must be >= 2, strictly ascending and span less than 360 deg")
        if not np.all(np.isfinite(g)):
            raise ValueError("gains must be finite")
        object.__setattr__(self, "el_deg", el)
        object.__setattr__(self, "az_deg", az)
        object.__setattr__(self, "gain", g)
        object.__setattr__(self, "_az_ext", np.append(az, az[0] + 360.0))
        object.__setattr__(self, "_gain_ext", np.concatenate([g, g[:, :1]], axis=1))
        de, da = np.diff(el), np.diff(self._az_ext)
        uniform = None
        if np.allclose(de, de[0]) and np.allclose(da, da[0]):
            table = np.maximum(self._gain_ext, self.floor_dbi).astype(np.float32).ravel()
            uniform = ((el[0], de[0], el.size), (az[0], da[0], az.size), table)
        object.__setattr__(self, "_uniform", uniform)

    def gain_dbi(self, el: ArrayLike, az: ArrayLike) -> NDArray[np.float64]:
        """Bilinear interpolation in (el, az) (rad), periodic in az, el clamped to the table."""
        e = np.clip(np.degrees(np.asarray(el, dtype=float)), self.el_deg[0], self.el_deg[-1])
        a0 = self._az_ext[0]
        a = np.mod(np.degrees(np.asarray(az, dtype=float)) - a0, 360.0) + a0
        e, a = np.broadcast_arrays(e, a)
        i = np.clip(np.searchsorted(self.el_deg, e, side="right") - 1, 0, self.el_deg.size - 2)
        j = np.clip(np.searchsorted(self._az_ext, a, side="right") - 1, 0, self.az_deg.size - 1)
        u = (e - self.el_deg[i]) / (self.el_deg[i + 1] - self.el_deg[i])
        t = (a - self._az_ext[j]) / (self._az_ext[j + 1] - self._az_ext[j])
        G = self._gain_ext
        g = ((1 - u) * ((1 - t) * G[i, j] + t * G[i, j + 1])
             + u * ((1 - t) * G[i + 1, j] + t * G[i + 1, j + 1]))
        return np.maximum(g, self.floor_dbi)

    def amplitude_at(self, el: NDArray, az: NDArray) -> NDArray:
        """sqrt(G) at antenna-frame angles (rad); uniform grids index directly (no search), in el's dtype."""
        if self._uniform is None:
            g = self.gain_dbi(el, az)
            return np.exp(g * (np.log(10.0) / 20.0)).astype(np.result_type(el), copy=False)
        g = self.gain_db_at(el, az)
        g *= np.result_type(el).type(np.log(10.0) / 20.0)  # table is dB; floor applied at build time
        return np.exp(g, out=g)

    def gain_db_at(self, el: NDArray, az: NDArray) -> NDArray:
        """Gain (dBi) at antenna-frame angles (rad) in el's dtype: the fast path of ``gain_dbi`` (bilinear on
        uniform tables without a search; the float64 reference otherwise)."""
        if self._uniform is None:
            return self.gain_dbi(el, az).astype(np.result_type(el), copy=False)
        dt = np.result_type(el).type
        (e0, de, ne), (a0, da, na), table = self._uniform
        fe = np.clip((el * dt(180.0 / np.pi) - dt(e0)) * dt(1.0 / de), dt(0.0), dt(ne - 1))
        fa = np.mod(az * dt(180.0 / np.pi) - dt(a0), dt(360.0)) * dt(1.0 / da)
        i = np.minimum(fe.astype(np.int32), ne - 2)
        j = np.minimum(fa.astype(np.int32), na - 1)
        u = fe - i
        t = fa - j
        k = i * (na + 1) + j  # index into the (ne, na + 1) table with the wrap column
        g00, g01 = table[k], table[k + 1]
        g10, g11 = table[k + (na + 1)], table[k + (na + 2)]
        g = g00 + t * (g01 - g00)
        g += u * (g10 + t * (g11 - g10) - g)
        return g

    def total_power_ratio(self) -> float:
        """(1 / 4 pi) * integral of G over the sphere on the table's own grid (1 for a directivity table)."""
        return sphere_integral(self.el_deg, self.az_deg, 10.0 ** (self.gain / 10.0)) / (4.0 * np.pi)

    def peak_dbi(self) -> float:
        return float(self.gain.max())


@dataclass(frozen=True)
class Mounted(Pattern):
    """A pattern mounted on a platform with a heading offset and optionally upside down.

    ``gain_dbi(el_p, az_p)`` takes platform angles (see the module docstring and :func:`mount_angles`).
    """

    pattern: Pattern = field(default_factory=Isotropic)
    heading_rad: float = 0.0
    flipped: bool = False

    @property
    def name(self) -> str:  # type: ignore[override]
        return self.pattern.name + (" (flipped)" if self.flipped else "")

    def gain_dbi(self, el: ArrayLike, az: ArrayLike) -> NDArray[np.float64]:
        el_a, az_a = mount_angles(el, az, self.heading_rad, self.flipped)
        return self.pattern.gain_dbi(el_a, az_a)


# --------------------------------------------------------------------------------------------- files


def sphere_integral(el_deg: NDArray, az_deg: NDArray, f: NDArray) -> float:
    """Integral of f(el, az) dOmega over the sphere (dOmega = cos el d_el d_az): trapezoid in el, rectangle
    in the periodic az (exact for a full uniform az grid)."""
    el = np.radians(el_deg)
    az = np.radians(np.append(az_deg, az_deg[0] + 360.0))
    w_az = np.diff(az)  # each column owns the interval to its successor
    ring = np.trapezoid(f * np.cos(el)[:, None], el, axis=0)
    return float(np.sum(ring * w_az))


def load_pattern_csv(path: str | Path, name: str | None = None) -> TabulatedPattern:
    """Read a tabulated pattern in the module's CSV format; bad input raises InputError (file, row)."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as e:
        raise InputError(f"cannot read antenna pattern: {e.strerror or e}", source=str(path)) from None
    header: list[float] | None = None
    els: list[float] = []
    rows: list[list[float]] = []
    notes: list[str] = []
    for lineno, line in enumerate(text.splitlines(), start=1):
        s = line.strip()
        if not s:
            continue
        if s.startswith("#"):
            notes.append(s.lstrip("# "))
            continue
        cells = [c.strip() for c in s.split(",")]
        if header is None:
            try:
                header = [float(c) for c in cells[1:]]
            except ValueError:
                raise InputError("header must be a label then azimuths in degrees", source=str(path),
                                 row=lineno) from None
            if len(header) < 2:
                raise InputError("need at least 2 azimuth columns", source=str(path), row=lineno)
            continue
        if len(cells) != len(header) + 1:
            raise InputError(f"expected {len(header) + 1} cells (elevation + {len(header)} gains), "
                             f"got {len(cells)}", source=str(path), row=lineno)
        try:
            vals = [float(c) for c in cells]
        except ValueError:
            raise InputError("non-numeric value", source=str(path), row=lineno) from None
        if not all(math.isfinite(v) for v in vals):
            raise InputError("non-finite value", source=str(path), row=lineno)
        if els and vals[0] <= els[-1]:
            raise InputError("elevations must be strictly ascending", source=str(path), row=lineno,
                             field="elevation")
        if not -90.0 <= vals[0] <= 90.0:
            raise InputError("elevation must be within [-90, 90] deg", source=str(path), row=lineno,
                             field="elevation")
        els.append(vals[0])
        rows.append(vals[1:])
    if header is None or len(els) < 2:
        raise InputError("need a header row and at least 2 elevation rows", source=str(path))
    az = np.asarray(header)
    if np.any(np.diff(az) <= 0) or az[-1] - az[0] >= 360.0:
        raise InputError("azimuths must be strictly ascending and distinct modulo 360", source=str(path),
                         row=None, field="azimuth")
    return TabulatedPattern(np.asarray(els), az, np.asarray(rows), name=name or path.stem,
                            note="; ".join(notes))


def save_pattern_csv(pattern: TabulatedPattern, path: str | Path, comments: tuple[str, ...] = ()) -> None:
    """Write a tabulated pattern in the module's CSV format (gains to 0.01 dB)."""
    lines = [f"# {c}" for c in comments]
    lines.append("el\\az," + ",".join(f"{a:g}" for a in pattern.az_deg))
    for e, row in zip(pattern.el_deg, pattern.gain, strict=True):
        lines.append(f"{e:g}," + ",".join(f"{v:.2f}" for v in row))
    Path(path).write_text("\n".join(lines) + "\n", encoding="utf-8")


def load_aerpaw_pattern(path: str | Path, name: str | None = None) -> TabulatedPattern:
    """Read a measured AERPAW pattern file (see module docstring), normalised to directivity (dBi)."""
    path = Path(path)
    try:
        lines = path.read_text(encoding="utf-8", errors="replace").splitlines()
    except OSError as e:
        raise InputError(f"cannot read antenna pattern: {e.strerror or e}", source=str(path)) from None
    start = next((k for k, s in enumerate(lines) if s.strip().lower().startswith("phi")), None)
    if start is None:
        raise InputError("no 'Phi Theta ...' header line: not an AERPAW pattern file", source=str(path))
    data = []
    for lineno, s in enumerate(lines[start + 1:], start=start + 2):
        if not s.strip():
            continue
        try:
            vals = [float(c) for c in s.split()[:3]]
        except ValueError:
            raise InputError("non-numeric value", source=str(path), row=lineno) from None
        if len(vals) < 3:
            raise InputError("expected Phi, Theta, ETotal_dB", source=str(path), row=lineno)
        data.append(vals)
    a = np.asarray(data)
    phi = np.round(np.degrees(a[:, 0]), 6)
    theta = np.round(np.degrees(a[:, 1]), 6)
    P, T = np.unique(phi), np.unique(theta)
    if a.shape[0] != P.size * T.size or not np.allclose(T, -T[::-1]) or T.min() > -179.999:
        raise InputError("expected a full Phi x Theta grid with Theta symmetric over [-180, 180]",
                         source=str(path))
    dphi = np.diff(P)
    if not np.allclose(dphi, dphi[0]) or not np.isclose(P[-1] + dphi[0], 180.0):
        raise InputError("expected Phi uniform over [0, 180)", source=str(path))
    E = np.full((P.size, T.size), np.nan)
    E[np.searchsorted(P, phi), np.searchsorted(T, theta)] = a[:, 2]
    Tpos = T[T >= 0]  # 0 .. 180
    el = 90.0 - Tpos[::-1]  # -90 .. 90 ascending
    it_pos = np.searchsorted(T, Tpos[::-1])  # Theta = 90 - el
    it_neg = np.searchsorted(T, -Tpos[::-1])  # Theta = -(90 - el): the half-plane Phi + 180
    az = np.concatenate([P, P + 180.0])
    g = np.concatenate([E[:, it_pos].T, E[:, it_neg].T], axis=1)  # (el, az)
    # directivity normalisation: (1 / 4 pi) * integral of 10^(g/10) dOmega = 1
    offset = 10.0 * np.log10(4.0 * np.pi / sphere_integral(el, az, 10.0 ** (g / 10.0)))
    return TabulatedPattern(el, az, g + offset, name=name or path.stem,
                            note=f"{path.name}: ETotal_dB + {offset:.3f} dB (directivity by integration)")


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
        raise InputError("antenna pattern file not found (or use isotropic, dipole, measured)",
                         source=str(path))
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

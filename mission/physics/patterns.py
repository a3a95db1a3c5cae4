"""Antenna gain patterns as objects: isotropic, vertical half-wave dipole, tabulated 3D (measured),
mounting.

Antenna frame
-------------
Every pattern is a function of direction in the antenna's own right-handed frame: ``z_a`` is the
antenna's "up" (its axis, pointing away from its mounting base when right side up), elevation ``el``
is measured from the antenna's horizontal plane (positive towards ``z_a``) and azimuth ``az`` is
counter-clockwise from ``x_a`` seen from above (the usual spherical convention of a chamber
measurement). Angles are radians in code, degrees in files.

Mounting (:func:`mount_angles`) maps a platform's angles to the antenna frame. Platform angles are
``el_p`` (up-positive elevation of the platform's level/body plane) and ``az_p`` clockwise from the
platform's forward direction (the body azimuth ``az_b`` for the UAV, the compass bearing for the
rover). ``heading_rad`` turns the antenna's ``x_a`` clockwise from forward; ``flipped`` mounts it
upside down (a 180 degree turn about ``x_a``): upright ``el_a = el_p, az_a = -(az_p - heading)``;
flipped ``el_a = -el_p, az_a = az_p - heading``.

Files (CSV, measured AERPAW) are read in ``mission.physics.pattern_files``; patterns by name and the
shipped measured pattern in ``mission.physics.antenna``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mission.physics.constants import DIPOLE_G0, GAIN_FLOOR_DBI

TWO_PI = 2.0 * np.pi


def mount_angles(
    el_p: ArrayLike, az_p: ArrayLike, heading_rad: float = 0.0, flipped: bool = False
) -> tuple[NDArray, NDArray]:
    """Platform angles (el up-positive, az clockwise from forward) -> antenna-frame (el_a, az_a),
    rad."""
    el_p = np.asarray(el_p)
    az_p = np.asarray(az_p)
    if flipped:  # 180 deg about x_a: (x, y, z) -> (x, -y, -z)
        return -el_p, np.mod(az_p - heading_rad, TWO_PI)
    return el_p, np.mod(heading_rad - az_p, TWO_PI)


class Pattern:
    """Base class: gain of an antenna in its own frame.

    ``gain_dbi(el, az)`` is the reference (angles in rad, float64); ``amplitude(sin_el, cos_el,
    az)`` is the fast path used by the propagation kernel: sqrt of the linear gain, dtype preserved.
    ``az`` is only computed by the caller when ``azimuth_symmetric`` is False.
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

    ``g0`` = 1.641 (2.15 dBi at el = 0); the axial limit (el = +-90 deg) is 0, floored at
    ``floor_dbi``.
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
        g = (1 - u) * ((1 - t) * G[i, j] + t * G[i, j + 1]) + u * (
            (1 - t) * G[i + 1, j] + t * G[i + 1, j + 1]
        )
        return np.maximum(g, self.floor_dbi)

    def amplitude_at(self, el: NDArray, az: NDArray) -> NDArray:
        """sqrt(G) at antenna-frame angles (rad); uniform grids index directly (no search), in el's
        dtype."""
        if self._uniform is None:
            g = self.gain_dbi(el, az)
            return np.exp(g * (np.log(10.0) / 20.0)).astype(np.result_type(el), copy=False)
        g = self.gain_db_at(el, az)
        # table is dB; floor applied at build time
        g *= np.result_type(el).type(np.log(10.0) / 20.0)
        return np.exp(g, out=g)

    def gain_db_at(self, el: NDArray, az: NDArray) -> NDArray:
        """Gain (dBi) at antenna-frame angles (rad) in el's dtype: the fast path of ``gain_dbi``
        (bilinear on uniform tables without a search; the float64 reference otherwise)."""
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
        """(1 / 4 pi) * integral of G over the sphere on the table's own grid (1 for a directivity
        table)."""
        return sphere_integral(self.el_deg, self.az_deg, 10.0 ** (self.gain / 10.0)) / (4.0 * np.pi)

    def peak_dbi(self) -> float:
        return float(self.gain.max())


@dataclass(frozen=True)
class Mounted(Pattern):
    """A pattern mounted on a platform with a heading offset and optionally upside down.

    ``gain_dbi(el_p, az_p)`` takes platform angles (see the module docstring and
    :func:`mount_angles`).
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


def sphere_integral(el_deg: NDArray, az_deg: NDArray, f: NDArray) -> float:
    """Integral of f(el, az) dOmega over the sphere (dOmega = cos el d_el d_az): trapezoid in el,
    rectangle in the periodic az (exact for a full uniform az grid)."""
    el = np.radians(el_deg)
    az = np.radians(np.append(az_deg, az_deg[0] + 360.0))
    w_az = np.diff(az)  # each column owns the interval to its successor
    ring = np.trapezoid(f * np.cos(el)[:, None], el, axis=0)
    return float(np.sum(ring * w_az))

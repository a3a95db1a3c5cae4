"""The effects a propagation model is built from (SPEC section 3, paper eqs. 1-9); the catalogue is
in ``mission.physics.propagation``'s docstring.

Each effect is a frozen dataclass whose fields are its parameters (so a model can swap or refit
one). The direct ray, ground ray and antennas are evaluated inside ``PropagationModel``
(``mission.physics.model``); any effect with ``rss_term_db(link: Link) -> array`` adds dB to the RSS
and plugs in without kernel changes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, ClassVar, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mission.physics.antenna import Dipole, Pattern, mount_angles
from mission.physics.constants import (
    DEFAULT_BETA,
    DEFAULT_EPS_R,
    DEFAULT_FC_HZ,
    DEFAULT_PT_DBM,
    DEFAULT_SIGMA_S_M,
    EPSILON_0,
    LEG_AZIMUTHS_DEG,
    LEG_DEPRESSION_THRESHOLD_DEG,
    LEG_HALF_WIDTH_DEG,
    SHADOW_D0_M,
)

TWO_PI = 2.0 * np.pi


class Effect(Protocol):
    name: str


@dataclass(frozen=True)
class FreeSpace:
    """Direct ray with Friis spreading: P_t + 20 log10(lambda / (4 pi d_los)) (+ antenna gains)."""

    pt_dbm: float = DEFAULT_PT_DBM  # P_t
    fc_hz: float = DEFAULT_FC_HZ  # f_c
    name: ClassVar[str] = "free_space"


@dataclass(frozen=True)
class GroundReflection:
    """Flat-ground reflected ray (paper eq. 1) with the Fresnel coefficient Gamma(grazing angle
    psi).

    Ground: relative permittivity ``eps_r``, conductivity ``sigma_s_m`` (complex permittivity
    eps = eps_r - j sigma / (omega eps_0)); ``polarization`` "V" (vertical, default) or "H".
    """

    eps_r: float = DEFAULT_EPS_R
    sigma_s_m: float = DEFAULT_SIGMA_S_M
    polarization: str = "V"
    name: ClassVar[str] = "ground_reflection"

    def __post_init__(self) -> None:
        if self.polarization.upper() not in ("V", "H"):
            raise ValueError(f"polarization must be 'V' or 'H', got {self.polarization!r}")

    def eps_complex(self, fc_hz: float) -> complex:
        """eps = eps_r - j sigma / (omega eps_0)."""
        return complex(self.eps_r, -self.sigma_s_m / (TWO_PI * fc_hz * EPSILON_0))

    def gamma(self, psi: ArrayLike, fc_hz: float) -> NDArray[np.complex128]:
        """Fresnel reflection coefficient at grazing angle psi (rad), reference implementation."""
        psi = np.asarray(psi, dtype=float)
        eps = self.eps_complex(fc_hz)
        root = np.sqrt(eps - np.cos(psi) ** 2 + 0j)
        s = np.sin(psi)
        if self.polarization.upper() == "V":
            return (eps * s - root) / (eps * s + root)
        return (s - root) / (s + root)

    def _gamma_fast(
        self, sin_psi: NDArray, cos2_psi: NDArray, fc_hz: float
    ) -> tuple[NDArray, NDArray | None]:
        """(Re Gamma, Im Gamma or None) from sin psi and cos^2 psi, no trig; real arithmetic if
        sigma = 0."""
        dt = np.result_type(sin_psi)
        eps = self.eps_complex(fc_hz)
        vertical = self.polarization.upper() == "V"
        if eps.imag == 0.0 and eps.real >= 1.0:
            e = dt.type(eps.real)
            root = np.sqrt(e - cos2_psi)
            num = e * sin_psi if vertical else sin_psi.copy()
            return (num - root) / (num + root), None
        ce = np.complex64(eps) if dt == np.float32 else np.complex128(eps)
        root = np.sqrt(ce - cos2_psi)
        num = ce * sin_psi if vertical else sin_psi.astype(root.dtype)
        g = (num - root) / (num + root)
        return g.real.astype(dt), g.imag.astype(dt)


@dataclass(frozen=True)
class _AntennaEffect:
    pattern: Pattern = field(default_factory=Dipole)
    heading_rad: float = 0.0  # antenna x_a clockwise from the platform's forward
    flipped: bool = False  # mounted upside down (180 deg about x_a)

    def _amplitude(self, sin_el: NDArray, cos_el: NDArray, az_p: Any) -> NDArray:
        """sqrt(G) for platform angles given as sin/cos of elevation and a lazy platform azimuth."""
        p = self.pattern
        if p.azimuth_symmetric:
            s = -sin_el if (self.flipped and not p.elevation_symmetric) else sin_el
            return p.amplitude(s, cos_el, None)
        el_p = np.arctan2(sin_el, cos_el)
        el_a, az_a = mount_angles(el_p, az_p(), self.heading_rad, self.flipped)
        return p.amplitude_at(el_a, az_a)

    def gain_dbi(self, el_p: ArrayLike, az_p: ArrayLike) -> NDArray[np.float64]:
        """Reference gain at platform angles (rad)."""
        el_a, az_a = mount_angles(el_p, az_p, self.heading_rad, self.flipped)
        return self.pattern.gain_dbi(el_a, az_a)


@dataclass(frozen=True)
class TxAntenna(_AntennaEffect):
    """Transmitter pattern; platform = rover, level, forward = north (``heading_rad`` = rover
    heading)."""

    name: ClassVar[str] = "tx_antenna"


@dataclass(frozen=True)
class RxAntenna(_AntennaEffect):
    """Receiver pattern on the UAV: antenna up = -z_b, x_a = nose turned by ``heading_rad``; el =
    -dep_b."""

    name: ClassVar[str] = "rx_antenna"


@dataclass(frozen=True)
class Attitude:
    """Take the receiver's gains (and shadowing) in the body frame given by the sample's
    roll/pitch/yaw.

    ``roll_pitch=False`` keeps only the yaw (heading) and treats the body as level: on the real AFAR
    flights the logged roll/pitch (a few degrees; their signs checked against the flight dynamics)
    make the held-out fit of the measured UAV pattern worse while the yaw improves it
    (``benchmarks/calibrate_real_afar.py``).
    """

    roll_pitch: bool = True
    name: ClassVar[str] = "attitude"

    def apply(self, att: NDArray) -> NDArray:
        """The (N, 3) attitude this effect uses: as given, or roll = pitch = 0."""
        return att if self.roll_pitch else att * np.array([0.0, 0.0, 1.0])


@dataclass(frozen=True)
class LegShadowing:
    """Leg shadowing (eqs. 8-9): S = 1 when az_b is within ``half_width_deg`` of a leg and dep_b <
    threshold; then the RSS loses Upsilon = 10 beta log10(d_los / d0)."""

    beta: float = DEFAULT_BETA
    legs_deg: tuple[float, ...] = LEG_AZIMUTHS_DEG
    half_width_deg: float = LEG_HALF_WIDTH_DEG
    threshold_deg: float = LEG_DEPRESSION_THRESHOLD_DEG
    d0_m: float = SHADOW_D0_M
    name: ClassVar[str] = "leg_shadowing"

    def shadowed(self, az_b: ArrayLike, dep_b: ArrayLike) -> NDArray[np.bool_]:
        """S from body angles (rad), reference (eq. 9)."""
        az = np.degrees(np.asarray(az_b, dtype=float))
        S = np.zeros(np.shape(az), dtype=bool)
        for psi_l in self.legs_deg:
            off = np.abs((az - psi_l + 180.0) % 360.0 - 180.0)
            S |= off <= self.half_width_deg
        return S & (np.degrees(np.asarray(dep_b, dtype=float)) < self.threshold_deg)

    def upsilon_db(self, d_los: ArrayLike) -> NDArray:
        """Upsilon = 10 beta log10(d_los / d0) (eq. 8)."""
        return 10.0 * self.beta * np.log10(np.asarray(d_los) / self.d0_m)

    def rss_term_db(self, link: Link) -> NDArray:
        """-S * Upsilon, from body-frame components without trig: cos(az_b - psi_l) >= cos Delta."""
        dt = link.d_los.dtype.type
        ubx, uby, ubz = link.u_b
        h = np.sqrt(ubx * ubx + uby * uby)
        h *= dt(math.cos(math.radians(self.half_width_deg)))
        S = np.zeros(ubx.shape, dtype=bool)
        for psi_l in self.legs_deg:
            c, s = math.cos(math.radians(psi_l)), math.sin(math.radians(psi_l))
            S |= ubx * dt(c) + uby * dt(s) >= h
        S &= ubz < link.d_los * dt(math.sin(math.radians(self.threshold_deg)))  # dep_b < delta
        term = np.zeros_like(link.d_los)
        if S.any():
            np.log(link.d_los, out=term, where=S)
            term *= dt(-10.0 * self.beta / math.log(10.0))
            term += dt(10.0 * self.beta * math.log10(self.d0_m)) * S
        return term


@dataclass(frozen=True)
class PathGainSlope:
    """Extra distance exponent: adds ``-10 n_extra log10(d_los / d_ref_m)`` dB to the RSS.

    Free space falls 20 dB/decade; with this effect the model falls ``10 (2 + n_extra)`` dB/decade.
    The reference distance only moves a constant (absorbed by the free offset of an uncalibrated
    receiver). An empirical term (not in the paper): the real AFAR flights fall faster with distance
    than any of the paper's effects explain (``rfsl gap``; ``benchmarks/calibrate_real_afar.py``).
    """

    n_extra: float = 0.0
    d_ref_m: float = 1.0
    name: ClassVar[str] = "path_gain_slope"

    def rss_term_db(self, link: Link) -> NDArray:
        dt = link.d_los.dtype.type
        term = np.log(link.d_los)
        term *= dt(-10.0 * self.n_extra / math.log(10.0))
        term += dt(10.0 * self.n_extra * math.log10(self.d_ref_m))
        return term


@dataclass
class Link:
    """Per-block fast-path geometry handed to ``rss_term_db`` effects (arrays of one block, model
    dtype).

    ``delta`` = p_tx - p_rx (ENU), ``d_los``, ``d_ref``, ``u_b`` = (x, y, z) of the direct LOS in
    the body frame (FRD; level frame with yaw 0 without the attitude effect).
    """

    delta: tuple[NDArray, NDArray, NDArray]
    z_t: NDArray
    z_r: NDArray
    d_los: NDArray
    d_ref: NDArray
    u_b: tuple[NDArray, NDArray, NDArray]

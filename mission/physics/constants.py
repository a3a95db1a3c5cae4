"""Physical constants and the paper's default link parameters (SPEC section 2), in SI units."""

from __future__ import annotations

import math

SPEED_OF_LIGHT = 299_792_458.0  # c, m/s
EPSILON_0 = 8.8541878128e-12  # vacuum permittivity, F/m

DEFAULT_PT_DBM = 41.0  # P_t, transmit power (paper, "Numerical Results")
DEFAULT_FC_HZ = 3.32e9  # f_c, carrier frequency
DEFAULT_EPS_R = 2.0  # ground relative permittivity
DEFAULT_SIGMA_S_M = 0.0  # ground conductivity, S/m

DIPOLE_G0 = 1.641  # peak gain of a half-wave dipole, linear (2.15 dBi)
GAIN_FLOOR_DBI = -40.0  # no pattern returns less (avoids -inf at nulls)

LEG_AZIMUTHS_DEG = (39.0, 150.0, 270.0)  # psi_l, body frame, clockwise from the nose
LEG_HALF_WIDTH_DEG = 5.0  # Delta
LEG_DEPRESSION_THRESHOLD_DEG = 10.0  # delta: shadowed only when dep_b < delta
DEFAULT_BETA = 2.0  # shadowing exponent beta (fitted downstream; 2 = a free-space-like extra loss)
SHADOW_D0_M = 1.0  # d_0, reference distance of Upsilon


def wavelength(fc_hz: float) -> float:
    """lambda = c / f_c (m)."""
    return SPEED_OF_LIGHT / fc_hz


def friis_constant_db(fc_hz: float) -> float:
    """20 log10(lambda / (4 pi)): the free-space term without distance (dB)."""
    return 20.0 * math.log10(wavelength(fc_hz) / (4.0 * math.pi))

"""Defaults that several parts of the package share, each in one place; no imports, so the command lines can
show them in ``--help`` without loading numpy."""

# The transmitter's antenna height above ground when nothing says otherwise: the AFAR rover's antenna stands
# about 1.5 m above the field (../shared/data/README.md); the paper's transmitter stands at 5 m.
DEFAULT_TX_HEIGHT_M = 1.5

# A mission's cruise altitude above the origin's ground when its file gives none (``MissionSpec.altitude_m``;
# also what a sidecar's trajectory record without an altitude was planned at).
DEFAULT_ALTITUDE_M = 30.0

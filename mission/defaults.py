"""Defaults that several parts of the package share, each in one place; no imports, so the command lines can
show them in ``--help`` without loading numpy."""

# The transmitter's antenna height above ground when nothing says otherwise: the AFAR rover's antenna stands
# about 1.5 m above the field (../shared/data/README.md); the paper's transmitter stands at 5 m.
DEFAULT_TX_HEIGHT_M = 1.5

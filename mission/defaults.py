"""Defaults that several parts of the package share, each in one place; no imports, so the command lines can
show them in ``--help`` without loading numpy."""

# The transmitter's antenna height above ground when nothing says otherwise: the AFAR rover's antenna stands
# about 1.5 m above the field (../shared/data/README.md); the paper's transmitter stands at 5 m.
DEFAULT_TX_HEIGHT_M = 1.5

# What a flight does when its predicted landing passes the time budget less its reserve (mission key
# ``budget_policy``, ``mission.flight.budget``): drop the mission's tail, only warn, or return at once.
BUDGET_POLICIES = ("trim", "warn", "return")

"""Defaults that several parts of the package share, each in one place; no imports, so the command
lines can show them in ``--help`` without loading numpy."""

# The transmitter's antenna height above ground when nothing says otherwise: the AFAR rover's
# antenna stands about 1.5 m above the field (../shared/data/README.md); the paper's transmitter
# stands at 5 m.
DEFAULT_TX_HEIGHT_M = 1.5

# Bounds of the options that size the work: past them a run never ends or exhausts memory (issue 37:
# a speed-up of 1e9 or nan, a billion dataset flights), so every command and mission key refuses
# them in one line.
# the built-in vehicle's simulated seconds per wall-clock second (fly-mission, rfsl sitl)
MAX_SPEEDUP = 1000.0
MAX_RATE_HZ = 1000.0  # position/attitude rate a flight may request
MAX_DURATION_S = 86400.0  # one day: any timeout or duration a command accepts
MAX_WORKERS = (
    256  # processes or threads a command may start (--workers 100000 would fork that many)
)
# What a flight does when its predicted landing passes the time budget less its reserve (mission key
# ``budget_policy``, ``mission.flight.budget``): drop the mission's tail, only warn, or return at
# once.
BUDGET_POLICIES = ("trim", "warn", "return")
# A mission's cruise altitude above the origin's ground when its file gives none
# (``MissionSpec.altitude_m``; also what a sidecar's trajectory record without an altitude was
# planned at).
DEFAULT_ALTITUDE_M = 30.0

"""The flight-log format: one CSV per flight plus a JSON sidecar, written and read only here.

CSV columns (``SPEC.md``): ``t_s, lat_deg, lon_deg, alt_m, rel_alt_m, roll_deg, pitch_deg, yaw_deg,
rss_dbm``.  Attitude may be empty (a receiver-only log).  Extra columns are kept, missing required
ones are refused.  The sidecar ``<name>.json`` beside the CSV holds the mission origin, the RSS
source (simulated: model and seed; or a real receiver, whose dB are not calibrated dBm), the
software version and, for simulated flights, the true transmitter position.

``schema.py``: column names, ``FlightLog`` (a log in memory; ``.samples()`` its ``FlightSamples``
view), ``make_meta``; ``read.py``: ``read_flight_log`` and its validation; ``write.py``:
``FlightLogWriter``, ``write_flight_log``, ``rounded``.
"""

from mission.flightlog.read import read_flight_log
from mission.flightlog.schema import (
    ADAPTIVE,
    COLUMNS,
    FLOWN_PHASES,
    GROUND,
    LAND,
    MISSION,
    OPTIONAL,
    PHASE_COLUMNS,
    PHASES,
    REQUIRED,
    RETURN,
    TAKEOFF,
    WARNING,
    FlightLog,
    make_meta,
    sidecar_path,
)
from mission.flightlog.write import (
    DEFAULT_DIGITS,
    DIGITS,
    FlightLogWriter,
    format_rows,
    rounded,
    write_flight_log,
)

__all__ = [
    "ADAPTIVE",
    "COLUMNS",
    "DEFAULT_DIGITS",
    "DIGITS",
    "FLOWN_PHASES",
    "GROUND",
    "LAND",
    "MISSION",
    "OPTIONAL",
    "PHASES",
    "PHASE_COLUMNS",
    "REQUIRED",
    "RETURN",
    "TAKEOFF",
    "WARNING",
    "FlightLog",
    "FlightLogWriter",
    "format_rows",
    "make_meta",
    "read_flight_log",
    "rounded",
    "sidecar_path",
    "write_flight_log",
]

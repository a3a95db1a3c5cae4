"""The flight: fly a mission on a MAVLink autopilot through MAVSDK, sample RSS, log it, localize.

Modules: ``runner`` (the order of a flight: check, connect, upload, arm, fly, return, land, close;
one task group), ``context`` (``FlightContext``: the state every coroutine shares; exit codes; the
``Extension`` protocol), ``tasks`` (one coroutine per telemetry stream, signals, the watchdog, the
log writer), ``estimates`` (the live estimates of every flight) and ``live`` (the estimate at log
time T), ``preflight`` (option checks before anything starts), ``vehicle_process`` (the built-in
simulated vehicle as a child that dies with its parent), ``plan`` (the mission items as MAVSDK
uploads them, the upload with retries), ``ardupilot`` (return nose first at mission speed),
``telemetry`` (time-stamped position/attitude on the vehicle's clock, measured speed-up and rates),
``phases`` (mission phase over time), ``logrows`` (RSS rows joined with telemetry and phase,
appended), ``sources`` (RSS sources behind one interface: sim, aerpaw-fifo, udp), ``sdklog``
(MAVSDK's own messages, once each), ``progress`` (the live display).
"""

"""The flight runner: fly a mission on a MAVLink autopilot through MAVSDK, sample RSS, log it, localize.

Modules: ``telemetry`` (time-stamped position/attitude buffers on the vehicle's clock, interpolation),
``sources`` (RSS sources behind one interface: sim, aerpaw-fifo, udp), ``plan`` (the raw MAVLink mission),
``progress`` (the live display), ``runner`` (the asyncio tasks, aborts and the embedded simulated vehicle).
"""

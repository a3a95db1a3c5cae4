"""Live estimates during a flight and the adaptive finish.

``config``: the mission's ``adaptive:`` block and its pre-flight checks; ``planner``: the survey cut and the
legs planned from the live posterior, checked against fence, altitude limits and time budget; ``live``: the
estimate a flight has at a time (in flight and ``localize --at``); ``runner``: the flight runner with live
estimates and adaptive rounds; ``simflight``: the same flight on the fast simulator (benchmark, preview).
"""

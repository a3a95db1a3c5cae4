"""The adaptive finish of a flight.

``config``: the mission's ``adaptive:`` block and its pre-flight checks; ``planner``: the survey cut
and the legs planned from the live posterior, checked against fence, altitude limits and time
budget; ``rounds``: the flight's extension that flies them (``AdaptiveRounds``); ``simflight``: the
same flight on the fast simulator (benchmark, preview).  The live estimates every flight has live in
``mission.flight.estimates``.
"""

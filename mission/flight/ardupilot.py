"""ArduPilot parameters that make its return leg look like the mission: nose first, at the mission's
speed.

Why: ArduCopter keeps its last heading on RTL (``WP_YAW_BEHAVIOR`` 2, its default) and returns at
``WPNAV_SPEED`` (10 m/s in SITL), so the return leg of the AFAR-like spiral was flown backwards,
pitched up 22-24 deg for half a minute.  Before flight the runner sets ``WP_YAW_BEHAVIOR`` = 1 (face
the next waypoint, RTL included) and ``RTL_SPEED`` (cm/s) = the mission's cruise speed; both also
hold for an RTL commanded on Ctrl-C.  The previous values are restored after landing, so an
operator's vehicle keeps its settings.
"""

from __future__ import annotations

import asyncio

WP_YAW_FACE_NEXT_INCLUDING_RTL = 1
SET_TIMEOUT_S = 5.0


def return_params(cruise_speed_mps: float) -> dict[str, int]:
    """The integer parameters to set for a nose-first return at the mission's speed."""
    return {
        "WP_YAW_BEHAVIOR": WP_YAW_FACE_NEXT_INCLUDING_RTL,
        "RTL_SPEED": int(round(cruise_speed_mps * 100)),
    }


async def set_params(
    param, values: dict[str, int | float], old: dict[str, int | float] | None = None
) -> dict[str, int | float]:
    """Set parameters (an ``int`` value as an integer parameter, a ``float`` as a float one); the
    previous value of each one set goes into ``old`` as soon as it is set (so a failure half way
    still knows what to restore), which is returned.  Errors propagate."""
    old = {} if old is None else old
    for name, value in values.items():
        real = isinstance(value, float)
        get = param.get_param_float if real else param.get_param_int
        put = param.set_param_float if real else param.set_param_int
        raw = await asyncio.wait_for(get(name), SET_TIMEOUT_S)
        before = float(raw) if real else int(raw)
        if (abs(before - value) > 1e-4) if real else before != value:
            await asyncio.wait_for(put(name, value), SET_TIMEOUT_S)
            old[name] = before
    return old

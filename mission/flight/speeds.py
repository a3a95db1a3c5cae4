"""The autopilot's own speeds set to the mission's before flight and restored after it (ArduPilot
and PX4).

Why: a mission's time budget holds only if the vehicle flies the speed the plan assumes.  The
mission's speed item (``MAV_CMD_DO_CHANGE_SPEED``) covers the legs; the return to launch (commanded
at the end, on Ctrl-C or on a failure) is flown at the autopilot's own speed: ArduPilot's
``RTL_SPEED`` (cm/s; with ``WP_YAW_BEHAVIOR`` = 1 for a nose-first return, see
``mission.flight.ardupilot``), PX4's ``MPC_XY_CRUISE`` (m/s, 4.8 on a v1.16 SITL quad, where the
spiral's return took a tenth longer than planned).  The flight sets them before the upload and
restores the operator's values after landing.  If they cannot be set, the plan is redone with the
speed the autopilot will fly and a warning says whether it still fits.
"""

from __future__ import annotations

import asyncio

from mission.flight.ardupilot import return_params, set_params
from mission.trajectory.autopilot import VerticalSpeeds

PX4_CRUISE = "MPC_XY_CRUISE"


def speed_params(ardupilot: bool, cruise_speed_mps: float) -> dict[str, int | float]:
    """Parameters that make the autopilot return (and fly legs without a speed item) at the
    mission's speed."""
    if ardupilot:
        return return_params(cruise_speed_mps)
    return {PX4_CRUISE: float(cruise_speed_mps)}


async def _return_speed_now(param, ardupilot: bool) -> float | None:
    """The return speed the autopilot will fly with its own settings (m/s), None if it cannot be
    read."""
    try:
        if ardupilot:
            v = int(await asyncio.wait_for(param.get_param_int("RTL_SPEED"), 5.0))
            if v == 0:  # 0: ArduCopter returns at WPNAV_SPEED
                v = int(await asyncio.wait_for(param.get_param_int("WPNAV_SPEED"), 5.0))
            return v / 100.0
        return float(await asyncio.wait_for(param.get_param_float(PX4_CRUISE), 5.0))
    except Exception:
        return None


async def apply_speeds(ctx, param, ardupilot: bool) -> float | None:
    """Set the speed parameters (previous values into ``ctx.restore_params``); returns the return
    speed the autopilot will fly (m/s): the mission's when set, else its own (None when it cannot be
    read)."""
    cruise = ctx.spec.cruise_speed_mps
    values = speed_params(ardupilot, cruise)
    try:
        await set_params(param, values, ctx.restore_params)
    except Exception as e:
        ctx.event(
            "params",
            f"could not set {', '.join(values)} ({e or type(e).__name__}): return at the "
            "autopilot's own speed" + (", maybe tail first" if ardupilot else ""),
            warn=True,
        )
        return await _return_speed_now(param, ardupilot)
    what = (
        "return nose first at the mission's speed"
        if ardupilot
        else "cruise and return at the mission's speed"
    )
    ctx.event("params", f"{what}: " + ", ".join(f"{k}={v:g}" for k, v in values.items()))
    return cruise


async def _get(param, name: str) -> float:
    """A parameter's value whatever its type (ArduPilot mixes integer and float speeds)."""
    try:
        return float(await asyncio.wait_for(param.get_param_float(name), 5.0))
    except Exception:
        return float(await asyncio.wait_for(param.get_param_int(name), 5.0))


async def vertical_speeds(ctx, param, ardupilot: bool) -> VerticalSpeeds | None:
    """The autopilot's take-off and landing speeds and return altitude, read (not changed: they are
    the operator's safety settings): ArduPilot ``WPNAV_SPEED_UP``, ``LAND_SPEED_HIGH`` (0:
    ``WPNAV_SPEED_DN``), ``LAND_SPEED`` below ``LAND_ALT_LOW`` (cm/s, cm), the hover
    ``RTL_LOIT_TIME`` (ms), the return altitude ``RTL_ALT`` (cm); PX4 ``MPC_TKO_SPEED``,
    ``MPC_Z_V_AUTO_DN``, ``MPC_LAND_SPEED`` below ``MPC_LAND_ALT2`` (m/s, m), the hover
    ``RTL_LAND_DELAY`` (s), the return altitude ``RTL_RETURN_ALT`` (m; its cone near home, which
    lowers the climb there, is not modelled: the plan then errs long). None (and one line) when
    they cannot be read: the plan keeps the mission's."""
    try:
        if ardupilot:
            up, high, dn, land, low = [
                await _get(param, n) / 100.0
                for n in (
                    "WPNAV_SPEED_UP",
                    "LAND_SPEED_HIGH",
                    "WPNAV_SPEED_DN",
                    "LAND_SPEED",
                    "LAND_ALT_LOW",
                )
            ]
            hover = await _get(param, "RTL_LOIT_TIME") / 1000.0
            ret = await _get(param, "RTL_ALT") / 100.0
            v = VerticalSpeeds(up, high if high > 0 else dn, land, low, hover, ret)
        else:
            up, dn, land, low, delay, ret = [
                await _get(param, n)
                for n in (
                    "MPC_TKO_SPEED",
                    "MPC_Z_V_AUTO_DN",
                    "MPC_LAND_SPEED",
                    "MPC_LAND_ALT2",
                    "RTL_LAND_DELAY",
                    "RTL_RETURN_ALT",
                )
            ]
            # -1: hovers until told: not planned
            v = VerticalSpeeds(up, dn, land, low, max(delay, 0.0), ret)
    except Exception as e:
        ctx.event(
            "budget", f"climb and landing speeds not read ({e or type(e).__name__}): mission's used"
        )
        return None
    return v if v.valid() else None


async def restore_speeds(ctx, param) -> None:
    """Put back the parameters ``apply_speeds`` changed (not over a dead link)."""
    restore = ctx.restore_params
    if not restore or ctx.link_dead.is_set():
        return
    try:
        await set_params(param, restore)
        ctx.event("params", "restored " + ", ".join(f"{k}={v:g}" for k, v in restore.items()))
    except Exception as e:
        ctx.event("params", f"could not restore {restore} ({e})", warn=True)

"""Parameters of the simulated vehicle over the MAVLink parameter protocol (PARAM_REQUEST_READ/LIST,
PARAM_SET).

Why: the runner plans a flight with the speed the autopilot will fly and sets the autopilot's own
cruise and return speed for it (PX4: ``MPC_XY_CRUISE``, the speed of legs without a speed item and
of the return), restoring the operator's value afterwards; the simulated vehicle must answer that
the way PX4 does (``PARAM_VALUE`` with ``MAV_PARAM_TYPE_REAL32``, echoed after a set).  A mixin of
``sitl.vehicle.SimVehicle``.
"""

from __future__ import annotations

from sitl.protocol import mav

REAL32 = mav.MAV_PARAM_TYPE_REAL32


class ParamStore:
    """``self.params``: name -> float value (all REAL32, as PX4's speeds are), in a fixed order."""

    def param(self, name: str) -> float:
        return float(self.params[name])

    def _send_param(self, name: str, dest: tuple[int, int] | None = None) -> None:
        names = list(self.params)
        self.mav.param_value_send(
            name.encode(), float(self.params[name]), REAL32, len(names), names.index(name)
        )

    def on_param_message(self, msg) -> None:
        """PARAM_REQUEST_READ (by name or index), PARAM_REQUEST_LIST, PARAM_SET (echoes the stored
        value; an unknown name gets no answer, as on PX4, so the ground station times out)."""
        t = msg.get_type()
        names = list(self.params)
        if t == "PARAM_REQUEST_LIST":
            for n in names:
                self._send_param(n)
            return
        pid = (
            msg.param_id.rstrip("\x00")
            if isinstance(msg.param_id, str)
            else msg.param_id.decode().rstrip("\x00")
        )
        if t == "PARAM_REQUEST_READ":
            if msg.param_index >= 0 and not pid:
                if msg.param_index < len(names):
                    self._send_param(names[msg.param_index])
            elif pid in self.params:
                self._send_param(pid)
        elif t == "PARAM_SET" and pid in self.params:
            self.params[pid] = float(msg.param_value)
            self.log(f"param {pid} = {self.params[pid]:g}")
            self._send_param(pid)

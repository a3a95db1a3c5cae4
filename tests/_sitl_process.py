"""A real autopilot SITL from ../shared as a test sees it (``sitl.shared``): a start that fails the
test with the SITL's log, an instance search that skips when no ports are free.  Shared by the
ArduPilot and PX4 end-to-end tests."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from sitl.shared import SharedSitl, SitlStartError
from sitl.shared import free_instance as _free


def free_instance(
    lo: int, hi: int, ports: Callable[[int], tuple[int, ...]], udp: bool, what: str
) -> int:
    """``sitl.shared.free_instance``; skip when no instance is free."""
    i = _free(lo, hi, ports, udp)
    if i is None:
        pytest.skip(f"no free {what} instance ports")
    return i


class SitlProcess(SharedSitl):
    """One SITL process in its own run folder (``run``, below the test's ``root``)."""

    def __init__(self, root: Path):
        super().__init__(root)
        self.root, self.url = root, ""

    def launch(self, script: Path, args: list[str], ready: str, what: str) -> int:
        """``SharedSitl.launch``; a SITL that does not start fails the test with its log."""
        try:
            return super().launch(script, args, ready, what)
        except SitlStartError as e:
            pytest.fail(str(e))

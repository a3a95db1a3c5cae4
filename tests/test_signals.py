"""Terminal signals reach the flight's loop even when its self-pipe is full
(``mission.flight.signals``): asyncio's own ``add_signal_handler`` drops them then, and a dropped
Ctrl-C is an abort (and its return to launch) that never happens."""

from __future__ import annotations

import asyncio
import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

from mission.flight.signals import LoopSignals

ROOT = Path(__file__).resolve().parents[1]
# a callback floods the loop's self-pipe (as MAVSDK's telemetry does while the loop is busy), then
# the signal arrives; prints what the loop received
FLOOD = textwrap.dedent(
    """
    import asyncio, os, signal, sys
    from mission.flight.signals import LoopSignals

    got = []

    async def main(ours):
        loop = asyncio.get_running_loop()
        if ours:
            sigs = LoopSignals(loop, [signal.SIGHUP], got.append).install()
        else:
            loop.add_signal_handler(signal.SIGHUP, got.append, "SIGHUP")

        def busy():
            for _ in range(300_000):
                loop.call_soon_threadsafe(lambda: None)
            os.kill(os.getpid(), signal.SIGHUP)

        loop.call_soon(busy)
        await asyncio.sleep(0.5)
        if ours:
            sigs.remove()
        print(got)

    asyncio.run(main(sys.argv[1] == "ours"))
    """
)


def _flood(which: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-c", FLOOD, which],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=60,
    )


def test_a_signal_is_not_lost_when_the_loops_self_pipe_is_full():
    ours = _flood("ours")
    assert ours.returncode == 0 and ours.stdout.strip() == "['SIGHUP']", ours
    assert "Traceback" not in ours.stderr and "wakeup fd" not in ours.stderr, ours.stderr
    # the reason for the module: asyncio's own handler loses it, with a traceback on stderr
    theirs = _flood("asyncio")
    assert theirs.stdout.strip() == "[]" and "BlockingIOError" in theirs.stderr, theirs


def test_handlers_and_wakeup_fd_are_put_back():
    """After ``remove`` a signal goes to the handler found at ``install`` (the runner's: a Ctrl-C,
    exit 130), and the wakeup fd is the one before."""

    async def main() -> list[str]:
        got: list[str] = []
        before = signal.getsignal(signal.SIGHUP)
        sigs = LoopSignals(asyncio.get_running_loop(), [signal.SIGHUP], got.append).install()
        os.kill(os.getpid(), signal.SIGHUP)
        await asyncio.sleep(0.05)  # from another thread's view: the loop wakes on its own pipe
        sigs.remove()
        assert signal.getsignal(signal.SIGHUP) is before
        assert signal.set_wakeup_fd(-1) == -1  # none left set (asyncio set none: no handlers)
        return got

    seen = []
    old = signal.signal(signal.SIGHUP, lambda s, f: seen.append(s))
    try:
        assert asyncio.run(main()) == ["SIGHUP"]
        os.kill(os.getpid(), signal.SIGHUP)
        assert seen == [signal.SIGHUP]
    finally:
        signal.signal(signal.SIGHUP, old)

"""Terminal signals (Ctrl-C, SIGTERM, SIGHUP) handed to the flight's event loop, never lost.

Why not ``loop.add_signal_handler``: asyncio passes the signal's number as a byte through the loop's
self-pipe, the same pipe every ``call_soon_threadsafe`` writes a byte to.  MAVSDK delivers telemetry
through ``call_soon_threadsafe`` thousands of times a second at a speed-up; when the loop is busy
for a moment the pipe fills, the signal's byte is dropped and the signal is lost ("Exception ignored
when trying to write to the signal wakeup fd: BlockingIOError", CPython issue 74224): the abort and
its return to launch never happen.  Here the signal is recorded by a Python-level handler (run in
the main thread, which runs the loop) and scheduled as a callback; a wakeup pipe of its own, which
only signals write to, wakes the loop when the signal arrives on another thread.
"""

from __future__ import annotations

import asyncio
import contextlib
import signal
import socket
from collections.abc import Callable, Iterable


class LoopSignals:
    """While installed, each of ``signals`` calls ``callback(name)`` on ``loop`` (``name``: e.g.
    ``"SIGINT"``); ``remove`` puts back the handlers and wakeup fd found at ``install``."""

    def __init__(
        self,
        loop: asyncio.AbstractEventLoop,
        signals: Iterable[signal.Signals],
        callback: Callable[[str], object],
    ) -> None:
        self.loop, self.signals, self.callback = loop, tuple(signals), callback
        self._old: dict[signal.Signals, object] = {}
        self._old_fd = -1
        self._pair: tuple[socket.socket, socket.socket] | None = None

    def _handler(self, signum: int, frame) -> None:
        self.loop.call_soon_threadsafe(self.callback, signal.Signals(signum).name)

    def _drain(self) -> None:
        with contextlib.suppress(OSError):
            while self._pair[0].recv(4096):
                pass

    def install(self) -> LoopSignals:
        """Take over ``signals`` (main thread only, as ``signal.signal``)."""
        r, w = socket.socketpair()
        r.setblocking(False)
        w.setblocking(False)
        self._pair = (r, w)
        self.loop.add_reader(r.fileno(), self._drain)
        self._old_fd = signal.set_wakeup_fd(w.fileno(), warn_on_full_buffer=False)
        self._old = {sig: signal.signal(sig, self._handler) for sig in self.signals}
        return self

    def remove(self) -> None:
        """Restore what ``install`` found (a later signal goes to those handlers)."""
        for sig, old in self._old.items():
            signal.signal(sig, old)
        self._old = {}
        if self._pair is not None:
            signal.set_wakeup_fd(self._old_fd)
            self.loop.remove_reader(self._pair[0].fileno())
            for s in self._pair:
                s.close()
            self._pair = None

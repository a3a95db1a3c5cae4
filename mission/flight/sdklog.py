"""MAVSDK's own log lines, kept off the terminal and turned into one plain warning per kind of
trouble.

Why: on a lost link MAVSDK prints e.g. "Connection refused" every second, with raw colour codes; the
operator needs one line saying the link is lost (the runner's watchdog says that), not a scroll of
errors. Without ``--verbose`` every MAVSDK line is swallowed; warnings and errors are queued (from
MAVSDK's thread) and the runner shows the first of each distinct text once (digits ignored), while
the link is up.
"""

from __future__ import annotations

import re
from collections import deque

from mavsdk import LogLevel, log_subscribe, log_unsubscribe

_DIGITS = re.compile(r"\d+")
# MAVSDK v4 calls every subscription's callback from one thread through a queue; past 100 queued
# it drops the oldest subscription updates (telemetry and autopilot texts alike) and says so at
# most every 5 s with the running count
_DROPPED = re.compile(r"Dropping subscription callbacks \((\d+) so far\)")
_ANSI = re.compile(r"\x1b\[[0-9;]*m")


class SdkLog:
    """Subscribes to MAVSDK's log (unless verbose) and hands out new distinct warning/error
    texts."""

    def __init__(self, verbose: bool) -> None:
        self.verbose = verbose
        self.queue: deque[str] = deque(maxlen=200)
        self.seen: set[str] = set()
        self.installed = False
        self.dropped = 0  # subscription callbacks MAVSDK said it dropped (the last count seen)

    def __enter__(self) -> SdkLog:
        if self.verbose:
            return self

        warn = LogLevel.WARN

        def _filter(level, message, file, line) -> bool:
            if level >= warn:
                self.on_log(str(message))
            return True  # swallowed: the runner decides what the operator sees

        log_subscribe(_filter)
        self.installed = True
        return self

    def on_log(self, message: str) -> None:
        """Queue one MAVSDK warning/error (called on MAVSDK's thread), without terminal colour
        codes."""
        text = _ANSI.sub("", message).strip()
        if m := _DROPPED.search(text):
            self.dropped = max(self.dropped, int(m.group(1)))
        self.queue.append(text)

    def new_messages(self) -> list[str]:
        """Warning/error texts not shown before (the queue is drained)."""
        out = []
        while self.queue:
            text = self.queue.popleft()
            key = _DIGITS.sub("#", text)
            if text and key not in self.seen:
                self.seen.add(key)
                out.append(text)
        return out

    def __exit__(self, *exc) -> None:
        if self.installed:
            log_unsubscribe()
            self.installed = False

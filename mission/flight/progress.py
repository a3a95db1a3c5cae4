"""The live progress display of a flight (rich): waypoint i of n, elapsed vs budget, RSS, warnings.

Why: the operator must see at a glance that the flight is on plan, that RSS is arriving, where the
strongest signal so far was, and any link or receiver trouble.  On a terminal it is a ``rich.live``
panel; otherwise (CI, a pipe) one plain status line every few seconds, never wrapped, so logs stay
readable.
"""

from __future__ import annotations

import textwrap
import time
from dataclasses import dataclass, field

import numpy as np
from rich.console import Console
from rich.live import Live
from rich.table import Table
from rich.text import Text


@dataclass
class FlightStatus:
    """What the display shows; written by the runner's tasks, read by the display task."""

    mission_name: str = ""
    budget_s: float = 0.0
    predicted_s: float | None = (
        None  # arm-to-landing time predicted from the measured pace (budget watch)
    )
    item: int = 0
    items: int = 0
    waypoint_offset: int = 2  # raw items before the first waypoint (take-off, speed [, home])
    n_waypoints: int = 0
    t_start: float | None = None  # vehicle time at arming
    t_now: float = 0.0
    rows: int = 0
    last_rss: float = float("nan")
    best_rss: float = float("-inf")
    best_xy: tuple[float, float] | None = None
    rel_alt: float = 0.0
    stage: str = "connecting"  # the runner's set-up step before arming, then the mission phase
    link_lost: bool = False
    log_error: str = ""  # a failed log write ("disk full"), shown until the end
    estimate: str = ""  # the live estimate (render.Shown.line), empty until there is one
    warnings: list[str] = field(default_factory=list)

    @property
    def elapsed(self) -> float:
        return 0.0 if self.t_start is None else max(self.t_now - self.t_start, 0.0)

    @property
    def waypoint(self) -> int:
        return min(max(self.item - self.waypoint_offset + 1, 0), self.n_waypoints)


def _fmt_rss(v: float) -> str:
    """``-45.2`` or ``-`` before the first sample (never ``nan``)."""
    return f"{v:.1f}" if np.isfinite(v) else "-"


def render(s: FlightStatus) -> Table:
    """A two-column table of the status.  Cells are ``Text`` built from markup here, so that the
    panel looks the same whatever options the console renders it with (a plain ``markup=False``
    message line printed under a live panel re-renders the panel with those options: string cells
    showed raw tags)."""
    t = Table(title=Text(f"fly-mission: {s.mission_name}"), show_header=False, expand=False)
    t.add_column(style="bold")
    t.add_column()
    stage = (
        Text.assemble(("LINK LOST", "red"), f" (last: {s.stage})") if s.link_lost else Text(s.stage)
    )
    t.add_row("stage", stage)
    if s.log_error:
        t.add_row("log", Text(f"WRITE FAILED: {s.log_error}", "red"))
    t.add_row("waypoint", Text(f"{s.waypoint} of {s.n_waypoints} (raw item {s.item}/{s.items})"))
    over = s.budget_s and s.elapsed > s.budget_s
    el = Text(f"{s.elapsed:6.1f} s of {s.budget_s:.0f} s budget")
    if s.predicted_s is not None and np.isfinite(s.predicted_s):
        el.append(
            f", landing at ~{s.predicted_s:.0f} s", "red" if s.predicted_s > s.budget_s else ""
        )
    if over:
        el.append(" (over budget)", "red")
    t.add_row("elapsed", el)
    t.add_row("altitude", Text(f"{s.rel_alt:5.1f} m"))
    t.add_row("RSS rows", Text(str(s.rows)))
    t.add_row("last RSS", Text(f"{_fmt_rss(s.last_rss):>7} dB"))
    best = (
        "-"
        if s.best_xy is None
        else f"{s.best_rss:7.2f} dB at ({s.best_xy[0]:.0f}, {s.best_xy[1]:.0f}) m"
    )
    t.add_row("strongest", Text(f"* {best}", "green"))
    if s.estimate:
        t.add_row("estimate", Text(s.estimate))
    for w in s.warnings[-3:]:
        t.add_row(Text("warning", "yellow"), Text(w, "yellow"))
    return t


PLAIN_WIDTH = 80


def fit_width(text: str, width: int = PLAIN_WIDTH) -> str:
    """``text`` wrapped at ``width`` columns, continuation lines indented two spaces; a single word
    longer than that (a path, a URL) stays whole on its own line."""
    out = []
    for line in text.splitlines() or [""]:
        out += textwrap.wrap(
            line, width, subsequent_indent="  ", break_long_words=False, break_on_hyphens=False
        ) or [""]
    return "\n".join(out)


class FoldedTexts:
    """Autopilot texts for the screen, each shown once: a repeat (ArduPilot's "Auto mission changed,
    restarted command" after every re-upload: 75-112 of 270-376 lines of an adaptive flight) is
    counted, and ``summary`` gives one line per repeated text at the end.  The sidecar keeps every
    text."""

    def __init__(self) -> None:
        self.counts: dict[str, int] = {}

    def show(self, text: str) -> bool:
        """Whether to show ``text`` (its first time)."""
        self.counts[text] = self.counts.get(text, 0) + 1
        return self.counts[text] == 1

    def summary(self) -> list[str]:
        """One line per text seen more than once: the text (shortened to fit 80 columns) and its
        count."""
        out = []
        for text, n in self.counts.items():
            if n > 1:
                tail = f" (x{n}, shown once)"
                room = PLAIN_WIDTH - len(tail)
                out.append((text if len(text) <= room else text[: room - 3] + "...") + tail)
        return out


def plain_line(s: FlightStatus) -> str:
    """The status as plain text for a log or a pipe: one line, or two when it would pass 80
    columns."""
    best = (
        "-" if s.best_xy is None else f"{s.best_rss:.1f}dB@({s.best_xy[0]:.0f},{s.best_xy[1]:.0f})"
    )
    stage = f"LINK LOST, last {s.stage}" if s.link_lost else s.stage
    stage = f"LOG FAILED, {stage}" if s.log_error else stage
    over = " OVER" if s.budget_s and s.elapsed > s.budget_s else ""
    if s.predicted_s is not None and np.isfinite(s.predicted_s) and not over:
        over = f" (land~{s.predicted_s:.0f}s)"
    head = (
        f"[{stage}] wp {s.waypoint}/{s.n_waypoints} t={s.elapsed:.0f}/{s.budget_s:.0f}s{over} "
        f"alt={s.rel_alt:.1f}m rss={_fmt_rss(s.last_rss)} rows={s.rows}"
    )
    tail = f"best={best}" + (f" est={s.estimate}" if s.estimate else "")
    # a log read at 80 columns: the strongest sample and the live estimate go on a second, indented
    # line
    return f"{head} {tail}" if len(head) + 1 + len(tail) <= PLAIN_WIDTH else f"{head}\n  {tail}"


class Display:
    """Live panel on a terminal, periodic plain lines otherwise (both on stderr)."""

    def __init__(self, status: FlightStatus, plain_every_s: float = 5.0) -> None:
        self.status = status
        self.console = Console(stderr=True)
        self.live = None
        self.plain_every = plain_every_s
        self._next = 0.0

    def __enter__(self) -> Display:
        if self.console.is_terminal:
            self.live = Live(
                render(self.status), console=self.console, refresh_per_second=4, transient=False
            )
            self.live.__enter__()
        return self

    def refresh(self) -> None:
        if self.live is not None:
            self.live.update(render(self.status))
        elif time.monotonic() >= self._next:
            self._next = time.monotonic() + self.plain_every
            self.console.print(
                plain_line(self.status), highlight=False, markup=False, soft_wrap=True
            )

    def message(self, text: str, style: str = "") -> None:
        """A line that stays (warnings, stage changes), wrapped at 80 columns."""
        self.console.print(
            fit_width(text), style=style or None, highlight=False, markup=False, soft_wrap=True
        )

    def __exit__(self, *exc) -> None:
        if self.live is not None:
            self.live.update(render(self.status))
            self.live.__exit__(None, None, None)

"""The project's rich ``Console``: the commands' output and the runtime's progress bars share it, so
a piped or redirected output is never folded mid-word.

Why a module of its own: the runtime (``mission.localize.matched``'s progress bar) and the command
layer (``mission.cli``) both print through it, and the runtime must not import the command layer.
``progress_bar`` is the transient bar they share.
"""

from __future__ import annotations

import sys
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from rich.console import Console
    from rich.progress import Progress


def console(stderr: bool = False) -> Console:
    """A rich Console that does not fold long lines mid-word when the output is a file or a pipe."""
    # rich stays lazy (noqa): a command that prints nothing through it starts without it
    from rich.console import Console  # noqa: PLC0415

    stream = sys.stderr if stderr else sys.stdout
    return Console(stderr=stderr, soft_wrap=not stream.isatty())


def progress_bar(label: str, con: Console, disable: bool = False) -> Progress:
    """The project's transient progress bar on ``con``: ``label`` (a rich format string: may name
    ``{task.description}``), the bar, done/total and the time elapsed."""
    # rich stays lazy (noqa), as above
    from rich.progress import (  # noqa: PLC0415
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
    )

    return Progress(
        TextColumn(label),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        console=con,
        transient=True,
        disable=disable,
    )

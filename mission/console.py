"""The project's rich ``Console``: the commands' output and the runtime's progress bars share it, so
a piped or redirected output is never folded mid-word.

Why a module of its own: the runtime (``mission.localize.matched``'s progress bar) and the command
layer (``mission.cli``) both print through it, and the runtime must not import the command layer.
"""

from __future__ import annotations

import sys
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from rich.console import Console


def console(stderr: bool = False) -> Console:
    """A rich Console that does not fold long lines mid-word when the output is a file or a pipe."""
    # rich stays lazy (noqa): a command that prints nothing through it starts without it
    from rich.console import Console  # noqa: PLC0415

    stream = sys.stderr if stderr else sys.stdout
    return Console(stderr=stderr, soft_wrap=not stream.isatty())

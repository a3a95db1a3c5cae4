"""``rfsl``: the umbrella command; every subcommand is one module of ``mission.cli``."""

from __future__ import annotations

import argparse
import importlib
import math
import re
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

from mission import __version__
from mission.console import console  # noqa: F401  (re-exported: the commands import it here)
from mission.errors import InputError, one_line

# name -> (module, one-line purpose). The order is the order of `rfsl --help`.
SUBCOMMANDS: dict[str, tuple[str, str]] = {
    "rss": (
        "mission.cli.rss",
        "link budget for one geometry (free-space, two-ray, enhanced two-ray)",
    ),
    "simulate": (
        "mission.cli.simulate",
        "fly a mission in the fast kinematic simulator and write a flight log",
    ),
    "preview": (
        "mission.cli.preview",
        "plot a mission, its simulated path and (--accuracy) expected error",
    ),
    "export": ("mission.cli.export", "export a mission as QGroundControl .plan, GeoJSON or KML"),
    "sitl": (
        "mission.cli.sitl",
        "run the simulated MAVLink vehicle alone (for QGroundControl or MAVProxy)",
    ),
    "replay": ("mission.cli.replay", "summarise a flight log and draw its path coloured by RSS"),
    "import": (
        "mission.cli.importer",
        "convert real flights (AFAR challenge MAT files) into flight logs",
    ),
    "dataset": (
        "mission.cli.dataset",
        "generate a simulated training dataset of many transmitter positions",
    ),
    "train": (
        "mission.cli.train",
        "train a localizer network and export it to ONNX (needs the [train] extra)",
    ),
    "evaluate": (
        "mission.cli.evaluate",
        "compare localizers on simulated test sets and real flights",
    ),
    "localize": ("mission.cli.localize", "estimate the transmitter position from a flight log"),
    "calibrate": (
        "mission.cli.calibrate",
        "fit a physics preset on real flights with known transmitters (held out)",
    ),
    "gap": (
        "mission.cli.gap",
        "diagnose the sim-to-real gap of a propagation model on flights with known truth",
    ),
}


def doc_summary(doc: str | None) -> str:
    """A module docstring's first paragraph on one line: the description ``--help`` prints."""
    return " ".join((doc or "").strip().split("\n\n")[0].split())


def _available() -> dict[str, tuple[object, str]]:
    mods = {}
    for name, (modname, purpose) in SUBCOMMANDS.items():
        try:
            mods[name] = (importlib.import_module(modname), purpose)
        except ModuleNotFoundError as e:
            if e.name != modname:
                raise
    return mods


class OneLineParser(argparse.ArgumentParser):
    """argparse with the project's error convention: one line naming the argument and exit code 2
    (the usage text is one ``--help`` away; a wall of usage hides which argument was wrong)."""

    def error(self, message: str):  # type: ignore[override]
        self.exit(2, one_line(f"error: {self.prog}: {message} (see {self.prog} --help)") + "\n")


# A value that starts with a minus and a digit: a negative number or a list such as -100,200,1.5.
_NEGATIVE_VALUE = re.compile(r"^-\.?\d")


def join_negative_values(parser: argparse.ArgumentParser, argv: Sequence[str]) -> list[str]:
    """``--tx -100,200,1.5`` -> ``--tx=-100,200,1.5`` for options that take one value.

    argparse reads a token starting with '-' as an option unless it is a plain negative number, so
    negative coordinates (normal in the local ENU frame) failed as "expected one argument".
    """
    takes_value: set[str] = set()
    stack = [parser]
    while stack:
        p = stack.pop()
        for a in p._actions:
            if a.option_strings and a.nargs is None:
                takes_value.update(a.option_strings)
            if isinstance(a, argparse._SubParsersAction):
                stack.extend(a.choices.values())
    out: list[str] = []
    for tok in argv:
        if out and out[-1] in takes_value and _NEGATIVE_VALUE.match(tok):
            out[-1] = f"{out[-1]}={tok}"
        else:
            out.append(tok)
    return out


def parse_args(parser: argparse.ArgumentParser, argv: Sequence[str] | None) -> argparse.Namespace:
    """``parser.parse_args`` with negative option values accepted (``join_negative_values``)."""
    args = parser.parse_args(
        join_negative_values(parser, sys.argv[1:] if argv is None else list(argv))
    )
    # argparse turns '--speedup=--' into [] past its own type check
    for p in _parsers(parser, args):
        for a in p._actions:
            if (
                a.option_strings
                and a.nargs is None
                and a.type is not None
                and isinstance(getattr(args, a.dest, None), list)
            ):
                p.error(f"argument {'/'.join(a.option_strings)}: expected one value")
    return args


def _parsers(
    parser: argparse.ArgumentParser, args: argparse.Namespace
) -> list[argparse.ArgumentParser]:
    """The parser and the subcommand parser that ``args`` came through."""
    out = [parser]
    for a in parser._actions:
        if isinstance(a, argparse._SubParsersAction) and getattr(args, a.dest, None) in a.choices:
            out.append(a.choices[getattr(args, a.dest)])
    return out


def model_name_arg(value: str) -> str:
    """argparse ``type`` for a propagation-model name: the aliases ``make_model`` accepts, folded to
    its name."""
    from mission.physics.propagation import canonical_model_name

    try:
        return canonical_model_name(value)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def print_notes(notes: Sequence[str]) -> None:
    """Print what was accepted with a remark (a real-log quirk, a missing sidecar) as one stderr
    line each: 'note: ...', or the note as it is when it already says 'warning: ...'
    (``mission.flightlog.WARNING``)."""
    for n in notes:
        print(n if n.startswith("warning: ") else f"note: {n}", file=sys.stderr)


def check_number(
    value: float,
    flag: str,
    lo: float | None = None,
    hi: float | None = None,
    strict_lo: bool = False,
) -> float:
    """A numeric option checked at the boundary: finite and within its bounds, else one line naming
    the option and the bound (``--speedup 1e9`` or ``nan`` ran until killed; the bound is what keeps
    the work finite)."""
    try:
        v = float(value)
    except (TypeError, ValueError):  # argparse hands '--link-timeout=--' over as a list
        raise InputError(f"expected a number, got {value!r}", field=flag) from None
    if not math.isfinite(v):
        raise InputError(f"expected a finite number, got {value}", field=flag)
    if lo is not None and (v <= lo if strict_lo else v < lo):
        raise InputError(f"must be {'>' if strict_lo else '>='} {lo:g}, got {v:g}", field=flag)
    if hi is not None and v > hi:
        raise InputError(f"must be <= {hi:g}, got {v:g}", field=flag)
    return v


def image_out(path: str | Path, flag: str = "--out") -> Path:
    """Check an image output path before any heavy work: a format matplotlib writes, not a
    directory."""
    p = Path(path)
    if p.is_dir():
        raise InputError(
            "is a directory; give an image file name such as plot.png", source=str(p), field=flag
        )
    from matplotlib.backend_bases import FigureCanvasBase

    formats = FigureCanvasBase.get_supported_filetypes()
    suffix = p.suffix.lower().lstrip(".")
    if suffix not in formats:
        raise InputError(
            f"unknown image format '{p.suffix or '(no suffix)'}'; use one of "
            f"{', '.join('.' + f for f in sorted(formats))}",
            source=str(p),
            field=flag,
        )
    return out_parent_ok(p, flag)


def out_parent_ok(path: Path, flag: str = "--out", folder: bool = False) -> Path:
    """``path`` unchanged, or an InputError when one of its parents (or itself, for a ``folder``) is
    a file or the folder it would be written in cannot be written
    (``mission.files.check_writable_dir``)."""
    from mission.files import check_writable_dir

    check_writable_dir(path if folder else path.parent, flag)
    return path


def build_parser() -> argparse.ArgumentParser:
    parser = OneLineParser(
        prog="rfsl", description="UAV-based RF source localization toolkit (see README.md)."
    )
    parser.add_argument("--version", action="version", version=f"rfsl {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name, (mod, purpose) in _available().items():
        p = sub.add_parser(name, help=purpose, description=doc_summary(mod.__doc__) or purpose)
        mod.add_arguments(p)
        p.set_defaults(_run=mod.run)
    return parser


def run_guarded(fn: Callable[[], int | None]) -> int:
    """Run a CLI body under the thread limits (``mission.threads``, ``$RFSL_THREADS``): bad input
    becomes one line on stderr and exit code 2, Ctrl-C exit code 130."""
    from mission.threads import thread_limits

    try:
        with thread_limits():
            rc = int(fn() or 0)
        sys.stdout.flush()  # a closed pipe is found here, not in the interpreter's exit flush
        return rc
    except InputError as e:
        print(f"error: {e}", file=sys.stderr)
        return e.exit_code
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    # the reader went away (``localize LOG --json | head``): no traceback for that
    except BrokenPipeError:
        import os

        # Python's exit flush must not fail too
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141  # 128 + SIGPIPE, as a shell reports it


def standalone_main(prog: str, module, argv: Sequence[str] | None = None) -> int:
    """Entry point of a console script (``fly-mission``, ``localize``) that is also an ``rfsl``
    subcommand."""
    parser = OneLineParser(prog=prog, description=doc_summary(module.__doc__))
    module.add_arguments(parser)
    args = parse_args(parser, argv)
    return run_guarded(lambda: module.run(args))


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parse_args(parser, argv)
    return run_guarded(lambda: args._run(args))


if __name__ == "__main__":
    sys.exit(main())

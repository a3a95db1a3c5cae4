"""``rfsl``: the umbrella command; every subcommand is one module of ``mission.cli``."""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Callable, Sequence

from mission import __version__
from mission.errors import InputError

# name -> (module, one-line purpose). The order is the order of `rfsl --help`.
SUBCOMMANDS: dict[str, tuple[str, str]] = {
    "rss": ("mission.cli.rss", "link budget for one geometry (free-space, two-ray, enhanced two-ray)"),
    "simulate": ("mission.cli.simulate", "fly a mission in the fast kinematic simulator and write a flight log"),
    "preview": ("mission.cli.preview", "plot a mission, its simulated path and (--accuracy) expected error"),
    "export": ("mission.cli.export", "export a mission as QGroundControl .plan, GeoJSON or KML"),
    "sitl": ("mission.cli.sitl", "run the simulated MAVLink vehicle alone (for QGroundControl or MAVProxy)"),
    "replay": ("mission.cli.replay", "summarise a flight log and draw its path coloured by RSS"),
    "import": ("mission.cli.importer", "convert real flights (AFAR challenge MAT files) into flight logs"),
    "dataset": ("mission.cli.dataset", "generate a simulated training dataset of many transmitter positions"),
    "train": ("mission.cli.train", "train a localizer network and export it to ONNX (needs the [train] extra)"),
    "evaluate": ("mission.cli.evaluate", "compare localizers on simulated test sets and real flights"),
    "localize": ("mission.cli.localize", "estimate the transmitter position from a flight log"),
    "gap": ("mission.cli.gap", "diagnose the sim-to-real gap of a propagation model on flights with known truth"),
}


def _available() -> dict[str, tuple[object, str]]:
    mods = {}
    for name, (modname, purpose) in SUBCOMMANDS.items():
        try:
            mods[name] = (importlib.import_module(modname), purpose)
        except ModuleNotFoundError as e:
            if e.name != modname:
                raise
    return mods


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="rfsl", description="UAV-based RF source localization toolkit (see README.md).")
    parser.add_argument("--version", action="version", version=f"rfsl {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name, (mod, purpose) in _available().items():
        p = sub.add_parser(name, help=purpose, description=(mod.__doc__ or purpose).strip().splitlines()[0])
        mod.add_arguments(p)
        p.set_defaults(_run=mod.run)
    return parser


def run_guarded(fn: Callable[[], int | None]) -> int:
    """Run a CLI body: bad input becomes one line on stderr and exit code 2, Ctrl-C exit code 130."""
    try:
        return int(fn() or 0)
    except InputError as e:
        print(f"error: {e}", file=sys.stderr)
        return e.exit_code
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


def standalone_main(prog: str, module, argv: Sequence[str] | None = None) -> int:
    """Entry point of a console script (``fly-mission``, ``localize``) that is also an ``rfsl`` subcommand."""
    parser = argparse.ArgumentParser(prog=prog, description=(module.__doc__ or "").strip().splitlines()[0])
    module.add_arguments(parser)
    args = parser.parse_args(argv)
    return run_guarded(lambda: module.run(args))


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    return run_guarded(lambda: args._run(args))


if __name__ == "__main__":
    sys.exit(main())

"""Where the shipped networks and missions live: ``models/`` and ``missions/`` beside the package in a source
checkout (editable install, ``PYTHONPATH``), or the copies that a plain ``pip install .`` carries inside the
package as ``mission/data/models`` and ``mission/data/missions`` (``setup.py``'s build step puts them there),
so that an installed package localizes with the shipped default instead of falling back to a weaker method."""

from __future__ import annotations

from pathlib import Path

PACKAGE_DIR = Path(__file__).resolve().parent
SHIPPED_FOLDERS = ("models", "missions")  # repository folders copied into the installed package's data/


def shipped_dir(kind: str, package_dir: Path = PACKAGE_DIR) -> Path:
    """The folder holding the shipped ``kind`` (``models`` or ``missions``): the installed copy in
    ``<package>/data/<kind>`` when there is one, else the source checkout's ``<repository>/<kind>``."""
    if kind not in SHIPPED_FOLDERS:
        raise ValueError(f"unknown shipped folder {kind!r} (expected one of {', '.join(SHIPPED_FOLDERS)})")
    installed = package_dir / "data" / kind
    return installed if installed.is_dir() else package_dir.parent / kind


def models_dir() -> Path:
    """The shipped networks and their cards (``models/*.onnx``, ``models/*.json``)."""
    return shipped_dir("models")


def missions_dir() -> Path:
    """The shipped mission files (``missions/*.yaml``)."""
    return shipped_dir("missions")


def shipped_model(name: str) -> Path | None:
    """``models/<name>`` if it exists: the source checkout's, or the installed package's copy."""
    p = models_dir() / name
    return p if p.is_file() else None


def resolve_shipped(path: str | Path, kind: str, suffix: str) -> Path:
    """``path`` when it exists; else the shipped file it names (``spiral``, ``spiral.yaml`` or
    ``missions/spiral.yaml``; ``rfsl_default.onnx`` or ``models/rfsl_default.onnx``), so the README's commands
    work from any folder after a plain ``pip install``; else ``path`` unchanged (the caller says it is missing)."""
    p = Path(path)
    if p.exists():
        return p
    parts = p.parts
    if len(parts) == 1 or (len(parts) == 2 and parts[0] == kind):
        shipped = shipped_dir(kind) / (p.name if p.suffix else p.name + suffix)
        if shipped.is_file():
            return shipped
    return p

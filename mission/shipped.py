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

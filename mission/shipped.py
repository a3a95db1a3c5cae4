"""Where the shipped networks and missions live: ``models/`` and ``missions/`` beside the package in
a source checkout (editable install, ``PYTHONPATH``), or the copies that a plain ``pip install .``
carries inside the package as ``mission/data/models`` and ``mission/data/missions`` (``setup.py``'s
build step puts them there), so that an installed package localizes with the shipped default instead
of falling back to a weaker method."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

from mission.errors import InputError

PACKAGE_DIR = Path(__file__).resolve().parent
# repository folders copied into the installed package's data/
SHIPPED_FOLDERS = (
    "models",
    "missions",
)


def shipped_dir(kind: str, package_dir: Path = PACKAGE_DIR) -> Path:
    """The folder holding the shipped ``kind`` (``models`` or ``missions``): the installed copy in
    ``<package>/data/<kind>`` when there is one, else the source checkout's
    ``<repository>/<kind>``."""
    if kind not in SHIPPED_FOLDERS:
        raise ValueError(
            f"unknown shipped folder {kind!r} (expected one of {', '.join(SHIPPED_FOLDERS)})"
        )
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
    ``missions/spiral.yaml``; ``rfsl_default.onnx`` or ``models/rfsl_default.onnx``), so the
    README's commands work from any folder after a plain ``pip install``; else ``path`` unchanged
    (the caller says it is missing)."""
    p = Path(path)
    if p.exists():
        return p
    parts = p.parts
    if len(parts) == 1 or (len(parts) == 2 and parts[0] == kind):
        shipped = shipped_dir(kind) / (p.name if p.suffix else p.name + suffix)
        if shipped.is_file():
            return shipped
    return p


DIGESTS = "sha256.json"  # models/sha256.json: the sha256 of every shipped network, by file name


def shipped_digests() -> dict[str, str]:
    """{file name: sha256 hex} of the shipped networks (empty when the digest file is missing)."""
    p = models_dir() / DIGESTS
    try:
        d = json.loads(p.read_text())
    except (OSError, ValueError):
        return {}
    return {str(k): str(v) for k, v in d.items()} if isinstance(d, dict) else {}


_checked: dict[tuple[str, int, int], str] = {}


def file_sha256(path: Path) -> str:
    """The sha256 of a file, cached by path, size and modification time (a model is loaded many
    times)."""
    st = path.stat()
    key = (str(path.resolve()), st.st_size, st.st_mtime_ns)
    if key not in _checked:
        _checked[key] = hashlib.sha256(path.read_bytes()).hexdigest()
    return _checked[key]


def check_shipped_digest(path: str | Path) -> None:
    """A network under a shipped name (``rfsl_default.onnx``) must be that network: bytes flipped in
    its weights still load and answer, wrongly and silently, so its digest is checked against
    ``models/sha256.json``."""
    p = Path(path)
    want = shipped_digests().get(p.name)
    if want is not None and file_sha256(p) != want:
        raise InputError(
            f"differs from the shipped {p.name} (sha256 {file_sha256(p)[:12]}.., expected "
            f"{want[:12]}..): damaged, or another network under a shipped name (rename it)",
            source=str(p),
        )


def record_shipped_digest(path: str | Path) -> bool:
    """After ``rfsl train --out models/NAME.onnx`` replaced a shipped network: record its new digest
    in the checkout's ``models/sha256.json`` (True), so the check above keeps guarding it; other
    paths: False."""
    p = Path(path)
    folder = PACKAGE_DIR.parent / "models"
    if p.suffix != ".onnx" or not folder.is_dir() or p.resolve().parent != folder.resolve():
        return False
    digests = shipped_digests() if models_dir().resolve() == folder.resolve() else {}
    digests[p.name] = file_sha256(p)
    (folder / DIGESTS).write_text(json.dumps(dict(sorted(digests.items())), indent=1) + "\n")
    return True

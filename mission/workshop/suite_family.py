"""Physics family files for the unseen-flight benchmark (``mission.workshop.suite``): resolve,
check, name.

A benchmark flight's family is a built-in name (``FAMILIES``, re-exported by
``mission.workshop.suite``) or a schema-1 family file (``mission.physics.family``; ``rfsl gap
--family`` writes one).  Files are parsed once per version, refused with one ``InputError`` naming
the file when malformed or unphysical (a negative sigma), and named by the sha256 of their canonical
JSON so caches, datasets and models record exactly which family they drew from.
"""

from __future__ import annotations

import hashlib
import json
from functools import lru_cache
from pathlib import Path

import numpy as np

from mission.errors import InputError
from mission.physics.family import SHIPPED, PhysicsFamily, load_family

# the built-in families (drawn in mission.workshop.suite)
FAMILIES = (
    "afar",
    "generic",
    "afar-heavy",
)
# a built-in name (FAMILIES), a schema-1 family JSON path, or a loaded family
FamilyArg = str | PhysicsFamily


def resolve_family(family: FamilyArg) -> str | PhysicsFamily:
    """A built-in family name as it is, the ``PhysicsFamily`` of a shipped family's name that is
    not a built-in one (``physics.family.SHIPPED``: ``afar-fades``), or of a ``.json`` path
    (InputError otherwise)."""
    if isinstance(family, PhysicsFamily) or family in FAMILIES:
        return family
    if family in SHIPPED:
        return load_family(str(family))
    if str(family).lower().endswith(".json"):
        p = Path(family)
        st = p.stat() if p.is_file() else None
        return _load_json_family(
            str(p.resolve()), st.st_mtime_ns if st else -1, st.st_size if st else -1
        )
    raise InputError(
        f"unknown suite family {family!r} (expected {', '.join(FAMILIES)} or a physics family "
        ".json file)",
        field="family",
    )


@lru_cache(maxsize=8)
def _load_json_family(path: str, _mtime_ns: int, _size: int) -> PhysicsFamily:
    """Parsed once per file version (the key holds mtime and size so an edited file is read again);
    a value of the wrong type that ``load_family``'s checks let through (e.g. ``"schema": null``) is
    refused here too."""
    try:
        fam = load_family(path)
        # a trial draw: a residual or offset that is not a number fails here
        fam.draw(np.random.default_rng(0))
        return fam
    except InputError:
        raise
    except (TypeError, ValueError, KeyError, AttributeError) as e:
        raise InputError(
            f"malformed physics family ({type(e).__name__}: {e})", source=path
        ) from None


def family_sha256(fam: PhysicsFamily) -> str:
    """sha256 of the family's canonical JSON: what a cache or a model records to name the family it
    drew from."""
    return hashlib.sha256(
        json.dumps(fam.to_dict(), sort_keys=True, default=float).encode()
    ).hexdigest()


def family_label(fam: str | PhysicsFamily) -> str:
    """``afar`` for a built-in family, ``json:NAME@SHA8`` for a family file."""
    return fam if isinstance(fam, str) else f"json:{fam.name}@{family_sha256(fam)[:8]}"


def antenna_label(spec: dict) -> str:
    """The UAV antenna of a drawn spec as the built-in families name it (``--by
    physics.rx_antenna``)."""
    pat = str(spec.get("rx_pattern", "isotropic"))
    if pat == "measured":
        return "flipped" if spec.get("rx_flipped") else "upright"
    return pat

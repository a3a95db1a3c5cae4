"""Typed access to a mission file's YAML mappings: every error names the file and the dotted key.

Why a module of its own: the mission parser (``mission.spec``) and the blocks it delegates (``adaptive:`` in
``mission.adaptive.config``) read their keys the same way, with the same one-line errors.
"""

from __future__ import annotations

import math
from typing import Any

from mission.errors import InputError


class SpecReader:
    """Typed access to a YAML mapping with dotted key paths in every error."""

    def __init__(self, data: Any, src: str, key: str = "") -> None:
        if data is None:
            data = {}
        if not isinstance(data, dict):
            raise InputError(f"expected a mapping, got {type(data).__name__}", source=src, field=key or None)
        self.d, self.src, self.key, self.used = data, src, key, set()

    def k(self, name: str) -> str:
        return f"{self.key}.{name}" if self.key else name

    def err(self, name: str, msg: str) -> InputError:
        return InputError(msg, source=self.src, field=self.k(name))

    def raw(self, name: str, default: Any = None) -> Any:
        self.used.add(name)
        return self.d.get(name, default)

    def has(self, name: str) -> bool:
        return name in self.d and self.d[name] is not None

    def num(self, name: str, default: float, lo: float | None = None, hi: float | None = None,
            strict_lo: bool = False) -> float:
        v = self.raw(name, default)
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            raise self.err(name, f"expected a number, got {v!r}")
        if lo is not None and (v <= lo if strict_lo else v < lo):
            raise self.err(name, f"must be {'>' if strict_lo else '>='} {lo}, got {v}")
        if hi is not None and v > hi:
            raise self.err(name, f"must be <= {hi}, got {v}")
        return float(v)

    def int_(self, name: str, default: int) -> int:
        v = self.raw(name, default)
        if isinstance(v, bool) or not isinstance(v, int):
            raise self.err(name, f"expected an integer, got {v!r}")
        return v

    def str_(self, name: str, default: str | None, choices: tuple[str, ...] | None = None) -> str | None:
        v = self.raw(name, default)
        if v is None and default is None:
            return None
        if not isinstance(v, str):
            raise self.err(name, f"expected a string, got {v!r}")
        if choices and v not in choices:
            raise self.err(name, f"expected one of {', '.join(choices)}, got '{v}'")
        return v

    def sub(self, name: str) -> SpecReader:
        return SpecReader(self.raw(name), self.src, self.k(name))

    def done(self) -> None:
        extra = [k for k in self.d if k not in self.used]
        if extra:
            raise self.err(str(extra[0]), "unknown key (see the schema at the top of missions/spiral.yaml)")
